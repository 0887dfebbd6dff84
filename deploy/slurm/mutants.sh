#!/bin/bash
# The full mutation run of tests/mutants.md as a Slurm job array: the mutants of the
# estimator core split into SHARDS round-robin shards, one `cargo mutants --shard K/SHARDS`
# per array task, and a summary job that pools the shards with tests/mutants/summarize.py
# once all of them have ended.
#
#   deploy/slurm/mutants.sh SHARDS OUTDIR [ARRAY]
#
# e.g. deploy/slurm/mutants.sh 100 mutants-full   (100 tasks of ~53 mutants, ~1.5 h each on
# a 2-core node). ARRAY (default 0-(SHARDS-1)) submits only some shards, e.g. 0-3 or 7,12.
# Run from a checkout of penumbra with cargo-mutants installed (`cargo install cargo-mutants
# --locked`); every task copies the checkout and builds it. Writes OUTDIR/listing.txt (the
# mutants), OUTDIR/shard-K/ (cargo-mutants' output), OUTDIR/summary.md (the table, the score
# and every missed mutant) and the job ids in OUTDIR/job.env. The summary job fails while a
# missed mutant is neither caught nor listed in tests/mutants/equivalent.txt (and, for the
# full array, while a shard has not finished). SBATCH_ARGS: extra sbatch options (partition,
# account, --cpus-per-task, default 2); MUTANTS_ARGS: extra cargo-mutants options.
set -euo pipefail
if [ $# -lt 2 ]; then
    sed -n '2,17p' "$0" >&2
    exit 2
fi
case $1 in '' | *[!0-9]* | 0) echo "error: SHARDS must be a positive integer, not '$1'" >&2; exit 2 ;; esac
here=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$here/../.." && pwd)
SHARDS=$1
mkdir -p "$2"; OUTDIR=$(realpath "$2")
ARRAY=${3:-0-$((SHARDS - 1))}
cargo mutants --version >/dev/null 2>&1 ||
    { echo "error: cargo-mutants is not installed (cargo install cargo-mutants --locked)" >&2; exit 1; }
(cd "$REPO" && cargo mutants --list) > "$OUTDIR/listing.txt"
COMPLETE=
[ -z "${3:-}" ] && COMPLETE=--complete
export REPO SHARDS OUTDIR COMPLETE MUTANTS_ARGS=${MUTANTS_ARGS:-}
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of options
shards=$(sbatch --parsable --cpus-per-task=2 ${SBATCH_ARGS:-} --chdir="$OUTDIR" --export=ALL \
    --array="$ARRAY" "$here/mutants-shard.sbatch")
# shellcheck disable=SC2086
summary=$(sbatch --parsable --cpus-per-task=1 ${SBATCH_ARGS:-} --chdir="$OUTDIR" --export=ALL \
    --dependency=afterany:"$shards" "$here/mutants-summary.sbatch")
cat > "$OUTDIR/job.env" <<ENV
REPO='$REPO'
SHARDS='$SHARDS'
ARRAY='$ARRAY'
SHARDS_JOB='$shards'
SUMMARY_JOB='$summary'
ENV
echo "$(wc -l < "$OUTDIR/listing.txt") mutants in $SHARDS shards; shards $ARRAY: job array $shards, summary: job $summary -> $OUTDIR/summary.md"
