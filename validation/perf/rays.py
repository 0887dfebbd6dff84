#!/usr/bin/env python3
"""Rays per second: penumbra's traversal against Mitsuba's (Embree) on the same rays.

Issue 42 asks how penumbra's ray casting compares with Mitsuba's own, apart from shading:
for each mesh and each batch of rays, both renderers load the same scene file and trace
the same rays, closest hit (penumbra `Scene.cast`, Mitsuba `ray_intersect_preliminary`) and
occlusion (`Scene.cast(any=True)`, Mitsuba `ray_test`), in llvm_ad_rgb (Embree, called by
Dr.Jit's kernels on packets of rays) and, with --variants, scalar_rgb. Times exclude the
conversion of the rays on both sides (Mitsuba's rays are evaluated before the clock starts,
and its kernel is compiled by an untimed first call); medians of --repeat runs. The
distances must agree ray by ray (same geometry): the script reports the share of rays
whose hit distances agree to 1e-4 (relative) and whose occlusion answers are equal.

Scene files given with --scene are measured too, whole (every shape they hold, where the
scene file puts them). Meshes: the Stanford bunny (scenes/meshes, 69,451 triangles) and a generated displaced
sphere of --dense triangles (default 2,000,000; written as a binary PLY to a temporary
folder). Batches of --rays rays (default 1M): "coherent" (a pinhole camera's rays, one per
pixel of a square image framing the mesh) and "incoherent" (origins uniform in the mesh's
bounding box, directions uniform on the sphere), both from a fixed seed.

Usage (penumbra's Python package and Mitsuba 3.9.1 in one environment):
    pip install mitsuba==3.9.1 numpy ./python
    python validation/perf/rays.py [--threads 1 --threads 2] [--rays 1000000]
        [--dense 2000000] [--repeat 3] [--variants llvm_ad_rgb,scalar_rgb] [--out FILE.md]
"""

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LLVM = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"

SCENE = """<scene version="3.0.0">
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    <shape type="{kind}"><string name="filename" value="{path}"/></shape>
</scene>
"""


