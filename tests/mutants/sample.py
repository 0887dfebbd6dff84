#!/usr/bin/env python3
"""A uniform random sample of cargo-mutants' mutants, drawn with a stated seed (issue 44).

    python3 tests/mutants/sample.py [--seed 44] [--n 400] [--listing LIST] > sample.txt
    python3 tests/mutants/sample.py --seed 44 --n 400 --run OUT [-- CARGO_MUTANTS_ARGS...]
    python3 tests/mutants/sample.py --seed 44 --n 400 --part 3/8 --run OUT3 [-- ...]

The population is the output of `cargo mutants --list` (run here unless `--listing` names a
saved copy): every mutant of the files `.cargo/mutants.toml` examines. `random.Random(seed)
.sample` draws `n` of them without replacement, each equally likely, and the sample is
printed one name per line in listing order. With `--run OUT`, cargo mutants is run on
exactly those mutants (one anchored `--re` per name) with the configured fast tier, its
output in OUT; then `python3 tests/mutants/summarize.py OUT --sample sample.txt` scores them.
`--part k/K` (k = 1..K) keeps every K-th drawn name from the k-th on: the run splits into K
parts of ~2 minutes a mutant each, for separate sittings or machines, which `summarize.py
OUT1 OUT2 ... --sample sample.txt` pools. Every part must use the same listing (one commit).

Standard library only. The sample depends only on the seed and the listing, so anyone with
the same commit draws the same mutants.
"""

import argparse
import random
import re
import subprocess
import sys


def listing(path):
    if path:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    else:
        text = subprocess.run(
            ["cargo", "mutants", "--list"], check=True, capture_output=True, text=True
        ).stdout
    return [line for line in text.splitlines() if line.strip()]


def draw(names, n, seed):
    """`n` names drawn uniformly without replacement, in the listing's order."""
    if n > len(names):
        raise SystemExit(f"cannot draw {n} of {len(names)} mutants")
    chosen = set(random.Random(seed).sample(range(len(names)), n))
    return [name for i, name in enumerate(names) if i in chosen]


def part(names, spec):
    """The k-th of K round-robin parts of `names` (`spec` is "k/K", 1 <= k <= K)."""
    try:
        k, total = (int(x) for x in spec.split("/"))
    except ValueError:
        raise SystemExit(f"--part {spec!r} is not k/K")
    if not 1 <= k <= total:
        raise SystemExit(f"--part {spec!r}: k must be in 1..K")
    return names[k - 1 :: total]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=44)
    ap.add_argument("--n", type=int, default=400)
    ap.add_argument("--listing", help="saved output of `cargo mutants --list`")
    ap.add_argument("--part", metavar="k/K", help="only the k-th of K round-robin parts")
    ap.add_argument("--run", metavar="OUT", help="run cargo mutants on the sample, output in OUT")
    ap.add_argument("rest", nargs="*", help="further cargo mutants arguments (after --)")
    args = ap.parse_args(argv)
    sample = draw(listing(args.listing), args.n, args.seed)
    if args.part:
        sample = part(sample, args.part)
    if not args.run:
        print("\n".join(sample))
        return 0
    cmd = ["cargo", "mutants", "-o", args.run, "--no-shuffle"]
    for name in sample:
        cmd += ["--re", "^" + re.escape(name) + "$"]
    cmd += args.rest
    return subprocess.call(cmd)


if __name__ == "__main__":
    sys.exit(main())
