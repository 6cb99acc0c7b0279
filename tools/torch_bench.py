#!/usr/bin/env python3
"""Forward-pass time of the full-width UWNR generator in PyTorch on the CPU, the reference for
crates/train/uwnr-train's `cargo bench -p uwnr-train --bench generator`.

Same architecture as tools/torch_parity.py (width 64, 11.57M parameters), 2 threads, no_grad,
input 1x7xSxS uniform in [0, 1] for S in 256, 512, 1024. Prints the median of several runs
after a warm-up, and the process's peak resident set.

Run from the repository root: `python3 tools/torch_bench.py [--runs 5]`.
"""

import argparse
import resource
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from torch_parity import Generator  # noqa: E402

SIZES = (256, 512, 1024)
THREADS = 2


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="timed runs per size (after 1 warm-up)")
    ap.add_argument("--sizes", type=int, nargs="*", default=list(SIZES))
    args = ap.parse_args()

    torch.set_num_threads(THREADS)
    torch.manual_seed(0)
    model = Generator(64).eval()
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    for size in args.sizes:
        x = torch.rand(1, 7, size, size)
        with torch.no_grad():
            model(x)  # warm-up
            times = []
            for _ in range(args.runs):
                t = time.perf_counter()
                model(x)
                times.append((time.perf_counter() - t) * 1e3)
        peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(
            f"forward {size}x{size}: median {statistics.median(times):.0f} ms "
            f"(runs {', '.join(f'{t:.0f}' for t in times)}), peak RSS so far {peak_mib:.0f} MiB"
        )
        # One machine-readable line per size for tools/bench_inference.sh.
        print(f"RESULT pytorch {size} {statistics.median(times):.2f}")


if __name__ == "__main__":
    main()
