#!/usr/bin/env python3
"""Time Mitsuba 3 rendering a scene, for comparison with penumbra.

Usage:
    python validation/mitsuba/time_mitsuba.py SCENE.xml --spp N
        [--variant auto|llvm_ad_rgb|scalar_rgb] [--repeat 3] [-D name=value ...]

Loads the scene (scene loading is not timed), renders once at N spp to warm up (JIT kernel
compilation in llvm variants; not timed), then times ``--repeat`` renders at N spp with distinct
seeds. Each timed render is forced to completion by converting it to a numpy array (llvm
variants record lazily). Prints one JSON object:

    variant, spp, width, height, seconds (median), all_seconds, mpaths_per_s
    (= width*height*spp / seconds / 1e6, camera paths), channel_means (R, G, B of the last
    timed render), scene, defines, mitsuba_version, cpu_count.

Render one scene at a time: the machine has 2 cores and Mitsuba uses all of them.
"""

import argparse
import json
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_util as mu  # noqa: E402


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="Mitsuba 3 XML scene")
    p.add_argument("--spp", type=int, required=True, help="samples per pixel per render")
    p.add_argument("--variant", choices=mu.VARIANT_CHOICES, default="auto",
                   help="auto = llvm_ad_rgb if it works, else scalar_rgb")
    p.add_argument("--repeat", type=int, default=3, help="number of timed renders (3)")
    p.add_argument("--seed-base", type=int, default=0,
                   help="warm-up uses seed_base, timed render k uses seed_base + 1 + k")
    p.add_argument("-D", dest="defines", action="append", default=[], metavar="NAME=VALUE",
                   help="XML $NAME substitution (repeatable)")
    args = p.parse_args(argv)
    if args.spp < 1 or args.repeat < 1:
        p.error("--spp and --repeat must be positive")
    return args


def main(argv=None):
    args = parse_args(argv)
    defines = mu.parse_defines(args.defines)
    mi, variant = mu.select_variant(args.variant)
    scene = mu.load_scene(mi, args.scene, defines)
    width, height, _ = mu.film_info(scene)

    t = time.perf_counter()
    mu.to_numpy(mi.render(scene, seed=args.seed_base, spp=args.spp))
    warmup = time.perf_counter() - t

    times = []
    img = None
    for k in range(args.repeat):
        t = time.perf_counter()
        img = mu.to_numpy(mi.render(scene, seed=args.seed_base + 1 + k, spp=args.spp))
        times.append(time.perf_counter() - t)

    seconds = statistics.median(times)
    paths = width * height * args.spp
    result = {
        "scene": args.scene,
        "variant": variant,
        "spp": args.spp,
        "width": width,
        "height": height,
        "seconds": round(seconds, 4),
        "all_seconds": [round(s, 4) for s in times],
        "warmup_seconds": round(warmup, 4),
        "mpaths_per_s": round(paths / seconds / 1e6, 4),
        "channel_means": [float(v) for v in img[..., :3].reshape(-1, 3).mean(0)],
        "defines": defines,
        "mitsuba_version": mi.__version__,
        "cpu_count": os.cpu_count(),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
