#!/usr/bin/env python3
"""Side-by-side efficiency of penumbra and Mitsuba 3.9.1 on the validation scenes.

For every landed scene in validation/scenes.toml, renders the scene with penumbra (the
release binary) and with Mitsuba (each requested variant; the scene is loaded once and
rendered once untimed so that the llvm JIT is warm), all at the same spp, in one run on the
same machine. For each render it measures the render time (scene loading excluded on both
sides) and the MSE against the scene's reference, and reports the efficiency ratio

    ratio = (t_mitsuba * MSE_mitsuba) / (t_penumbra * MSE_penumbra)

(> 1: penumbra reaches a given error faster). Times and MSEs are medians over --repeat runs
with distinct seeds.

Usage:
    cargo build --release
    .venv/bin/python validation/perf/side_by_side.py [--spp 64] [--repeat 3]
        [--scene NAME ...] [--variants llvm_ad_rgb,scalar_rgb] [--threads N] [--out FILE.md]
        [--engine scalar --engine lanes]

With --engine (repeatable) penumbra renders each scene with each of its engines (`penumbra
render --engine`), one row per scene and engine, against the same Mitsuba renders.

A spectral entry (`mode = "spectral"`) renders with `--mode spectral` and is compared with
Mitsuba's spectral variants (`--variants llvm_ad_spectral,scalar_spectral`).
`--scenes validation/perf/spectral-media.toml` measures two of Mitsuba's media scenes that
way, against the suite's spectral references.
"""

import argparse
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LLVM = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"


def load_exr(path):
    import mitsuba as mi
    import numpy as np

    bmp = mi.Bitmap(str(path))
    names = [bmp.struct_()[i].name for i in range(bmp.channel_count())]
    arr = np.array(bmp, copy=False).reshape(bmp.height(), bmp.width(), -1)
    return np.stack([arr[..., names.index(c)] for c in "RGB"], axis=-1).astype(np.float64)


def mse(a, b):
    import numpy as np

    return float(np.mean((a - b) ** 2))


def penumbra_run(exe, scene, spp, seed, threads, tmp, engine=None):
    out = Path(tmp) / "p.exr"
    stats = Path(tmp) / "p.json"
    cmd = [str(exe), "render", str(ROOT / scene["file"]), "--spp", str(spp), "--seed", str(seed),
           "--quiet", "-o", str(out), "--stats", str(stats)]
    for k, v in scene.get("defines", {}).items():
        cmd += ["-D", f"{k}={v}"]
    if "integrator" in scene:
        cmd += ["--integrator", scene["integrator"]]
    if threads:
        cmd += ["--threads", str(threads)]
    if engine:
        cmd += ["--engine", engine]
    if scene.get("mode") == "spectral":
        cmd += ["--mode", "spectral"]
    subprocess.run(cmd, check=True)
    seconds = json.loads(stats.read_text())["seconds"]
    return seconds, load_exr(out)


def mitsuba_integrator(scene):
    """The integrator Mitsuba renders the entry with where it is not the file's own: the
    entry's `mitsuba_integrator` (a JSON dict, as its reference was rendered), or, for an
    entry whose penumbra render uses `integrator` (`--integrator`), Mitsuba's integrator of
    that name with the file's max_depth (a <default> the entry's defines may set), so that
    both sides run the same algorithm (the reference itself is the path-traced one)."""
    import mitsuba as mi

    if "mitsuba_integrator" in scene:
        return mi.load_dict(json.loads(scene["mitsuba_integrator"]))
    if "integrator" in scene:
        text = (ROOT / scene["file"]).read_text()
        m = re.search(r'<default\s+name="max_depth"\s+value="(-?\d+)"', text)
        depth = scene.get("defines", {}).get("max_depth", m.group(1) if m else "-1")
        try:
            return mi.load_dict({"type": scene["integrator"], "max_depth": int(depth)})
        except RuntimeError:
            # penumbra's own integrators (whitted) have no Mitsuba plugin: Mitsuba renders
            # the file's integrator, the one its reference was rendered with.
            return None
    return None


