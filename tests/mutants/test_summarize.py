"""Tests of summarize.py on small cargo-mutants outcome files written here (run by .ci/run:
`python -m pytest tests/mutants`)."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import summarize  # noqa: E402


def mutant(name, summary):
    file = name.split(":")[0]
    return {"scenario": {"Mutant": {"name": name, "file": file}}, "summary": summary}


def run_dir(tmp_path, label, outcomes):
    d = tmp_path / label / "mutants.out"
    d.mkdir(parents=True)
    baseline = {"scenario": "Baseline", "summary": "Success"}
    (d / "outcomes.json").write_text(json.dumps({"outcomes": [baseline] + outcomes}))
    return tmp_path / label


A = "src/bsdf/diffuse.rs:24:5: replace Diffuse::pdf -> f32 with 0.0"
B = "src/accel.rs:99:50: replace * with + in padded"
C = "src/integrator/path.rs:87:30: replace / with * in PathIntegrator::li"
D = "src/film.rs:65:9: replace + with - in Filter::eval"


def test_rows_group_by_directory_under_src():
    assert summarize.group("src/bsdf/diffuse.rs") == "src/bsdf/"
    assert summarize.group("src/bsdf/nested/x.rs") == "src/bsdf/"
    assert summarize.group("src/accel.rs") == "src/accel.rs"


def test_wilson_bounds_solve_the_score_equation():
    # The Wilson bounds are the two p with (k/n - p)^2 = z^2 p (1 - p) / n.
    z = 1.959964
    for k, n in [(44, 52), (143, 172), (0, 10), (10, 10)]:
        lo, hi = summarize.wilson(k, n)
        assert lo < hi
        for p in (lo, hi):
            assert abs((k / n - p) ** 2 - z * z * p * (1 - p) / n) < 1e-12
    # The interval of 143/172 quoted in tests/mutants.md.
    lo, hi = summarize.wilson(143, 172)
    assert (round(100 * lo), round(100 * hi)) == (77, 88)


def test_runs_pool_and_a_rerun_overrides(tmp_path, capsys):
    first = run_dir(tmp_path, "a", [mutant(A, "MissedMutant"), mutant(B, "CaughtMutant")])
    second = run_dir(
        tmp_path, "b", [mutant(A, "CaughtMutant"), mutant(C, "Timeout"), mutant(D, "Unviable")]
    )
    eq = tmp_path / "eq.txt"
    eq.write_text("# none\n")
    assert summarize.main([str(first), str(second), "--equivalent", str(eq), "--strict"]) == 0
    out = capsys.readouterr().out
    assert "| src/bsdf/ | 1 | 0 | 0 | 0 |" in out
    assert "| src/integrator/ | 0 | 0 | 1 | 0 |" in out
    assert "| src/film.rs | 0 | 0 | 0 | 1 |" in out
    assert "| **all** | **2** | **0** | **1** | **1** |" in out
    assert "Score 3/3 = 100.0%" in out
    assert "listed as equivalent" not in out


def test_strict_fails_until_every_miss_is_listed(tmp_path, capsys):
    run = run_dir(tmp_path, "a", [mutant(A, "MissedMutant"), mutant(B, "CaughtMutant")])
    eq = tmp_path / "eq.txt"
    eq.write_text("")
    assert summarize.main([str(run), "--equivalent", str(eq), "--strict"]) == 1
    assert summarize.main([str(run), "--equivalent", str(eq)]) == 0
    eq.write_text(f"# reason in mutants.md\n{A}\n")
    assert summarize.main([str(run), "--equivalent", str(eq), "--strict"]) == 0
    out = capsys.readouterr().out
    assert "Score 1/2 = 50.0%" in out
    assert f"- {A} (equivalent, listed)" in out
    assert "Without the 1 listed as equivalent: 1/1 = 100.0%." in out


def test_listing_finds_stale_entries_and_untested_mutants(tmp_path, capsys):
    run = run_dir(tmp_path, "a", [mutant(B, "CaughtMutant")])
    eq = tmp_path / "eq.txt"
    listing = tmp_path / "list.txt"
    listing.write_text(f"{B}\n{C}\n")
    eq.write_text(f"{D}\n")  # not in the listing: stale
    args = [str(run), "--equivalent", str(eq), "--listing", str(listing), "--strict"]
    assert summarize.main(args) == 1
    assert "Stale equivalence entry (not in the listing): " + D in capsys.readouterr().out
    eq.write_text(f"{C}\n")
    assert summarize.main(args) == 0
    assert "1 of the 2 listed mutants have an outcome." in capsys.readouterr().out
    assert summarize.main(args + ["--complete"]) == 1
    assert f"No outcome: {C}" in capsys.readouterr().out


def test_the_repository_list_names_only_mutants_of_the_estimator_core():
    entries = summarize.read_list(summarize.EQUIVALENT)
    assert len(entries) >= 11
    for e in entries:
        file, line, column, description = e.split(":", 3)
        assert file.startswith("src/") and file.endswith(".rs"), e
        assert (Path(__file__).resolve().parents[2] / file).exists(), e
        assert int(line) > 0 and int(column) > 0 and description.startswith(" "), e


def test_sample_restricts_the_score_to_the_drawn_mutants(tmp_path, capsys):
    run = run_dir(
        tmp_path,
        "s",
        [mutant(A, "CaughtMutant"), mutant(B, "MissedMutant"), mutant(C, "CaughtMutant")],
    )
    drawn = tmp_path / "sample.txt"
    drawn.write_text(f"{A}\n{C}\n")
    assert summarize.main([str(run), "--sample", str(drawn), "--strict"]) == 0
    out = capsys.readouterr().out
    assert "Score 2/2" in out and B not in out
    # without the sample, B's miss counts and --strict fails
    assert summarize.main([str(run), "--strict"]) == 1


import sample  # noqa: E402


def test_sample_is_a_seeded_uniform_draw_in_listing_order():
    names = [f"src/x.rs:{i}:1: replace a with b" for i in range(1000)]
    a = sample.draw(names, 400, 44)
    assert a == sample.draw(names, 400, 44)
    assert len(a) == len(set(a)) == 400 and set(a) <= set(names)
    assert a == sorted(a, key=names.index)
    assert a != sample.draw(names, 400, 45)
    # every mutant is equally likely: over 2000 draws of 1 in 10 names, each name's count is
    # binomial(2000, 0.1); chi-square with 9 dof below its 0.999 quantile (27.88)
    ten = names[:10]
    counts = {n: 0 for n in ten}
    for seed in range(2000):
        counts[sample.draw(ten, 1, seed)[0]] += 1
    chi2 = sum((c - 200) ** 2 / 200 for c in counts.values())
    assert chi2 < 27.88, counts


def test_the_parts_of_a_sample_cover_it_once():
    drawn = [f"m{i}" for i in range(400)]
    parts = [sample.part(drawn, f"{k}/8") for k in range(1, 9)]
    assert sorted(sum(parts, []), key=drawn.index) == drawn
    assert [len(p) for p in parts] == [50] * 8
    assert sample.part(drawn, "1/1") == drawn
    for bad in ("0/8", "9/8", "a/8", "3"):
        with pytest.raises(SystemExit):
            sample.part(drawn, bad)
