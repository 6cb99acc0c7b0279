#!/usr/bin/env python3
"""Forward-pass time of the full-width UWNR generator in ONNX Runtime (CPU execution provider),
for tools/bench_inference.sh.

The generator of tools/torch_parity.py (width 64, 11.57M parameters, seeded random weights) is
exported with torch.onnx to a temporary file with dynamic height and width, then run with 2
intra-op threads on input 1x7xSxS uniform in [0, 1]. Prints the median of several runs after a
warm-up, one `RESULT onnxruntime <size> <ms>` line per size for the script that collects them.

Needs `pip install torch onnxruntime onnx onnxscript safetensors numpy`. Run from the
repository root: `python3 tools/onnx_bench.py [--runs 5] [--sizes 256 512 1024]`.
"""

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from torch_parity import Generator  # noqa: E402

SIZES = (256, 512, 1024)
THREADS = 2
EXPORT_SIZE = 256


def export(path: Path) -> None:
    torch.manual_seed(0)
    model = Generator(64).eval()
    x = torch.rand(1, 7, EXPORT_SIZE, EXPORT_SIZE)
    axes = {"x": {2: "h", 3: "w"}, "y": {2: "h", 3: "w"}}
    try:
        torch.onnx.export(
            model, (x,), str(path), input_names=["x"], output_names=["y"],
            dynamic_axes=axes, opset_version=17, dynamo=False,
        )
    except Exception as e:  # older or newer exporters
        print(f"legacy exporter failed ({e}); trying the dynamo exporter", file=sys.stderr)
        torch.onnx.export(
            model, (x,), str(path), input_names=["x"], output_names=["y"],
            dynamic_shapes={"x": {2: torch.export.Dim("h"), 3: torch.export.Dim("w")}},
            dynamo=True,
        )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="timed runs per size (after 1 warm-up)")
    ap.add_argument("--sizes", type=int, nargs="*", default=list(SIZES))
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "uwnr-generator.onnx"
        export(path)
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = THREADS
        opts.inter_op_num_threads = 1
        opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        sess = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    print(f"onnxruntime {ort.__version__}, {THREADS} threads")
    rng = np.random.default_rng(0)
    for size in args.sizes:
        x = rng.random((1, 7, size, size), dtype=np.float32)
        sess.run(None, {"x": x})  # warm-up
        times = []
        for _ in range(args.runs):
            t = time.perf_counter()
            sess.run(None, {"x": x})
            times.append((time.perf_counter() - t) * 1e3)
        med = statistics.median(times)
        print(f"forward {size}x{size}: median {med:.0f} ms (runs {', '.join(f'{t:.0f}' for t in times)})")
        print(f"RESULT onnxruntime {size} {med:.2f}")


if __name__ == "__main__":
    main()