def mitsuba_runs(scene, spp, seeds, variant, threads):
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    spectral = scene.get("mode") == "spectral"
    if spectral != variant.endswith("_spectral"):
        raise SystemExit(f"{scene['name']} renders in {'spectral' if spectral else 'RGB'} mode: "
                         f"compare it with Mitsuba's matching variants, not {variant}")
    mi.set_variant(variant)
    defines = dict(scene.get("defines", {}))
    s = mi.load_file(str(ROOT / scene["file"]), **defines)
    integrator = mitsuba_integrator(scene)
    extra = {"integrator": integrator} if integrator is not None else {}
    # Dr.Jit's thread pool renders every variant, scalar_rgb included. It is narrowed only
    # around the renders: with one thread, Mitsuba's EXR reader (scene textures, load_exr)
    # hangs.
    default_threads = dr.thread_count()
    if threads:
        dr.set_thread_count(threads)
    try:
        np.array(mi.render(s, spp=spp, seed=10_000, **extra))  # warm-up (JIT compile), untimed
        results = []
        for seed in seeds:
            t0 = time.perf_counter()
            img = np.array(mi.render(s, spp=spp, seed=seed, **extra))  # forces evaluation
            results.append((time.perf_counter() - t0, img[..., :3].astype(np.float64)))
    finally:
        dr.set_thread_count(default_threads)
    return results


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--scene", action="append", help="only these scenes (repeatable)")
    ap.add_argument("--scenes", type=Path, default=ROOT / "validation" / "scenes.toml",
                    help="the scene list (default validation/scenes.toml; e.g. "
                         "validation/perf/spectral-media.toml)")
    ap.add_argument("--variants", default="llvm_ad_rgb,scalar_rgb")
    ap.add_argument("--threads", type=int, default=None,
                    help="threads of both renderers (penumbra --threads, Mitsuba's Dr.Jit "
                         "thread pool); default: every core")
    ap.add_argument("--out", type=Path, help="also write the markdown table here")
    ap.add_argument("--penumbra", type=Path, default=ROOT / "target" / "release" / "penumbra",
                    help="the penumbra binary (default: target/release/penumbra; e.g. the "
                         "profile-guided build of deploy/pgo.sh)")
    ap.add_argument("--engine", action="append", choices=["scalar", "lanes"],
                    help="penumbra's engine (repeatable: a row per engine); default: "
                         "penumbra's default")
    args = ap.parse_args()
    if os.path.exists(LLVM):
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", LLVM)
    if "llvm_ad_rgb" in args.variants and not os.path.exists(
            os.environ.get("DRJIT_LIBLLVM_PATH", "")):
        # Without it Dr.Jit picks up whatever libLLVM it finds; Debian's LLVM 15 aborts in
        # code generation ("Cannot select: fminimum").
        sys.exit(f"llvm_ad_rgb needs LLVM 19: apt-get install -y libllvm19 (expected {LLVM}), "
                 "or set DRJIT_LIBLLVM_PATH")

    scenes = tomllib.loads(args.scenes.read_text())["scene"]
    scenes = [s for s in scenes if s["status"] == "landed" and (not args.scene or s["name"] in args.scene)]
    variants = [v for v in args.variants.split(",") if v]
    seeds = list(range(1, args.repeat + 1))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for sc in scenes:
            ref = load_exr(ROOT / sc["reference"])
            paths = ref.shape[0] * ref.shape[1] * args.spp
            scene_rows = []
            for engine in args.engine or [None]:
                pen = [penumbra_run(args.penumbra, sc, args.spp, s, args.threads, tmp, engine)
                       for s in seeds]
                pt = statistics.median(t for t, _ in pen)
                pm = statistics.median(mse(img, ref) for _, img in pen)
                name = sc["name"] + (f" ({engine})" if args.engine else "")
                scene_rows.append({"scene": name, "penumbra_s": pt, "penumbra_mse": pm,
                                   "penumbra_mpaths": paths / pt / 1e6})
            for v in variants:
                runs = mitsuba_runs(sc, args.spp, seeds, v, args.threads)
                mt = statistics.median(t for t, _ in runs)
                mm = statistics.median(mse(img, ref) for _, img in runs)
                for row in scene_rows:
                    row[v] = {"s": mt, "mse": mm,
                              "ratio": (mt * mm) / (row["penumbra_s"] * row["penumbra_mse"]),
                              "mpaths": paths / mt / 1e6}
            for row in scene_rows:
                rows.append(row)
                print(json.dumps(row), file=sys.stderr)

    head = ["scene", "penumbra s", "Mpath/s", "MSE"]
    for v in variants:
        head += [f"{v} s", "Mpath/s", "MSE", f"efficiency ratio vs {v}"]
    options = f" --threads {args.threads}" if args.threads else ""
    if args.penumbra != ap.get_default("penumbra"):
        options += f" --penumbra {args.penumbra}"
    for engine in args.engine or []:
        options += f" --engine {engine}"
    if args.variants != ap.get_default("variants"):
        options += f" --variants {args.variants}"
    if args.scenes != ap.get_default("scenes"):
        options += f" --scenes {args.scenes.resolve().relative_to(ROOT)}"
    lines = [
        f"Side-by-side at {args.spp} spp, medians of {args.repeat} seeds, "
        f"{args.threads or os.cpu_count()} thread(s); "
        f"machine: {platform.machine()}, {os.cpu_count()} cores; "
        f"command: `python validation/perf/side_by_side.py --spp {args.spp} --repeat {args.repeat}{options}`",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
    ]
    for r in rows:
        cells = [r["scene"], f"{r['penumbra_s']:.3f}", f"{r['penumbra_mpaths']:.2f}",
                 f"{r['penumbra_mse']:.3e}"]
        for v in variants:
            cells += [f"{r[v]['s']:.3f}", f"{r[v]['mpaths']:.2f}", f"{r[v]['mse']:.3e}",
                      f"{r[v]['ratio']:.2f}"]
        lines.append("| " + " | ".join(cells) + " |")
    table = "\n".join(lines)
    print(table)
    if args.out:
        args.out.write_text(table + "\n")


if __name__ == "__main__":
    main()
