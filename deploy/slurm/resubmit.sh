#!/bin/bash
# Resubmits failed or cancelled parts of a render started with submit.sh, and a new merge
# job that waits for them (the old merge job, whose dependency can no longer be met, is
# cancelled). Parts that finished are kept.
#
#   deploy/slurm/resubmit.sh OUTDIR K [K...]
set -euo pipefail
if [ $# -lt 2 ]; then
    sed -n '2,7p' "$0" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
OUTDIR=$(realpath "$1"); shift
# shellcheck source=/dev/null
. "$OUTDIR/job.env"
export PENUMBRA SCENE SPP PARTS OUTDIR RENDER_ARGS
scancel "$MERGE_JOB" 2>/dev/null || true
list=$(IFS=,; echo "$*")
# shellcheck disable=SC2086
parts=$(sbatch --parsable ${SBATCH_ARGS:-} --chdir="$OUTDIR" --export=ALL \
    --array="$list" "$here/render-part.sbatch")
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --chdir="$OUTDIR" --export=ALL \
    --dependency=afterok:"$parts" "$here/merge.sbatch")
sed -i "s/^MERGE_JOB=.*/MERGE_JOB='$merge'/" "$OUTDIR/job.env"
echo "parts $list: job array $parts, merge: job $merge -> $OUTDIR/final.exr"
