#!/bin/sh
# Instruction count of a small, fixed render (callgrind counts instructions exactly, so the
# figure does not depend on machine load): compare builds by the ratio of two counts.
#   validation/perf/instructions.sh [binary] [scene]
set -e
bin=${1:-target/release/penumbra}
scene=${2:-scenes/cornell-box.xml}
valgrind --tool=callgrind --callgrind-out-file=/tmp/penumbra-callgrind.out \
    "$bin" render "$scene" -D res=32 --spp 8 --threads 1 -o /tmp/penumbra-callgrind.exr 2>&1 |
    sed -n 's/.*Collected : \([0-9]*\).*/\1 instructions (32x32, 8 spp, 1 thread)/p'
