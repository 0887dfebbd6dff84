#!/usr/bin/env python3
"""Scene load time and peak memory, penumbra against Mitsuba 3.9.1, on the same file.

Usage:
    .venv/bin/python validation/perf/load_time.py SCENE.xml [-D name=value ...]
        [--repeat 3] [--variant llvm_ad_rgb] [--penumbra target/release/penumbra]

penumbra: `penumbra render SCENE -D ... --spp 1` with the film forced to 1x1 pixel
(-D overrides of the scene's resolution defaults, given with -D like the others), timed as
a whole process: parse, load every mesh and texture, build the BVH, one sample, write the
EXR. Mitsuba: a Python process that imports mitsuba, sets the variant (timed apart) and
calls `mi.load_file` (timed: parse, load, build the acceleration structure); peak RSS of
each whole process (getrusage of the child), and Mitsuba's RSS after the import alone, so
that its interpreter's share can be told apart. Runs alternate penumbra and Mitsuba;
medians of --repeat runs, with min and max.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

MITSUBA_CHILD = r"""
import json, sys, time, resource
t0 = time.perf_counter()
import mitsuba as mi
mi.set_variant(sys.argv[1])
t1 = time.perf_counter()
rss_import = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
defines = json.loads(sys.argv[3])
scene = mi.load_file(sys.argv[2], **defines)
t2 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "load": t2 - t1, "rss_import_kb": rss_import,
                  "shapes": len(scene.shapes())}))
"""


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("-D", dest="defines", action="append", default=[])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--penumbra", default="target/release/penumbra")
    a = p.parse_args()
    defines = dict(d.split("=", 1) for d in a.defines)
    pen, mit = [], []
    with tempfile.TemporaryDirectory() as tmp:
        out_exr = os.path.join(tmp, "out.exr")
        for _ in range(a.repeat):
            cmd = [a.penumbra, "render", a.scene, "--spp", "1", "-q", "-o", out_exr]
            for k, v in defines.items():
                cmd += ["-D", f"{k}={v}"]
            # peak RSS of this process alone: /usr/bin/time's %M
            t = time.perf_counter()
            r = subprocess.run(["/usr/bin/time", "-f", "%M"] + cmd, check=True,
                               capture_output=True, text=True)
            wall = time.perf_counter() - t
            pen.append((wall, int(r.stderr.strip().splitlines()[-1])))
            t = time.perf_counter()
            r = subprocess.run(["/usr/bin/time", "-f", "%M", sys.executable, "-c",
                                MITSUBA_CHILD, a.variant, a.scene, json.dumps(defines)],
                               check=True, capture_output=True, text=True)
            wall = time.perf_counter() - t
            info = json.loads(r.stdout.strip().splitlines()[-1])
            info["wall"] = wall
            info["rss_kb"] = int(r.stderr.strip().splitlines()[-1])
            mit.append(info)

    def stat(xs):
        return f"{statistics.median(xs):.2f} (min {min(xs):.2f}, max {max(xs):.2f})"

    print(f"scene {a.scene} {defines}, {a.repeat} runs alternated")
    print(f"penumbra process (load + build + 1 sample): {stat([w for w, _ in pen])} s, "
          f"peak RSS {statistics.median([m for _, m in pen]) / 1024:.0f} MiB")
    print(f"mitsuba {a.variant} mi.load_file: {stat([m['load'] for m in mit])} s; "
          f"import + set_variant {stat([m['import'] for m in mit])} s; "
          f"process {stat([m['wall'] for m in mit])} s")
    print(f"mitsuba peak RSS {statistics.median([m['rss_kb'] for m in mit]) / 1024:.0f} MiB "
          f"(after import alone {statistics.median([m['rss_import_kb'] for m in mit]) / 1024:.0f}"
          f" MiB), {mit[0]['shapes']} shapes")


if __name__ == "__main__":
    main()
