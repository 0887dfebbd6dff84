#!/usr/bin/env python3
"""The ladder of classic algorithms (scenes/ladder, docs/classic.md): renders each of the six
rungs and compares it with its path-traced reference, printing a Markdown table of time and
error per rung (the z-test uses both images' per-sample variances). Python's standard library only; it runs the penumbra binary.

    cargo build --release
    python3 validation/ladder.py                 # the table (128x128, the scene files' spp)
    python3 validation/ladder.py --figure docs/ladder   # also the README's pictures

References (validation/references): Mitsuba 3.9.1's path tracer at 16384 spp for the
diffuse spheres (rungs 1, 2, 5) and the mirror and glass spheres (rungs 3, 6); penumbra's
path tracer at 16384 spp for the Phong spheres (rung 4: Mitsuba 3 has no phong BSDF).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (scene, what it shows, reference)
RUNGS = [
    ("1-ray-casting", "ray casting (no shadows)", "ladder-diffuse"),
    ("2-shadows", "+ shadow rays", "ladder-diffuse"),
    ("3-whitted", "Whitted: mirror + glass", "ladder-specular"),
    ("4-phong", "Phong spheres (Whitted)", "ladder-phong"),
    ("5-radiosity", "radiosity (final gather)", "ladder-diffuse"),
    ("6-path", "path tracing", "ladder-specular"),
]


def run(args):
    res = subprocess.run(args, cwd=ROOT, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit(f"{' '.join(args)} failed:\n{res.stderr.strip()}")
    return res


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--penumbra", default=os.path.join(ROOT, "target", "release", "penumbra"),
                   help="the penumbra binary (default: target/release/penumbra)")
    p.add_argument("--spp", type=int, default=None,
                   help="samples per pixel for every rung (default: each scene file's 64)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--figure", metavar="DIR", default=None,
                   help="also render each rung at 256x256 with --figure-spp into DIR/N.png")
    p.add_argument("--figure-spp", type=int, default=1024)
    args = p.parse_args()
    if not os.path.exists(args.penumbra):
        sys.exit(f"{args.penumbra} not found: run `cargo build --release` first")

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene, what, ref in RUNGS:
            exr = os.path.join(tmp, scene + ".exr")
            stats = os.path.join(tmp, scene + ".json")
            cmd = [args.penumbra, "render", f"scenes/ladder/{scene}.xml", "-D", "res=128",
                   "--seed", str(args.seed), "-o", exr, "--stats", stats, "--variance"]
            if args.spp:
                cmd += ["--spp", str(args.spp)]
            run(cmd)
            with open(stats) as f:
                st = json.load(f)
            cmp = json.loads(run([args.penumbra, "compare", exr,
                                  f"validation/references/{ref}.exr", "--json"]).stdout)
            rows.append((scene, what, ref, st, cmp))
            print(f"{scene}: {st['seconds']:.2f} s, RMSE {cmp['rmse']:.4e}", file=sys.stderr)

    print("| rung | spp | time (s) | RMSE | relMSE | image mean vs. reference (R, G, B) "
          "| z-test pass | reference |")
    print("|---|---:|---:|---:|---:|---|---:|---|")
    for scene, what, ref, st, cmp in rows:
        bias = " / ".join(f"{100 * d:+.1f}%" for d in cmp["mean_rel_diff"])
        z = cmp.get("z_test") or {}
        zpass = f"{100 * z['pass_rate']:.1f}%" if "pass_rate" in z else "-"
        print(f"| {scene} ({what}) | {st['spp']} | {st['seconds']:.2f} | {cmp['rmse']:.4f} "
              f"| {cmp['rel_mse']:.2e} | {bias} | {zpass} | {ref} |")

    if args.figure:
        os.makedirs(os.path.join(ROOT, args.figure), exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            for i, (scene, _, _, _, _) in enumerate(rows, 1):
                png = os.path.join(args.figure, f"{i}.png")
                run([args.penumbra, "render", f"scenes/ladder/{scene}.xml", "-D", "res=256",
                     "--spp", str(args.figure_spp), "--seed", str(args.seed),
                     "-o", os.path.join(tmp, "x.exr"), "--preview", png])
                print(f"wrote {png}", file=sys.stderr)


if __name__ == "__main__":
    main()
