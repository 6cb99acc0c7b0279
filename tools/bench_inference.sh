#!/usr/bin/env bash
# Forward-pass time of the full-width UWNR generator (one image, seeded random weights) on
# uwnr's engine (f32 and bf16 products, 1 and 2 threads), uwnr on burn flex, PyTorch and ONNX
# Runtime, at 256, 512 and 1024 px, printed as one table with the ratios to ONNX Runtime and
# the GFLOP/s against the machine's measured FMA peak.
#
# Usage, from the repository root:
#   tools/bench_inference.sh                 # Rust paths only
#   PYTHON=/path/to/venv/bin/python tools/bench_inference.sh   # with PyTorch and ONNX Runtime
# Options through the environment: RUNS (timed runs per size, default 5), SIZES (default
# "256 512 1024"), THREADS (default 2), NO_FLEX=1 to skip the slow burn path.
# The Python side needs `pip install torch onnxruntime onnx onnxscript safetensors numpy` in
# the environment PYTHON names; without PYTHON those columns are left out.
set -euo pipefail
cd "$(dirname "$0")/.."

RUNS="${RUNS:-5}"
SIZES="${SIZES:-256 512 1024}"
THREADS="${THREADS:-2}"
out="$(mktemp)"
trap 'rm -f "$out"' EXIT

echo "machine: $(nproc) cores, load: $(uptime | sed 's/.*load average: //')" >&2
cargo build --release --quiet -p uwnr-train --example bench_inference
bin=target/release/examples/bench_inference
flex_flag=()
[[ "${NO_FLEX:-0}" == 1 ]] && flex_flag=(--no-flex)

echo "== uwnr, $THREADS threads" >&2
RAYON_NUM_THREADS="$THREADS" "$bin" --runs "$RUNS" --sizes $SIZES "${flex_flag[@]}" | tee -a "$out" >&2
echo "== uwnr engine, 1 thread" >&2
RAYON_NUM_THREADS=1 "$bin" --runs "$RUNS" --sizes $SIZES --no-flex \
    | sed 's/^RESULT engine /RESULT engine-1t /; s/^RESULT engine-bf16 /RESULT engine-bf16-1t /; s/^PEAK /PEAK1 /' \
    | tee -a "$out" >&2
if [[ -n "${PYTHON:-}" ]]; then
    echo "== PyTorch" >&2
    "$PYTHON" tools/torch_bench.py --runs "$RUNS" --sizes $SIZES | tee -a "$out" >&2
    echo "== ONNX Runtime" >&2
    "$PYTHON" tools/onnx_bench.py --runs "$RUNS" --sizes $SIZES | tee -a "$out" >&2
fi

python3 - "$out" "$SIZES" <<'PY'
import sys
from collections import defaultdict

path, sizes = sys.argv[1], [int(s) for s in sys.argv[2].split()]
# Kernel multiply-accumulates of the paper's network: 8.61 GMac at 256x256, scaling with pixels.
GMAC_256 = 8.6137
res = defaultdict(dict)
peak = {}
bf16_kind = "native"
for line in open(path):
    f = line.split()
    if f and f[0] == "RESULT":
        res[f[1]][int(f[2])] = float(f[3])
    elif f and f[0] in ("PEAK", "PEAK1"):
        peak[f[0]] = float(f[1])
    elif f and f[0] == "BF16":
        bf16_kind = f[1]
order = ["engine", "engine-1t", "engine-bf16", "engine-bf16-1t", "flex", "pytorch", "onnxruntime"]
bf16 = "bf16" if bf16_kind == "native" else "bf16 emulated"
names = {
    "engine": "uwnr engine",
    "engine-1t": "uwnr engine, 1 thread",
    "engine-bf16": f"uwnr engine, {bf16}",
    "engine-bf16-1t": f"uwnr engine, {bf16}, 1 thread",
    "flex": "uwnr flex (burn)",
    "pytorch": "PyTorch (no_grad)",
    "onnxruntime": "ONNX Runtime (CPU EP)",
}
paths = [p for p in order if p in res]
ref = "onnxruntime" if "onnxruntime" in res else None
print()
print("| path | " + " | ".join(f"{s}x{s}" for s in sizes) + " |")
print("|---|" + "---|" * len(sizes))
for p in paths:
    cells = []
    for s in sizes:
        ms = res[p].get(s)
        if ms is None:
            cells.append("-")
            continue
        gflops = 2 * GMAC_256 * (s / 256) ** 2 / ms * 1e3
        cell = f"{ms:.0f} ms, {gflops:.0f} GFLOP/s"
        if ref and s in res[ref]:
            cell += f", {ms / res[ref][s]:.2f}x ORT"
        cells.append(cell)
    print(f"| {names[p]} | " + " | ".join(cells) + " |")
if "PEAK" in peak:
    print(f"\nmeasured FP32 FMA peak: {peak['PEAK']:.0f} GFLOP/s on the benchmark's threads"
          + (f", {peak['PEAK1']:.0f} GFLOP/s on 1 thread" if "PEAK1" in peak else ""))
print("GFLOP/s counts the direct convolutions' 2 x MACs; Winograd does fewer real operations.")
PY
