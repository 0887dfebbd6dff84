#!/usr/bin/env python3
"""Tabulate Mitsuba 3's `cylinder` shape for penumbra's tests (src/shape/cylinder.rs).

For each cylinder configuration (p0, p1, radius, flip_normals and a to_world matrix), a scene
holding only that cylinder is loaded and ~40 rays are traced with `scene.ray_intersect`:
from outside, from inside the tube, through the open ends, grazing just inside and just
outside the silhouette, parallel to the axis, missing, and hitting beyond `maxt`. The rays are
built in the cylinder's object space (unit radius, z in [0, 1]) from a fixed numpy seed and
mapped to world space with Mitsuba's own composed to_world, so each lands where intended.
A few area samples (`sample_position`, `pdf_position`) are printed as well.

Output format (one record per line, numbers as f32-exact decimals):
  case NAME flip 0|1
  p0 x y z / p1 x y z / radius r
  to_world m00 m01 .. m33      the user's to_world (row-major), as Mitsuba stored it (f32)
  object m00 .. m33            Mitsuba's composed object-to-world matrix (traverse: to_world)
  area A
  bbox min.xyz max.xyz         Mitsuba's world bounding box (shape.bbox())
  r KIND ox oy oz dx dy dz maxt miss
  r KIND ox oy oz dx dy dz maxt t p.xyz n.xyz sh_n.xyz sh_s.xyz uv.xy dp_du.xyz dp_dv.xyz
  s u1 u2 p.xyz n.xyz pdf pdf_position

Usage: python validation/mitsuba/cylinder_hits.py [OUT]
       (default tests/data/mitsuba_cylinder_hits.txt)
Mitsuba 3.9.1, scalar_rgb variant.
"""
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))
T = mi.ScalarTransform4f


def unit(v):
    v = np.asarray(v, dtype=float)
    return list(v / np.linalg.norm(v))


# (name, p0, p1, radius, flip_normals, user to_world)
CASES = [
    # An oblique axis, rotation, translation and a uniform scale: no warning in Mitsuba.
    ("oblique", [0.2, -0.4, 0.1], [-0.6, 0.8, 1.9], 0.45, False,
     T().translate([1.0, 2.0, -3.0]) @ T().rotate(unit([1, 1, 0]), 35.0) @ T().scale(1.3)),
    # A non-uniform scale along the cylinder's axis (allowed: it only stretches the length),
    # with rotation, translation and flipped normals.
    ("axis-scaled-flipped", [0.0, 0.0, -0.5], [0.0, 0.0, 1.0], 0.6, True,
     T().translate([-2.0, 0.5, 1.0]) @ T().rotate(unit([0.2, 1.0, 0.3]), 70.0)
     @ T().scale([0.8, 0.8, 2.5])),
    # Non-uniform scale across the axis: an elliptic cylinder. Mitsuba warns ("shouldn't
    # contain non-uniform scaling along the X and Y axes") but intersects it exactly in object
    # space; its surface_area is then 2*pi*|M e_x|*|M e_z|, not the ellipse's.
    ("elliptic", [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.5, False,
     T().rotate(unit([0.3, -0.5, 1.0]), 50.0) @ T().scale([2.0, 0.7, 1.2])),
    # A mirror (negative determinant): Mitsuba flips its internal flip_normals flag so that
    # intersection normals still point outward.
    ("mirrored", [0.1, 0.2, 0.3], [0.4, -0.3, 1.5], 0.8, False,
     T().translate([0.5, -1.0, 2.0]) @ T().scale([-1.0, 1.0, 1.0])),
]


def fmt(*vals):
    out = []
    for v in vals:
        if isinstance(v, (list, tuple, np.ndarray)) or hasattr(v, "__len__"):
            out.extend(repr(float(x)) for x in v)
        else:
            out.append(repr(float(v)))
    return " ".join(out)


def matrix_rows(tf):
    m = np.array(tf.matrix, dtype=np.float64)
    return m.reshape(4, 4)


def make_rays(rng, obj):
    """Rays (kind, o_obj, d_obj, maxt) in object space, mapped to world space by obj."""
    rays = []

    def on_surface(phi, z):
        return np.array([np.cos(phi), np.sin(phi), z])

    def rand_dir():
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)

    # From outside: origin at object radius 2-4, aiming at a surface point.
    for _ in range(10):
        a = rng.uniform(0, 2 * np.pi)
        o = np.array([rng.uniform(2, 4) * np.cos(a), rng.uniform(2, 4) * np.sin(a),
                      rng.uniform(-1, 2)])
        target = on_surface(a + rng.uniform(-1.0, 1.0), rng.uniform(0.05, 0.95))
        scale = 2.5 if len(rays) % 3 == 0 else 1.0  # some unnormalised directions
        rays.append(("outside", o, (target - o) * scale, np.inf))
    # From inside the tube, in any direction (some leave through the open ends: misses).
    for _ in range(8):
        r = rng.uniform(0, 0.7)
        a = rng.uniform(0, 2 * np.pi)
        o = np.array([r * np.cos(a), r * np.sin(a), rng.uniform(0.1, 0.9)])
        rays.append(("inside", o, rand_dir(), np.inf))
    # Through an open end onto the inner wall.
    for z0, dz in ((1.8, -1.0), (-0.8, 1.0)):
        a = rng.uniform(0, 2 * np.pi)
        o = np.array([0.2 * np.cos(a), 0.2 * np.sin(a), z0])
        target = on_surface(a + np.pi + 0.3, 0.5)
        rays.append(("end", o, target - o, np.inf))
    # Grazing: lines at object distance 1 - 1e-3 (hit) and 1 + 1e-3 (miss) from the axis.
    for dist, kind in ((1 - 1e-3, "graze-in"), (1 - 1e-3, "graze-in"), (1 - 1e-3, "graze-in"),
                       (1 + 1e-3, "graze-out"), (1 + 1e-3, "graze-out")):
        a = rng.uniform(0, 2 * np.pi)
        q = np.array([dist * np.cos(a), dist * np.sin(a), rng.uniform(0.3, 0.7)])
        d = np.array([-np.sin(a), np.cos(a), rng.uniform(-0.2, 0.2)])
        rays.append((kind, q - 3.0 * d, d, np.inf))
    # Parallel to the axis, inside and outside the tube: never a hit.
    rays.append(("axial", np.array([0.3, -0.2, -1.0]), np.array([0.0, 0.0, 1.0]), np.inf))
    rays.append(("axial", np.array([1.5, 0.5, -1.0]), np.array([0.0, 0.0, 1.0]), np.inf))
    # Misses: pointing away, and crossing the infinite tube beyond its ends.
    for _ in range(2):
        a = rng.uniform(0, 2 * np.pi)
        o = np.array([3 * np.cos(a), 3 * np.sin(a), 0.5])
        rays.append(("miss", o, np.array([np.cos(a), np.sin(a), 0.1]), np.inf))
    rays.append(("miss", np.array([3.0, 0.0, 1.5]), np.array([-1.0, 0.1, 0.0]), np.inf))
    rays.append(("miss", np.array([0.0, -3.0, -0.2]), np.array([0.05, 1.0, -0.01]), np.inf))
    # maxt: short of the near hit (miss); between the near and far hits (near hit); from
    # inside, short of the wall (miss).
    o = np.array([3.0, 0.4, 0.5])
    d = np.array([-1.0, 0.0, 0.05])
    rays.append(("tmax-short", o, d, 1.5))
    rays.append(("tmax-between", o, d, 3.0))
    rays.append(("tmax-inside", np.array([0.1, 0.0, 0.5]), np.array([1.0, 0.2, 0.0]), 0.5))
    out = []
    lin = obj[:3, :3]
    for kind, o, d, maxt in rays:
        ow = obj[:3, :3] @ o + obj[:3, 3]
        dw = lin @ d  # a linear map keeps the ray parameter t unchanged
        out.append((kind, ow.astype(np.float32), dw.astype(np.float32), maxt))
    return out


