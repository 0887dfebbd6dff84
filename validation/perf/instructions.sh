#!/bin/sh
# Instruction count of a small, fixed render (callgrind counts instructions exactly, so the
# figure does not depend on machine load): compare builds by the ratio of two counts.
#   validation/perf/instructions.sh [binary] [scene] [render options...]
# e.g. ... target/release/penumbra scenes/cornell-box.xml --engine lanes --lane-backend avx2
# (valgrind cannot run AVX-512: force the avx2 or portable lane backend under it).
# SPP=16 validation/perf/instructions.sh ... counts at 16 spp: the marginal cost of a path
# is (count at 16 spp - count at 8 spp) / 8192, which leaves out loading and output.
set -e
bin=${1:-target/release/penumbra}
scene=${2:-scenes/cornell-box.xml}
spp=${SPP:-8}
if [ $# -gt 2 ]; then shift 2; else set --; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
valgrind --tool=callgrind --callgrind-out-file="$tmp/callgrind.out" \
    "$bin" render "$scene" -D res=32 --spp "$spp" --threads 1 -o "$tmp/render.exr" "$@" 2>&1 |
    sed -n "s|.*Collected : \([0-9]*\).*|\1 instructions (32x32, $spp spp, 1 thread; $*)|p"