def displaced_sphere(path, triangles, np):
    """A unit sphere with a bumpy radius, `triangles` triangles (a latitude-longitude grid
    with two triangles per cell), written as a binary little-endian PLY."""
    cells = max(triangles // 2, 8)
    n_theta = max(int(round((cells / 2) ** 0.5)), 2)
    n_phi = max(cells // n_theta, 4)
    theta = (np.arange(n_theta + 1) + 0.0) / n_theta * np.pi
    phi = np.arange(n_phi) / n_phi * 2 * np.pi
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    r = 1 + 0.05 * np.sin(7 * th) * np.cos(11 * ph) + 0.02 * np.sin(31 * th + 17 * ph)
    v = np.stack([r * np.sin(th) * np.cos(ph), r * np.sin(th) * np.sin(ph), r * np.cos(th)], -1)
    v = v.reshape(-1, 3).astype("<f4")
    i = np.arange(n_theta)[:, None]
    j = np.arange(n_phi)[None, :]
    a = i * n_phi + j
    b = i * n_phi + (j + 1) % n_phi
    c = a + n_phi
    d = b + n_phi
    faces = np.concatenate(
        [np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)]
    ).astype("<i4")
    rec = np.zeros(len(faces), dtype=[("n", "u1"), ("f", "<i4", (3,))])
    rec["n"] = 3
    rec["f"] = faces
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(v.tobytes())
        f.write(rec.tobytes())
    return len(faces)


def ray_batches(lo, hi, n, np):
    """The coherent and incoherent batches for a mesh with bounding box [lo, hi]."""
    rng = np.random.default_rng(42)
    centre, extent = (lo + hi) / 2, float(np.max(hi - lo))
    side = int(n**0.5)
    # Coherent: a pinhole 2.5 extents in front of the box (+z), a square image of side
    # `side` that frames it.
    eye = centre + np.array([0.0, 0.0, 2.5 * extent])
    s = (np.arange(side) + 0.5) / side * 2 - 1
    x, y = np.meshgrid(s, -s)
    half = 0.6 * extent
    target = np.stack(
        [centre[0] + half * x, centre[1] + half * y, np.full_like(x, centre[2])], -1
    ).reshape(-1, 3)
    d_coh = target - eye
    d_coh /= np.linalg.norm(d_coh, axis=1, keepdims=True)
    o_coh = np.broadcast_to(eye, d_coh.shape)
    # Incoherent: origins in the box, directions uniform on the sphere.
    m = side * side
    o_inc = lo + rng.random((m, 3)) * (hi - lo)
    z = rng.random(m) * 2 - 1
    a = rng.random(m) * 2 * np.pi
    rxy = np.sqrt(1 - z * z)
    d_inc = np.stack([rxy * np.cos(a), rxy * np.sin(a), z], -1)
    f32 = lambda t: np.ascontiguousarray(t, dtype=np.float32)
    return {
        "coherent": (f32(o_coh), f32(d_coh)),
        "incoherent": (f32(o_inc), f32(d_inc)),
    }


def mitsuba_cast(mi, dr, scene, o, d, any_hit, coherent):
    """Mitsuba's answers for the rays and the seconds of the traversal alone."""
    ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
    dr.eval(ray)
    dr.sync_thread()
    start = time.perf_counter()
    if any_hit:
        out = scene.ray_test(ray, coherent=coherent)
    else:
        out = scene.ray_intersect_preliminary(ray, coherent=coherent).t
    dr.eval(out)
    dr.sync_thread()
    seconds = time.perf_counter() - start
    return out.numpy().astype("f4"), seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--dense", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, action="append")
    ap.add_argument("--variants", default="llvm_ad_rgb")
    ap.add_argument("--scene", action="append", default=[],
                    help="also a whole scene file (its shapes, loaded by both)")
    ap.add_argument("--no-meshes", action="store_true",
                    help="only the --scene files, not the bunny and the generated mesh")
    ap.add_argument("--out")
    args = ap.parse_args()
    threads = args.threads or [1, 2]
    if os.path.exists(LLVM):
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM)
    import numpy as np
    import drjit as dr
    import mitsuba as mi
    import penumbra

    tmp = Path(tempfile.mkdtemp(prefix="penumbra-rays-"))
    meshes = []
    if not args.no_meshes:
        dense = tmp / "dense.ply"
        n_dense = displaced_sphere(dense, args.dense, np)
        meshes = [
            ("bunny (69,451 triangles)", "obj", ROOT / "scenes/meshes/stanford-bunny.obj"),
            (f"displaced sphere ({n_dense:,} triangles)", "ply", dense),
        ]
    meshes += [(Path(p).name, "scene", Path(p).resolve()) for p in args.scene]
    rows = [
        "| mesh | rays | query | threads | penumbra Mrays/s | "
        + " | ".join(f"{v} Mrays/s | ratio vs {v}" for v in args.variants.split(","))
        + " | agree |",
        "|---|---|---|---:|---:|" + "---:|---:|" * len(args.variants.split(",")) + "---:|",
    ]
    for label, kind, path in meshes:
        if kind == "scene":
            xml = path
        else:
            xml = tmp / f"{path.stem}.xml"
            xml.write_text(SCENE.format(kind=kind, path=path))
        pen = penumbra.load(str(xml))
        scenes = {}
        for v in args.variants.split(","):
            mi.set_variant(v)
            scenes[v] = (mi.load_file(str(xml)), mi)
        mi.set_variant(args.variants.split(",")[0])
        bbox = scenes[args.variants.split(",")[0]][0].bbox()
        lo, hi = np.array(bbox.min, dtype=float).ravel(), np.array(bbox.max, dtype=float).ravel()
        for name, (o, d) in ray_batches(lo, hi, args.rays, np).items():
            for any_hit in (False, True):
                query = "occlusion" if any_hit else "closest"
                for n in threads:
                    p_times, p_out = [], None
                    for _ in range(args.repeat):
                        p_out, s = pen.cast(o, d, any=any_hit, threads=n)
                        p_times.append(s)
                    p_rate = len(o) / statistics.median(p_times) / 1e6
                    cells, agree = [], []
                    for v, (scene, _) in scenes.items():
                        mi.set_variant(v)
                        dr.set_thread_count(n)
                        coherent = name == "coherent"
                        mitsuba_cast(mi, dr, scene, o, d, any_hit, coherent)  # compile
                        m_times, m_out = [], None
                        for _ in range(args.repeat):
                            m_out, s = mitsuba_cast(mi, dr, scene, o, d, any_hit, coherent)
                            m_times.append(s)
                        m_rate = len(o) / statistics.median(m_times) / 1e6
                        cells.append(f"{m_rate:.2f} | {p_rate / m_rate:.2f}")
                        if any_hit:
                            same = (m_out > 0.5) == (p_out > 0.5)
                        else:
                            both_miss = ~np.isfinite(m_out) & ~np.isfinite(p_out)
                            close = np.abs(m_out - p_out) <= 1e-4 * np.maximum(1, np.abs(m_out))
                            same = both_miss | close
                        agree.append(f"{same.mean():.5f}")
                    row = (
                        f"| {label} | {name} | {query} | {n} | {p_rate:.2f} | "
                        + " | ".join(cells)
                        + f" | {', '.join(agree)} |"
                    )
                    rows.append(row)
                    print(row, flush=True)
    text = "\n".join(rows) + "\n"
    if args.out:
        Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
