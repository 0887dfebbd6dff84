#!/usr/bin/env python3
"""How well does Mitsuba 3.9.1 itself reproduce the image means of its regression suite's
references? For every scene of validation/mitsuba-suite, renders it N times (seeds 1000..)
at the suite's sample count (2,000,000 // pixels) with the scene's own integrator, and prints
per channel the mean of the N image means, its standard error from the N renders' spread,
the reference's image mean and z = (Mitsuba - reference) / se.

A reference whose mean Mitsuba 3.9.1 does not reproduce (|z| well above what 123
scene-channels allow) cannot serve as the truth of penumbra's image-mean test: the test then
compares with Mitsuba's own mean recorded here (tests/spectral_suite.rs, MITSUBA_MEANS).

Usage: python validation/suite-means/suite_means.py [--mode spectral|rgb] [--n 8] [--scene SUBSTR] \
           > validation/mitsuba-suite/spectral-means.txt
(llvm_ad_* variants: set DRJIT_LIBLLVM_PATH to libLLVM). mitsuba_means.py beside it checks one
seed-0 scalar_rgb render per scene for the RGB suite's offsets.
"""
import argparse
import glob
import os

import mitsuba as mi
import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "mitsuba-suite", "tests", "scenes")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mode", default="spectral")
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--scene", default="")
    ap.add_argument("--variant", default=None)
    a = ap.parse_args()
    mi.set_variant(a.variant or "llvm_ad_" + a.mode)
    mi.set_log_level(mi.LogLevel.Error)
    print("# scene | Mitsuba %s %s, %d renders: mean R G B | se R G B | reference mean R G B | z R G B"
          % (mi.__version__, mi.variant(), a.n))
    for path in sorted(glob.glob(os.path.join(ROOT, "*", "*.xml"))):
        name = os.path.relpath(path, ROOT)[:-4]
        if a.scene not in name:
            continue
        group, base = os.path.split(name)
        integrator = base.rsplit("_", 1)[1]
        ref_base = base.rsplit("_", 1)[0]
        ref = os.path.join(ROOT, group, "refs", "%s_ref_%s.exr" % (ref_base, a.mode))
        r = np.array(mi.Bitmap(ref), dtype=np.float64)[..., :3]
        spp = 2_000_000 // (r.shape[0] * r.shape[1])
        scene = mi.load_file(path, spp=spp, integrator=integrator)
        means = []
        for k in range(a.n):
            img = np.array(mi.render(scene, spp=spp, seed=1000 + k), dtype=np.float64)[..., :3]
            means.append(img.reshape(-1, 3).mean(0))
        means = np.array(means)
        m = means.mean(0)
        se = means.std(0, ddof=1) / np.sqrt(a.n)
        rm = r.reshape(-1, 3).mean(0)
        z = (m - rm) / np.maximum(se, 1e-30)
        f = lambda v: " ".join("%.6g" % x for x in v)
        print("%s | %s | %s | %s | %s" % (name, f(m), f(se), f(rm), " ".join("%+.2f" % x for x in z)),
              flush=True)


if __name__ == "__main__":
    main()
