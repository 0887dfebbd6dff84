#!/usr/bin/env python3
"""Mitsuba 3.9.1's own samplers on a penumbra validation scene: RMSE and image-mean bias
against the scene's reference (an independent-sampler Mitsuba render), per sampler, so that
penumbra's samplers (`penumbra converge ... --sweep sampler=...`) can be compared with
Mitsuba's side by side.

Usage:
    python validation/mitsuba/sampler_rmse.py [--scene scenes/cornell-box.xml]
        [--reference validation/references/cornell-box.exr] [--spp 1024] [--seeds 2]
        [--variant llvm_ad_rgb] [-D res=128 ...]

Prints one line per sampler: the mean over seeds of the RMSE, the image-mean difference per
channel in percent and in standard errors of the seed mean, and the render time.
"""
import argparse
import re
import time

import numpy as np
import mitsuba as mi

SAMPLERS = ["independent", "stratified", "multijitter", "orthogonal", "ldsampler"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="scenes/cornell-box.xml")
    ap.add_argument("--reference", default="validation/references/cornell-box.exr")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("-D", action="append", default=["res=128"])
    a = ap.parse_args()
    mi.set_variant(a.variant)
    defines = dict(d.split("=", 1) for d in a.D)
    ref = np.array(mi.Bitmap(a.reference), dtype=np.float64)[..., :3]
    text = open(a.scene).read()
    for s in SAMPLERS:
        xml = re.sub(r'<sampler type="\w+"', f'<sampler type="{s}"', text)
        scene = mi.load_string(xml, **defines)
        rmse, means, secs = [], [], []
        for seed in range(a.seeds):
            t = time.time()
            img = np.array(mi.render(scene, spp=a.spp, seed=seed), dtype=np.float64)[..., :3]
            secs.append(time.time() - t)
            rmse.append(np.sqrt(np.mean((img - ref) ** 2)))
            means.append(img.reshape(-1, 3).mean(0))
        means = np.array(means)
        diff = means.mean(0) / ref.reshape(-1, 3).mean(0) - 1
        print(
            f"{s:12s} spp {a.spp}  RMSE {np.mean(rmse):.4e}  mean diff "
            + " / ".join(f"{100 * d:+.3f}%" for d in diff)
            + f"  time {np.median(secs):.2f} s"
        )


if __name__ == "__main__":
    main()
