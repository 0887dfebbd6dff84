#!/usr/bin/env bash
# A profile-guided build of penumbra for long reference renders (docs/performance.md,
# "Profile-guided build"): the `dist` profile (fat LTO) compiled once with instrumentation,
# run on the example scenes to record which branches and calls are hot, then compiled again
# with that profile. Renders are bit-identical to the plain build (no floating-point
# semantics change); only code layout, inlining and branch order do.
#
#   deploy/pgo.sh            # -> target/pgo/penumbra
#
# Needs llvm-profdata of the compiler's own LLVM version: `rustup component add llvm-tools`.
# Takes two full builds (about 5 minutes each on 2 cores) and a minute of training renders.
set -euo pipefail
cd "$(dirname "$0")/.."

host=$(rustc -vV | sed -n 's/^host: //p')
profdata="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata"
if [ ! -x "$profdata" ]; then
    echo "deploy/pgo.sh: llvm-profdata not found; install it with: rustup component add llvm-tools" >&2
    exit 1
fi

work=target/pgo
raw="$PWD/$work/raw"
rm -rf "$raw" "$work/merged.profdata"
mkdir -p "$raw"

echo "1/3 instrumented build" >&2
RUSTFLAGS="-Cprofile-generate=$raw" cargo build --profile dist --bin penumbra \
    --target-dir "$work/gen" --quiet
gen="$work/gen/dist/penumbra"

echo "2/3 training renders (every example scene, 8 spp; the light tracer and SPPM once)" >&2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for scene in scenes/*.xml scenes/mitsuba/cbox/cbox.xml scenes/mitsuba/hello.xml \
    scenes/mitsuba/matpreview/matpreview.xml; do
    "$gen" render "$scene" --spp 8 --quiet -o "$out/t.exr"
done
"$gen" render scenes/cornell-box.xml --spp 8 --integrator ptracer --quiet -o "$out/t.exr"
"$gen" render scenes/caustic-glass.xml --spp 8 --integrator sppm --quiet -o "$out/t.exr"
"$profdata" merge -o "$work/merged.profdata" "$raw"

echo "3/3 optimised build" >&2
RUSTFLAGS="-Cprofile-use=$PWD/$work/merged.profdata" cargo build --profile dist --bin penumbra \
    --target-dir "$work/use" --quiet
cp "$work/use/dist/penumbra" "$work/penumbra"
echo "$work/penumbra"
