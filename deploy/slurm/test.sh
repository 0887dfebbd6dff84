#!/bin/bash
# End-to-end test of the Slurm recipe on this machine: installs and starts a single-node
# Slurm if there is none (Debian packages; needs root), renders a 4-part Cornell box with
# submit.sh, cancels one part with scancel, resubmits it with resubmit.sh, and checks that
# the merged EXR equals the one-process render pixel for pixel. Run from the repository root
# after `cargo build --release`:
#
#   deploy/slurm/test.sh
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
cd "$root"
penumbra=$root/target/release/penumbra
[ -x "$penumbra" ] || { echo "build first: cargo build --release" >&2; exit 1; }

"$here/local-slurm.sh"

wait_for() { # job id: until it has left the queue
    for _ in $(seq 3000); do [ -z "$(squeue -h -j "$1" 2>/dev/null)" ] && return 0; sleep 0.2; done
    echo "job $1 did not finish" >&2; exit 1
}

# --- the test ------------------------------------------------------------------------------
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene=scenes/cornell-box.xml
args=(-D res=64)
spp=512
seconds_since() { awk -v a="$1" -v b="$(date +%s%N)" 'BEGIN { printf "%.1f", (b - a) / 1e9 }'; }
start=$(date +%s%N)
"$penumbra" render "$scene" --spp $spp "${args[@]}" --threads 1 --quiet -o "$work/single.exr"
t_single=$(seconds_since "$start")

start=$(date +%s%N)
PENUMBRA=$penumbra "$here/submit.sh" "$scene" $spp 4 "$work/out" "${args[@]}"
# shellcheck source=/dev/null
. "$work/out/job.env"
scancel "${PARTS_JOB}_2"               # part 2 is cancelled (pending or running)
wait_for "$PARTS_JOB"
if [ -f "$work/out/part-2-of-4.pnbr" ]; then
    echo "part 2 finished before it could be cancelled: rerun" >&2; exit 1
fi
PENUMBRA=$penumbra "$here/resubmit.sh" "$work/out" 2
# shellcheck source=/dev/null
. "$work/out/job.env"
wait_for "$MERGE_JOB"
t_parts=$(seconds_since "$start")
[ -f "$work/out/final.exr" ] || { echo "no merged image; merge log:" >&2; cat "$work"/out/penumbra-merge-*.log >&2; exit 1; }
max_abs=$("$penumbra" compare "$work/out/final.exr" "$work/single.exr" --json |
    sed -n 's/.*"max_abs": \(.*\),/\1/p')
echo "one process (1 thread): ${t_single} s; 4 Slurm parts with one cancelled and resubmitted, merged: ${t_parts} s; max |merged - single| = $max_abs"
[ "$max_abs" = "0.0" ] || { echo "the merged render differs from the one-process render" >&2; exit 1; }
echo "slurm recipe: ok"