def main():
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        REPO_ROOT, "tests", "data", "mitsuba_cylinder_hits.txt")
    rng = np.random.default_rng(20261127)
    lines = ["# generated by validation/mitsuba/cylinder_hits.py: Mitsuba 3.9.1 scalar_rgb",
             "# see the script's docstring for the record format"]
    for name, p0, p1, radius, flip, to_world in CASES:
        scene = mi.load_dict({
            "type": "scene",
            "cyl": {"type": "cylinder", "p0": p0, "p1": p1, "radius": radius,
                    "flip_normals": flip, "to_world": to_world},
        })
        shape = scene.shapes()[0]
        obj = matrix_rows(mi.traverse(shape)["to_world"])
        lines.append(f"case {name} flip {int(flip)}")
        lines.append("p0 " + fmt(p0))
        lines.append("p1 " + fmt(p1))
        lines.append("radius " + fmt(radius))
        lines.append("to_world " + fmt(matrix_rows(to_world).ravel()))
        lines.append("object " + fmt(obj.ravel()))
        lines.append("area " + fmt(shape.surface_area()))
        bb = shape.bbox()
        lines.append("bbox " + fmt(bb.min, bb.max))
        for kind, o, d, maxt in make_rays(rng, obj):
            ray = mi.Ray3f(mi.ScalarPoint3f(o), mi.ScalarVector3f(d))
            ray.maxt = float(maxt)
            si = scene.ray_intersect(ray)
            head = f"r {kind} " + fmt(o, d, [np.float32(maxt)])
            if not si.is_valid():
                lines.append(head + " miss")
                continue
            lines.append(head + " " + fmt(si.t, si.p, si.n, si.sh_frame.n, si.sh_frame.s,
                                          si.uv, si.dp_du, si.dp_dv))
        for u in rng.uniform(0, 1, size=(8, 2)).astype(np.float32):
            ps = shape.sample_position(0.0, mi.ScalarPoint2f(u))
            lines.append("s " + fmt(u, ps.p, ps.n, ps.pdf, shape.pdf_position(ps)))
    with open(out_path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {out_path}")


if __name__ == "__main__":
    main()
