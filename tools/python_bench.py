"""Cost of the Python package's augmentation: one ``aug(x)`` at 256x256 and 512x512 per method,
and the throughput of a PyTorch DataLoader with two workers (when torch is installed).

    python tools/python_bench.py [--references DIR] [--repeats 5]

Not run by CI; prints a Markdown table.
"""

import argparse
import os
import statistics
import time

import numpy as np

import uwnr


def synthetic(h, w, seed):
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.stack([np.sin(x / 9), np.cos(y / 7), (x + y) / (h + w)], axis=2) * 0.4 + 0.5
    return (np.clip(img + rng.normal(0, 0.03, img.shape), 0, 1) * 255).astype(np.uint8)


def time_calls(fn, repeats):
    fn()  # warm-up: loads the model, computes the reference's light field
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


class Pairs:
    def __init__(self, aug, n, side):
        self.aug, self.n, self.side = aug, n, side

    def __len__(self):
        return self.n

    def __getitem__(self, i):
        import torch

        clean = torch.from_numpy(synthetic(self.side, self.side, i)).permute(2, 0, 1).float() / 255
        return self.aug(clean), clean


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--references", default=None, help="folder of references (default: synthetic)")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    refs = args.references or [synthetic(300, 400, 99)[..., [2, 1, 0]]]

    print(f"threads: RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all cores')}, "
          f"load average {os.getloadavg()[0]:.2f}")
    print("| method | aug(x) 256x256 (ms) | aug(x) 512x512 (ms) |")
    print("|---|---|---|")
    for method in uwnr.METHODS:
        aug = uwnr.UnderwaterAugment(refs, methods=[method], p=1.0, seed=0)
        row = []
        for side in (256, 512):
            x = synthetic(side, side, 1)
            row.append(time_calls(lambda: aug(x), args.repeats) * 1000)
        print(f"| {method} | {row[0]:.0f} | {row[1]:.0f} |")

    try:
        import torch
    except ImportError:
        print("torch not installed: DataLoader throughput skipped")
        return
    for method in ("uwnr", "jerlov"):
        aug = uwnr.UnderwaterAugment(refs, methods=[method], p=1.0, seed=0)
        loader = torch.utils.data.DataLoader(
            Pairs(aug, 64, 256), batch_size=8, num_workers=2, persistent_workers=True
        )
        it = iter(loader)
        next(it)  # worker start-up and model loading
        t = time.perf_counter()
        n = sum(u.shape[0] for u, _ in it)
        dt = time.perf_counter() - t
        print(f"DataLoader, 2 workers, {method}, 256x256: {n / dt:.2f} pairs/s ({n} pairs in {dt:.1f} s)")


if __name__ == "__main__":
    main()
