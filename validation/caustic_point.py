#!/usr/bin/env python3
"""sppm, ptracer and path on the point-light caustic (scenes/caustic-glass-point.xml, 64x64),
measured on the pixels the reference is valid for.

The reference is Mitsuba 3.9.1's particle tracer (validation/references/caustic-glass-point.exr,
524,288 spp): light tracing is unbiased for every pixel that sees a diffuse surface directly,
and renders the glass sphere itself black (a delta surface cannot be connected to the camera).
The comparison therefore uses the pixels whose reference value is non-zero and none of whose
eight neighbours is zero: the sphere's pixels and its silhouette's are left out. On those
pixels sppm, the particle tracer and the path tracer (which cannot produce this caustic: a
control) are compared against the reference at a ladder of sample counts, each render timed.

    pip install ./python numpy          # the penumbra module (docs/python.md)
    python validation/caustic_point.py [--budget 60]
"""

import argparse
import time

import numpy as np
import penumbra

SCENE = "scenes/caustic-glass-point.xml"
REFERENCE = "validation/references/caustic-glass-point.exr"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--budget", type=float, default=60.0,
                   help="each ladder stops before a step (4x the spp of the last) would take "
                   "longer than this, in seconds (60)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()

    ref, ref_var, attrs = penumbra.read_exr(REFERENCE)
    ref_spp = float(attrs.get("spp", 524288))
    zero = ref.max(axis=2) == 0
    near_zero = zero.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_zero |= np.roll(np.roll(zero, dy, axis=0), dx, axis=1)
    mask = ~near_zero
    print(f"{mask.sum()} of {mask.size} pixels compared ({zero.sum()} black in the reference "
          f"where the camera sees the glass sphere, {(near_zero & ~zero).sum()} beside them)")
    r = ref[mask]
    print("| integrator | spp | time (s) | RMSE | relMSE | mean vs. reference | z-test pass |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for integrator in ("path", "ptracer", "sppm"):
        scene = penumbra.load(SCENE, res=64, integrator=integrator)
        spp = 4
        while True:
            t0 = time.perf_counter()
            out = scene.render(spp=spp, seed=args.seed, variance=True)
            seconds = time.perf_counter() - t0
            img, var = out
            a = img[mask]
            d = a - r
            rmse = float(np.sqrt(np.mean(d * d)))
            rel = float(np.mean(d * d / (r * r + 0.01)))
            mean = float(a.mean() / r.mean() - 1.0)
            # z-test with both images' per-sample variances; none for sppm, whose pixels are
            # not means of independent samples (its noise has no per-sample variance).
            zpass = "–"
            if integrator != "sppm":
                z = np.abs(d) / np.sqrt(var[mask] / spp + ref_var[mask] / ref_spp + 1e-30)
                zpass = f"{100 * np.mean(z < _sidak_z(0.01, z.size)):.2f}%"
            print(f"| {integrator} | {spp} | {seconds:.2f} | {rmse:.3e} | {rel:.3e} | "
                  f"{100 * mean:+.2f}% | {zpass} |", flush=True)
            if 4 * seconds > args.budget:
                break
            spp *= 4


def _sidak_z(alpha, n):
    """The two-sided normal critical value of a Šidák-corrected family of n tests."""
    from statistics import NormalDist
    a = 1.0 - (1.0 - alpha) ** (1.0 / n)
    return NormalDist().inv_cdf(1.0 - a / 2.0)


if __name__ == "__main__":
    main()
