#!/usr/bin/env python3
"""Tabulate Mitsuba 3.9.1's spectral lookups of `bitmap` textures and of the `envmap` emitter
for penumbra's tests (tests/spectral_textures.rs).

Writes two small float EXR images under tests/data/spectral/ (linear data, no sRGB decode):

- tex_rgb.exr, 3x2 RGB: saturated, pale and grey colours and one texel above 1 (which
  srgb_model_fetch clamps to [0, 1]);
- env_rgb.exr, 4x3 RGB, HDR values (up to 40), one black texel;

then, in the scalar_spectral variant:

- `coeff NAME i r g b c0 c1 c2`: Mitsuba's srgb_model_fetch of texel i (row-major) of the
  bitmap (rgb as stored) or of the envmap (rgb / max(1e-8, s), s = 2 max(rgb), as the
  plugin stores it; then the line carries s as a 4th coefficient);
- `bitmap FILTER WRAP u v l0 l1 l2 l3 s0 s1 s2 s3`: tex.eval(si) at uv (u, v) and
  wavelengths l (nm) for the bitmap loaded with that filter_type and wrap_mode;
- `bitmap_mean FILTER WRAP m`: tex.mean();
- `envmap SCALE dx dy dz l0 l1 l2 l3 s0 s1 s2 s3`: the envmap's eval(si) with si.wi = -d,
  d the direction the radiance arrives from (an escaping ray's direction), at wavelengths l;
- a two-triangle mesh (vertices (0,0,0), (1,0,0), (0,1,0), (1,1,0); faces (0,1,2),
  (1,3,2)) with attributes `vertex_color`, `face_color` (converted to coefficients by
  Mitsuba's add_attribute) and `vertex_foo` (three channels, not a colour: kept as given):
  `attr NAME values...` the attribute as given, `attr_stored NAME values...` Mitsuba's
  attribute_buffer after loading, and `mesh_eval NAME prim b1 b2 l0..l3 s0..s3`
  mesh.eval_attribute(NAME, si) at barycentrics (1 - b1 - b2, b1, b2) of triangle prim
  (si.p placed there; on triangle 0 Mitsuba's least-squares barycentrics are exactly b1, b2);
- grid_rgb.vol, a 3x2x2 three-channel `gridvolume` (x fastest): `coeff grid i r g b c0 c1 c2 s`
  as for the envmap (Mitsuba's gridvolume stores rgb / max(1e-8, s), s = 2 max(rgb)), and
  `grid FILTER WRAP x y z l0..l3 s0..s3`: volume.eval(it) at point (x, y, z) (the grid spans
  the unit cube) and wavelengths l.

Floats are printed with 9 significant digits (f32 round-trips exactly).

Usage: python validation/mitsuba/spectral_textures.py [OUT]
       (default tests/data/spectral/mitsuba_spectral_textures.txt)
"""
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_spectral")
mi.set_log_level(mi.LogLevel.Error)  # silence "pixels exceed the [0, 1] range"

SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))
DATA = os.path.join(REPO_ROOT, "tests", "data", "spectral")

TEX = np.array(
    [
        [[0.8, 0.1, 0.05], [0.5, 0.5, 0.5], [2.0, 1.5, 0.3]],
        [[0.1, 0.6, 0.2], [0.05, 0.1, 0.7], [0.3, 0.25, 0.2]],
    ],
    dtype=np.float32,
)
ENV = np.array(
    [
        [[1.0, 2.0, 3.0], [4.0, 4.0, 4.0], [0.5, 0.2, 0.1], [2.0, 1.0, 0.5]],
        [[10.0, 3.0, 1.0], [0.0, 0.0, 0.0], [0.2, 0.8, 0.4], [40.0, 30.0, 20.0]],
        [[0.3, 0.3, 0.6], [1.5, 0.5, 0.5], [6.0, 7.0, 2.0], [0.1, 0.1, 0.1]],
    ],
    dtype=np.float32,
)

