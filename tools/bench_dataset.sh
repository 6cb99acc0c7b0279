#!/usr/bin/env bash
# Throughput of `uwnr dataset` with the full-width network (the bundled model, or WEIGHTS=FILE of
# the same architecture: speed does not depend on the weights' values), on DEVICE (default
# engine; DEVICE=flex for burn's backend):
#   1. 24 in-air photos at --size 256x256, K = 1;
#   2. the 11 Set14 photos at their native sizes (about 0.1-0.25 MP);
#   3. 6 SUN-Hays photos at their native sizes (1024 px on the long side, about 0.7 MP);
# each with --jobs 1 and --jobs 2. Prints pairs/s as `uwnr dataset` reports them.
# Run from the repository root with ../shared/data present, on a quiet machine:
#   cargo build --release -p uwnr-cli && bash tools/bench_dataset.sh
set -euo pipefail
DATA=${DATA:-../shared/data}
BIN=${BIN:-target/release/uwnr}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
W=()
if [ -n "${WEIGHTS:-}" ]; then W=(--weights "$WEIGHTS"); fi
W+=(--device "${DEVICE:-engine}")

mkdir -p "$WORK/small" "$WORK/set14" "$WORK/large"
ls "$DATA"/inair/cbsd68/*.jpg | head -12 | xargs -I{} cp {} "$WORK/small/"
ls "$DATA"/inair/urban100/*.jpg | head -12 | xargs -I{} cp {} "$WORK/small/"
cp "$DATA"/inair/set14/*.jpg "$WORK/set14/"
ls "$DATA"/inair/sun-hays80/*.jpg | head -6 | xargs -I{} cp {} "$WORK/large/"
REFS="$DATA/references/u45"

run() { # name, clean dir, jobs, extra args...
  local name=$1 clean=$2 jobs=$3
  shift 3
  local out="$WORK/out-$name-j$jobs"
  local line
  line=$("$BIN" dataset --clean "$clean" --references "$REFS" --output "$out" --per-image 1 \
    --jobs "$jobs" --no-gallery "${W[@]}" "$@" 2>&1 | grep '^dataset:')
  echo "$name jobs=$jobs: $line"
}
for j in 1 2; do run 256x256 "$WORK/small" "$j" --size 256x256; done
for j in 1 2; do run set14-native "$WORK/set14" "$j"; done
for j in 1 2; do run sun-native "$WORK/large" "$j"; done
