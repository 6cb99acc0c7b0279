#!/usr/bin/env bash
# Throughput of `uwnr dataset` per method, to size a job array (docs/datasets.md, "Beyond one machine"):
# pairs/s on one core (--jobs 1, RAYON_NUM_THREADS=1) and on every core of the machine (--jobs =
# cores), at --size 256x256 and 512x512, for the default and every other method, with the peak
# resident memory of each run (GNU time). One run each; prints a Markdown table.
#
# Clean images: 12 CBSD68 and 12 Urban100 photos from ../shared/data/inair, PER_IMAGE renders each
# (default 8: 192 pairs a run); references: U45 (references/u45). Run from the repository root on a quiet
# machine with a release binary:
#   cargo build --release -p uwnr-cli && bash tools/bench_throughput.sh
# Settings: BIN (default target/release/uwnr), DATA, METHODS, SIZES, PER_IMAGE, CAMERA (`--camera`;
# unset, the default).
set -euo pipefail
DATA=${DATA:-../shared/data}
BIN=${BIN:-target/release/uwnr}
METHODS=${METHODS:-uwnr uwgan jerlov uisa seathru reinhard haze}
SIZES=${SIZES:-256x256 512x512}
PER_IMAGE=${PER_IMAGE:-8}
CORES=$(nproc)
[ -x /usr/bin/time ] || { echo "needs GNU time (/usr/bin/time, Debian's package time)" >&2; exit 1; }
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$WORK/clean"
find "$DATA/inair/cbsd68" -type f | sort | head -12 | xargs -I{} cp {} "$WORK/clean/"
find "$DATA/inair/urban100" -type f | sort | head -12 | xargs -I{} cp {} "$WORK/clean/"
REFS="$DATA/references/u45"

run() { # method, size, jobs, rayon threads -> "pairs/s peak-MiB"
    local method=$1 size=$2 jobs=$3 threads=$4
    local out="$WORK/out-$method-$size-$jobs"
    RAYON_NUM_THREADS=$threads /usr/bin/time -f 'peak_kib=%M' -o "$WORK/time" \
        "$BIN" dataset --clean "$WORK/clean" --references "$REFS" --output "$out" \
        --per-image "$PER_IMAGE" --size "$size" --method "$method" --jobs "$jobs" --no-gallery ${CAMERA:+--camera "$CAMERA"} \
        >"$WORK/log" 2>&1 || { cat "$WORK/log" >&2; return 1; }
    local rate kib
    rate=$(grep '^dataset:' "$WORK/log" | sed -E 's/.*\(([0-9.]+) pairs\/s\).*/\1/')
    kib=$(grep -o 'peak_kib=[0-9]*' "$WORK/time" | cut -d= -f2)
    rm -rf "$out"
    echo "$rate $((kib / 1024))"
}

simd=AVX2
grep -qw avx512f /proc/cpuinfo && simd=AVX-512
echo "$(lscpu | sed -n 's/^Model name: *//p') ($simd), $CORES cores; $("$BIN" --version)"
echo
echo "| method | size | pairs/s, 1 core | pairs/s, $CORES cores | peak RSS, 1 core / $CORES cores |"
echo "|---|---|---:|---:|---:|"
for size in $SIZES; do
    for m in $METHODS; do
        read -r one one_mib < <(run "$m" "$size" 1 1)
        read -r all all_mib < <(run "$m" "$size" "$CORES" "$CORES")
        echo "| $m | $size | $one | $all | $one_mib / $all_mib MiB |"
    done
done