# 3 x 2 x 2 cells (x fastest), three channels: saturated, pale, grey, dark and one HDR cell.
GRID = np.array(
    [
        [0.8, 0.1, 0.05], [0.5, 0.5, 0.5], [2.0, 1.5, 0.3],
        [0.1, 0.6, 0.2], [0.05, 0.1, 0.7], [0.3, 0.25, 0.2],
        [0.0, 0.0, 0.0], [0.9, 0.9, 0.2], [0.02, 0.01, 0.015],
        [4.0, 1.0, 2.0], [0.6, 0.3, 0.9], [0.25, 0.7, 0.7],
    ],
    dtype=np.float32,
)


def write_vol(path, cells):
    """Mitsuba's .vol format: 'VOL', version 3, float32 encoding, 3x2x2 cells, 3 channels,
    the unit cube as the box, then the data (x fastest)."""
    import struct

    with open(path, "wb") as fh:
        fh.write(b"VOL" + bytes([3]) + struct.pack("<i", 1) + struct.pack("<4i", 3, 2, 2, 3))
        fh.write(struct.pack("<6f", 0, 0, 0, 1, 1, 1))
        fh.write(cells.astype("<f4").tobytes())


WAVELENGTHS = [
    [360.0, 450.0, 550.0, 830.0],
    [412.5, 487.25, 601.0, 700.75],
    [500.0, 500.0, 500.0, 500.0],
]


def f(x):
    return "%.9g" % x


