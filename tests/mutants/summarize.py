#!/usr/bin/env python3
"""The mutation score of one or more cargo-mutants runs (shards), as tests/mutants.md reports it.

    python3 tests/mutants/summarize.py OUT [OUT ...] [--listing LIST] [--strict]

Each OUT is a directory given to `cargo mutants -o` (or its `mutants.out`); the outcomes of
all of them are pooled (a mutant seen in several, e.g. re-run with `--re`, counts once, by
its last outcome). Prints, in Markdown: caught / missed / timeout / unviable per directory of
the estimator core, the score with its 95% Wilson interval (timeouts count as caught: the
mutant hung the tests, the tests noticed), and every missed mutant, marked when
tests/mutants/equivalent.txt lists it as equivalent.

`--sample FILE` (the names tests/mutants/sample.py drew) scores only those mutants.

`--listing LIST` (the output of `cargo mutants --list`) also checks that every entry of the
equivalence list still names a mutant (entries go stale when code above them moves), and
counts the listed mutants without an outcome; `--complete` makes those an error (a full run
whose shards did not all finish). `--strict` exits with status 1 when a missed mutant is not
listed as equivalent or an entry is stale (or, with `--complete`, a mutant has no outcome),
so the job that merges the shards of a full run fails until every survivor is dealt with.
Standard library only.
"""

import argparse
import json
import math
import sys
from collections import Counter, OrderedDict
from pathlib import Path

KINDS = ("caught", "missed", "timeout", "unviable")
SUMMARY = {
    "CaughtMutant": "caught",
    "MissedMutant": "missed",
    "Timeout": "timeout",
    "Unviable": "unviable",
}
EQUIVALENT = Path(__file__).resolve().parent / "equivalent.txt"


def group(path):
    """The row a file is counted in: its directory under src/ (`src/bsdf/`), or the file
    itself when it lies directly in src/ (`src/accel.rs`)."""
    parts = path.split("/")
    return "/".join(parts[:2]) + "/" if len(parts) > 2 else path


def wilson(k, n, z=1.959964):
    """95% Wilson score interval of the proportion k / n."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (max(0.0, centre - half), min(1.0, centre + half))


def read_outcomes(dirs):
    """{mutant name: (file, kind)} over all runs, later runs overriding earlier ones."""
    seen = OrderedDict()
    for d in dirs:
        d = Path(d)
        path = d / "outcomes.json" if (d / "outcomes.json").exists() else d / "mutants.out" / "outcomes.json"
        if not path.exists():
            raise SystemExit(f"error: no outcomes.json in {d} (nor in {d}/mutants.out)")
        try:
            outcomes = json.loads(path.read_text())["outcomes"]
        except (ValueError, KeyError) as e:
            raise SystemExit(f"error: {path} is not a cargo-mutants outcomes file ({e})")
        for o in outcomes:
            scenario = o.get("scenario")
            if not isinstance(scenario, dict) or "Mutant" not in scenario:
                continue  # the baseline
            kind = SUMMARY.get(o.get("summary"))
            if kind is None:
                raise SystemExit(f"error: {path}: unknown outcome {o.get('summary')!r}")
            mutant = scenario["Mutant"]
            seen[mutant["name"]] = (mutant["file"], kind)
    return seen


def read_list(path):
    """Non-empty, non-comment lines of a file."""
    return [
        line.strip()
        for line in Path(path).read_text().splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    ]


def summarize(outcomes, equivalent, listing=None, complete=False):
    """The report (Markdown lines) and the number of problems (unlisted misses, stale
    equivalence entries and, with `complete`, listed mutants without an outcome)."""
    rows = OrderedDict()
    for file, kind in outcomes.values():
        rows.setdefault(group(file), Counter())[kind] += 1
    total = Counter()
    for counts in rows.values():
        total.update(counts)
    out = ["| directory | caught | missed | timeout | unviable |", "|---|---:|---:|---:|---:|"]
    for name in sorted(rows):
        c = rows[name]
        out.append(f"| {name} | " + " | ".join(str(c[k]) for k in KINDS) + " |")
    out.append("| **all** | " + " | ".join(f"**{total[k]}**" for k in KINDS) + " |")
    out.append("")

    caught = total["caught"] + total["timeout"]
    viable = caught + total["missed"]
    missed = [n for n, (_, kind) in outcomes.items() if kind == "missed"]
    listed = set(equivalent)
    open_misses = [n for n in missed if n not in listed]
    if viable:
        lo, hi = wilson(caught, viable)
        out.append(
            f"Score {caught}/{viable} = {100 * caught / viable:.1f}% of the viable mutants "
            f"(timeouts as caught; 95% interval {100 * lo:.0f}–{100 * hi:.0f}%)."
        )
        non_equivalent = viable - (len(missed) - len(open_misses))
        if non_equivalent and non_equivalent < viable:
            out.append(
                f"Without the {len(missed) - len(open_misses)} listed as equivalent: "
                f"{caught}/{non_equivalent} = {100 * caught / non_equivalent:.1f}%."
            )
    else:
        out.append("No viable mutants in these runs.")
    out.append("")
    if missed:
        out.append("Missed:")
        for n in missed:
            out.append(f"- {n}" + (" (equivalent, listed)" if n in listed else ""))
        out.append("")
    problems = len(open_misses)
    if listing is not None:
        names = set(listing)
        stale = [e for e in equivalent if e not in names]
        for e in stale:
            out.append(f"Stale equivalence entry (not in the listing): {e}")
        problems += len(stale)
        untested = [n for n in listing if n not in outcomes]
        out.append(f"{len(listing) - len(untested)} of the {len(listing)} listed mutants have an outcome.")
        if complete:
            for n in untested:
                out.append(f"No outcome: {n}")
            problems += len(untested)
    return out, problems


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="cargo mutants output directories")
    ap.add_argument("--equivalent", default=EQUIVALENT, help="equivalence list (default: %(default)s)")
    ap.add_argument("--listing", help="output of `cargo mutants --list`, to find stale entries")
    ap.add_argument("--complete", action="store_true", help="every listed mutant must have an outcome")
    ap.add_argument("--strict", action="store_true", help="exit 1 on unlisted misses or stale entries")
    ap.add_argument(
        "--sample",
        help="names drawn by tests/mutants/sample.py: score only these (cargo mutants runs its "
        "'delete field' mutants whatever --re says)",
    )
    args = ap.parse_args(argv)
    outcomes = read_outcomes(args.runs)
    if args.sample:
        drawn = set(read_list(args.sample))
        outcomes = OrderedDict((n, v) for n, v in outcomes.items() if n in drawn)
    equivalent = read_list(args.equivalent)
    listing = read_list(args.listing) if args.listing else None
    if args.complete and listing is None:
        ap.error("--complete needs --listing")
    report, problems = summarize(outcomes, equivalent, listing, args.complete)
    print("\n".join(report))
    return 1 if args.strict and problems else 0


if __name__ == "__main__":
    sys.exit(main())
