#!/usr/bin/env python3
"""Check that scenes/cornell-box.xml is the scene ``mitsuba.cornell_box()`` builds.

Usage:
    python validation/mitsuba/check_cornell_xml.py [--xml scenes/cornell-box.xml]
        [--spp 256] [--variant auto|llvm_ad_rgb|scalar_rgb]

1. Loads both versions without Mitsuba's shape merging (``optimize=False``) and compares every
   parameter ``mi.traverse`` exposes under the same key (shape to_world matrices, cube vertex
   positions and normals, BSDF reflectances, light radiance), the sensor's parameters, and each
   shape's bounding box, BSDF id and emitter flag.
2. Renders both (the dict's film filter changed to box, as in the XML) at ``--spp`` with
   different seeds and compares the per-channel image means, with the standard error taken
   from per-pass image means (4 passes each).

Exits non-zero if a parameter differs by more than 1e-6 or a mean differs by more than
4 standard errors.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_util as mu  # noqa: E402

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def as_array(v):
    if hasattr(v, "matrix"):
        v = v.matrix
    return np.array(v, dtype=np.float64)


def compare_params(mi, sd, sx):
    pd, px = mi.traverse(sd), mi.traverse(sx)
    worst = 0.0
    common = sorted(set(pd.keys()) & set(px.keys()))
    for k in common:
        a, b = as_array(pd[k]), as_array(px[k])
        if a.shape != b.shape:
            print(f"  {k}: shape {a.shape} vs {b.shape}")
            worst = np.inf
            continue
        d = float(np.max(np.abs(a - b))) if a.size else 0.0
        worst = max(worst, d)
        print(f"  {k:42s} max |diff| {d:.3g}")
    # the sensor has no id in the XML, so its keys differ: compare it directly
    ps, qs = mi.traverse(sd.sensors()[0]), mi.traverse(sx.sensors()[0])
    for k in sorted(ps.keys()):
        d = float(np.max(np.abs(as_array(ps[k]) - as_array(qs[k]))))
        worst = max(worst, d)
        print(f"  sensor.{k:35s} max |diff| {d:.3g}")
    only = sorted(set(pd.keys()) ^ set(px.keys()))
    only = [k for k in only if not k.startswith("sensor.") and not k.startswith("object_")]
    if only:
        print("  keys in only one version:", only)
        worst = np.inf
    return worst


def compare_shapes(sd, sx):
    A = {s.id(): s for s in sd.shapes()}
    B = {s.id(): s for s in sx.shapes()}
    if sorted(A) != sorted(B):
        print("  shape ids differ:", sorted(A), sorted(B))
        return np.inf
    worst = 0.0
    for k in A:
        ba, bb = A[k].bbox(), B[k].bbox()
        d = max(np.abs(np.array(ba.min) - np.array(bb.min)).max(),
                np.abs(np.array(ba.max) - np.array(bb.max)).max())
        same = (A[k].is_emitter() == B[k].is_emitter()
                and A[k].bsdf().id() == B[k].bsdf().id())
        worst = max(worst, float(d) if same else np.inf)
        print(f"  {k:11s} bbox min {np.array(ba.min)} max {np.array(ba.max)} |diff| {d:.3g} "
              f"bsdf {B[k].bsdf().id()} emitter {B[k].is_emitter()} {'ok' if same else 'MISMATCH'}")
    return worst


def image_means(mi, scene, spp, seed0, passes=4):
    per = []
    for k in range(passes):
        img = mu.to_numpy(mi.render(scene, seed=seed0 + k, spp=max(1, spp // passes)))
        per.append(img[..., :3].reshape(-1, 3).mean(0).astype(np.float64))
    per = np.array(per)
    return per.mean(0), per.std(0, ddof=1) / np.sqrt(passes)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--xml", default=os.path.join(REPO_ROOT, "scenes", "cornell-box.xml"))
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--variant", choices=mu.VARIANT_CHOICES, default="auto")
    args = p.parse_args(argv)

    mi, variant = mu.select_variant(args.variant)
    d = mi.cornell_box()
    d["sensor"]["film"]["rfilter"] = {"type": "box"}
    sd = mi.load_dict(d, optimize=False)
    sx = mi.load_file(args.xml, optimize=False)

    print("parameters (mi.traverse):")
    wp = compare_params(mi, sd, sx)
    print("shapes:")
    ws = compare_shapes(sd, sx)
    print(f"largest parameter difference {wp:.3g}, largest bbox difference {ws:.3g}")

    print(f"renders ({variant}, {args.spp} spp each, box filter):")
    md, sed = image_means(mi, mi.load_dict(d), args.spp, 1000)
    mx, sex = image_means(mi, mi.load_file(args.xml), args.spp, 2000)
    z = (md - mx) / np.sqrt(sed ** 2 + sex ** 2)
    print(f"  dict mean {md} +- {sed}")
    print(f"  xml  mean {mx} +- {sex}")
    print(f"  difference {md - mx}, z {z}")
    ok = wp <= 1e-6 and ws <= 1e-6 and np.all(np.abs(z) < 4)
    print("OK" if ok else "MISMATCH")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