def main():
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(DATA, "mitsuba_spectral_textures.txt")
    os.makedirs(DATA, exist_ok=True)
    tex_file = os.path.join(DATA, "tex_rgb.exr")
    env_file = os.path.join(DATA, "env_rgb.exr")
    mi.Bitmap(TEX).write(tex_file)
    mi.Bitmap(ENV).write(env_file)
    lines = [
        "# Mitsuba %s scalar_spectral lookups; see validation/mitsuba/spectral_textures.py" % mi.__version__
    ]

    for i, rgb in enumerate(TEX.reshape(-1, 3)):
        c = mi.srgb_model_fetch(mi.Color3f(*[float(x) for x in rgb]))
        lines.append(" ".join(["coeff", "tex", str(i)] + [f(x) for x in rgb] + [f(x) for x in c]))
    for i, rgb in enumerate(ENV.reshape(-1, 3)):
        s = float(np.float32(max(rgb)) * np.float32(2.0))
        d = np.float32(max(1e-8, s))
        norm = [float(np.float32(x) / d) for x in rgb]
        c = mi.srgb_model_fetch(mi.Color3f(*norm))
        lines.append(
            " ".join(["coeff", "env", str(i)] + [f(x) for x in rgb] + [f(x) for x in c] + [f(s)])
        )

    rng = np.random.default_rng(43)
    uvs = [(u, v) for u in (0.0, 1 / 6, 0.25, 0.5, 0.9, 1.0) for v in (0.0, 0.25, 0.5, 0.75, 1.0)]
    uvs += [(-0.3, 1.7), (2.2, -0.45), (-1.01, 0.33)]
    uvs += [tuple(x) for x in rng.uniform(-1.5, 2.5, size=(20, 2))]
    for filt in ("bilinear", "nearest"):
        for wrap in ("repeat", "mirror", "clamp"):
            tex = mi.load_dict(
                {"type": "bitmap", "filename": tex_file, "filter_type": filt, "wrap_mode": wrap}
            )
            lines.append(" ".join(["bitmap_mean", filt, wrap, f(tex.mean())]))
            for (u, v) in uvs:
                for wl in WAVELENGTHS:
                    si = mi.SurfaceInteraction3f()
                    si.uv = mi.Point2f(float(u), float(v))
                    si.wavelengths = mi.Spectrum(wl)
                    val = tex.eval(si)
                    lines.append(
                        " ".join(
                            ["bitmap", filt, wrap]
                            + [f(np.float32(u)), f(np.float32(v))]
                            + [f(x) for x in wl]
                            + [f(val[k]) for k in range(4)]
                        )
                    )

    dirs = rng.normal(size=(60, 3))
    dirs = list(dirs / np.linalg.norm(dirs, axis=1, keepdims=True))
    dirs += [np.array([0.0, 1.0, 0.0]), np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, -1.0])]
    for scale in (1.0, 2.5):
        env = mi.load_dict({"type": "envmap", "filename": env_file, "scale": scale})
        for d in dirs:
            d = [float(np.float32(x)) for x in d]
            for wl in WAVELENGTHS:
                si = mi.SurfaceInteraction3f()
                si.wi = -mi.Vector3f(d)
                si.wavelengths = mi.Spectrum(wl)
                val = env.eval(si)
                lines.append(
                    " ".join(
                        ["envmap", f(scale)]
                        + [f(x) for x in d]
                        + [f(x) for x in wl]
                        + [f(val[k]) for k in range(4)]
                    )
                )

    attrs = {
        "vertex_color": [0.8, 0.1, 0.05, 0.1, 0.6, 0.2, 0.05, 0.1, 0.7, 0.5, 0.5, 0.5],
        "face_color": [0.3, 0.25, 0.2, 0.96, 0.03, 0.52],
        "vertex_foo": [1e-4, -0.1, 20.0, -2e-4, 0.2, -40.0, 0.0, 0.0, 1.5, 1e-5, 0.0, -3.0],
    }
    mesh = mi.Mesh("m", vertex_count=4, face_count=2, has_vertex_normals=False,
                   has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0]
    params["faces"] = [0, 1, 2, 1, 3, 2]
    params.update()
    for name, values in attrs.items():
        mesh.add_attribute(name, 3, values)
        lines.append(" ".join(["attr", name] + [f(np.float32(x)) for x in values]))
        lines.append(" ".join(["attr_stored", name] + [f(x) for x in mesh.attribute_buffer(name)]))
    bary = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.25, 0.5), (1 / 3, 1 / 3), (0.7, 0.2)]
    bary += [tuple(x) for x in rng.dirichlet([1, 1, 1], size=6)[:, 1:]]
    for name in attrs:
        for prim in (0, 1) if name == "face_color" else (0,):
            for (b1, b2) in bary:
                b1, b2 = np.float32(b1), np.float32(b2)
                for wl in WAVELENGTHS:
                    si = mi.SurfaceInteraction3f()
                    si.p = mi.Point3f(float(b1), float(b2), 0.0)
                    si.prim_index = prim
                    si.wavelengths = mi.Spectrum(wl)
                    val = mesh.eval_attribute(name, si)
                    lines.append(
                        " ".join(
                            ["mesh_eval", name, str(prim), f(b1), f(b2)]
                            + [f(x) for x in wl]
                            + [f(val[k]) for k in range(4)]
                        )
                    )

    grid_file = os.path.join(DATA, "grid_rgb.vol")
    write_vol(grid_file, GRID)
    for i, rgb in enumerate(GRID.reshape(-1, 3)):
        s = float(np.float32(max(rgb)) * np.float32(2.0))
        d = np.float32(max(1e-8, s))
        norm = [float(np.float32(x) / d) for x in rgb]
        c = mi.srgb_model_fetch(mi.Color3f(*norm))
        lines.append(
            " ".join(["coeff", "grid", str(i)] + [f(x) for x in rgb] + [f(x) for x in c] + [f(s)])
        )
    points = [tuple(x) for x in rng.uniform(-0.2, 1.2, size=(25, 3))]
    points += [(0.5, 0.5, 0.5), (1 / 6, 0.25, 0.75), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)]
    for filt in ("trilinear", "nearest"):
        for wrap in ("clamp", "repeat", "mirror"):
            vol = mi.load_dict(
                {"type": "gridvolume", "filename": grid_file, "filter_type": filt, "wrap_mode": wrap}
            )
            for pt in points:
                pt = [float(np.float32(x)) for x in pt]
                for wl in WAVELENGTHS:
                    it = mi.Interaction3f()
                    it.p = mi.Point3f(pt)
                    it.wavelengths = mi.Spectrum(wl)
                    val = vol.eval(it)
                    lines.append(
                        " ".join(
                            ["grid", filt, wrap]
                            + [f(x) for x in pt]
                            + [f(x) for x in wl]
                            + [f(val[k]) for k in range(4)]
                        )
                    )

    with open(out_path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("wrote", out_path, len(lines), "lines")


if __name__ == "__main__":
    main()
