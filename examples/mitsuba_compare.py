"""Render the Cornell box with penumbra and with Mitsuba 3 from Python, and compare the two
arrays with penumbra's per-pixel z-test (Mitsuba's acceptance rule: at least 99.75% of the
pixel-channels pass at family level alpha = 0.01).

    python examples/mitsuba_compare.py [--res 64] [--spp 1024] [--variant scalar_rgb]

Needs the penumbra module (`pip install ./python`) and Mitsuba (`pip install mitsuba==3.9.1`).
`--variant llvm_ad_rgb` is Mitsuba's fast CPU variant; it needs libLLVM (Debian:
`apt-get install libllvm19` and DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1).
"""

import argparse
import time
from pathlib import Path

import mitsuba as mi
import numpy as np

import penumbra

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "cornell-box.xml"

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--res", type=int, default=64)
parser.add_argument("--spp", type=int, default=1024)
parser.add_argument("--passes", type=int, default=64, help="Mitsuba passes (for its variance)")
parser.add_argument("--variant", default="scalar_rgb")
args = parser.parse_args()

# penumbra: the image and its per-sample variance in one call.
scene = penumbra.load(SCENE, res=args.res)
start = time.perf_counter()
ours, our_var = scene.render(spp=args.spp, seed=0, variance=True)
our_time = time.perf_counter() - start

# Mitsuba: `passes` renders with their own seeds; the spread of the pass means gives the
# per-sample variance (pass_spp x the variance of a pass mean), as penumbra reports it.
mi.set_variant(args.variant)
mscene = mi.load_file(str(SCENE), res=args.res)
pass_spp = args.spp // args.passes
start = time.perf_counter()
passes = np.stack(
    [np.array(mi.render(mscene, spp=pass_spp, seed=k))[..., :3] for k in range(args.passes)]
)
mi_time = time.perf_counter() - start
theirs = passes.mean(axis=0)
their_var = pass_spp * passes.var(axis=0, ddof=1)
their_spp = pass_spp * args.passes

result = penumbra.compare(ours, theirs, spp_a=args.spp, spp_b=their_spp, var_a=our_var, var_b=their_var)
z = result["z_test"]
print(f"Cornell box {args.res}x{args.res}: penumbra {args.spp} spp in {our_time:.2f} s, "
      f"Mitsuba {args.variant} {their_spp} spp in {mi_time:.2f} s")
print(f"image means (R, G, B): penumbra {np.round(result['mean_a'], 5).tolist()}, "
      f"Mitsuba {np.round(result['mean_b'], 5).tolist()}")
print(f"relative difference of the means: {[f'{100 * d:+.2f}%' for d in result['mean_rel_diff']]}")
print(f"RMSE {result['rmse']:.4e}, relative MSE {result['rel_mse']:.4e}")
print(f"z-test: {z['failures']} of {z['tests']} pixel-channels beyond |z| = {z['z_critical']:.2f} "
      f"(pass rate {100 * z['pass_rate']:.2f}%): {'PASS' if z['passed'] else 'FAIL'}")
