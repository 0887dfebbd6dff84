#!/bin/bash
# Renders a scene as a Slurm job array of parts and merges them when all have succeeded.
#
#   deploy/slurm/submit.sh SCENE SPP PARTS OUTDIR [render arguments...]
#
# e.g. deploy/slurm/submit.sh scenes/cornell-box.xml 100000 64 refs/cbox -D res=512
# Writes OUTDIR/part-K-of-PARTS.pnbr, then OUTDIR/final.exr and OUTDIR/stats.json; the job
# ids and parameters are kept in OUTDIR/job.env for resubmit.sh. Set PENUMBRA to the binary
# (default: target/release/penumbra, else penumbra on the PATH) and SBATCH_ARGS for extra
# sbatch options (partition, account, time limit, --cpus-per-task for more threads per part).
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n '2,10p' "$0" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
SCENE=$(realpath "$1"); SPP=$2; PARTS=$3; OUTDIR=$4; shift 4
RENDER_ARGS="$*"
mkdir -p "$OUTDIR"; OUTDIR=$(realpath "$OUTDIR")
if [ -z "${PENUMBRA:-}" ]; then
    if [ -x target/release/penumbra ]; then PENUMBRA=$(realpath target/release/penumbra);
    else PENUMBRA=$(command -v penumbra); fi
fi
export PENUMBRA SCENE SPP PARTS OUTDIR RENDER_ARGS
# shellcheck disable=SC2086 # SBATCH_ARGS is a list of options
parts=$(sbatch --parsable ${SBATCH_ARGS:-} --chdir="$OUTDIR" --export=ALL \
    --array=0-$((PARTS - 1)) "$here/render-part.sbatch")
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} --chdir="$OUTDIR" --export=ALL \
    --dependency=afterok:"$parts" "$here/merge.sbatch")
cat > "$OUTDIR/job.env" <<ENV
PENUMBRA='$PENUMBRA'
SCENE='$SCENE'
SPP='$SPP'
PARTS='$PARTS'
OUTDIR='$OUTDIR'
RENDER_ARGS='$RENDER_ARGS'
PARTS_JOB='$parts'
MERGE_JOB='$merge'
ENV
echo "parts: job array $parts (0-$((PARTS - 1))), merge: job $merge -> $OUTDIR/final.exr"
