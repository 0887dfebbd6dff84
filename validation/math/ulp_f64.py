#!/usr/bin/env python3
"""Measures the error of penumbra's f64 elementary functions (src/math/elementary.rs) in ulps
against 50-digit values from mpmath.

    PENUMBRA_ULP_DUMP=samples.txt cargo test --release --lib elementary::tests::measure_ulp_exhaustive -- --ignored
    python3 validation/math/ulp_f64.py samples.txt

The dump holds one line per sample: the function's name, its arguments and its result, as the
hex bits of f64 values. Prints, per function, the sample count and the largest error in ulps
(the spacing of f64 at the exact value) with the argument where it occurred.
"""
import struct
import sys

from mpmath import mp, mpf, sin, cos, exp, log, atan2, acos, floor, log as mlog

mp.dps = 50
EXACT = {"sin": sin, "cos": cos, "exp": exp, "ln": log, "atan2": atan2, "acos": acos}


def f64(h):
    return struct.unpack("<d", struct.pack("<Q", int(h, 16)))[0]


def ulp(v):
    v = abs(v)
    if v == 0:
        return mpf(2) ** -1074
    e = int(floor(mlog(v, 2)))
    return mpf(2) ** max(e - 52, -1074)


def main(path):
    worst = {}
    for line in open(path):
        name, *hexes = line.split()
        *args, got = [f64(h) for h in hexes]
        exact = EXACT[name](*[mpf(a) for a in args])
        err = abs(mpf(got) - exact) / ulp(exact)
        n, w, at = worst.get(name, (0, mpf(0), None))
        worst[name] = (n + 1, max(w, err), args if err > w else at)
    for name, (n, w, at) in worst.items():
        print(f"{name}: {n} samples, max error {mp.nstr(w, 4)} ulp at {at}")


if __name__ == "__main__":
    main(sys.argv[1])
