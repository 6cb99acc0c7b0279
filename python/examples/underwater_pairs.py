"""A PyTorch dataset that turns a folder of clean photos into (underwater, clean) training pairs
on the fly, rendering each photo in the style of a real underwater reference drawn at random.

    python underwater_pairs.py CLEAN_DIR REFERENCE_DIR [--methods uwnr jerlov] [--crop 256]

prints the throughput of a DataLoader with two workers. In your own training code, use
``UnderwaterPairs`` like any map-style dataset.
"""

import argparse
import os
import time

import numpy as np
import torch
from PIL import Image

import uwnr

EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


class UnderwaterPairs(torch.utils.data.Dataset):
    """(underwater, clean) pairs, CHW float tensors in [0, 1], of random ``crop`` x ``crop``
    crops of the photos in ``clean_dir``."""

    def __init__(self, clean_dir, references, methods=("uwnr",), crop=256, seed=0):
        self.files = sorted(
            os.path.join(clean_dir, f) for f in os.listdir(clean_dir) if f.lower().endswith(EXTENSIONS)
        )
        if not self.files:
            raise ValueError(f"{clean_dir} holds no images")
        # p=1: every sample is rendered. The augmentation draws the reference, the method and
        # the method's parameters from its own generator, seeded per DataLoader worker.
        self.render = uwnr.UnderwaterAugment(references, methods=methods, p=1.0, seed=seed)
        self.crop = crop

    def __len__(self):
        return len(self.files)

    def __getitem__(self, i):
        img = np.asarray(Image.open(self.files[i]).convert("RGB"))
        h, w = img.shape[:2]
        c = min(self.crop, h, w)
        # torch's generator is seeded per worker by the DataLoader, so crops are reproducible
        # under torch.manual_seed.
        y = int(torch.randint(0, h - c + 1, ()).item())
        x = int(torch.randint(0, w - c + 1, ()).item())
        clean = torch.from_numpy(np.ascontiguousarray(img[y : y + c, x : x + c])).permute(2, 0, 1)
        clean = clean.float() / 255
        return self.render(clean), clean


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("clean_dir")
    ap.add_argument("references")
    ap.add_argument("--methods", nargs="+", default=["uwnr"])
    ap.add_argument("--crop", type=int, default=256)
    ap.add_argument("--batch-size", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--batches", type=int, default=10)
    args = ap.parse_args()

    torch.manual_seed(0)
    data = UnderwaterPairs(args.clean_dir, args.references, args.methods, args.crop)
    loader = torch.utils.data.DataLoader(
        data, batch_size=args.batch_size, shuffle=True, num_workers=args.workers,
        persistent_workers=args.workers > 0,
    )
    seen, start = 0, None
    for b, (underwater, clean) in enumerate(loader):
        if b == 0:
            start = time.perf_counter()  # the first batch includes worker start-up
        else:
            seen += underwater.shape[0]
        if b == args.batches:
            break
    elapsed = time.perf_counter() - start
    print(f"{seen} pairs in {elapsed:.2f} s: {seen / elapsed:.2f} pairs/s "
          f"({args.workers} workers, {args.crop}x{args.crop}, methods {' '.join(args.methods)})")


if __name__ == "__main__":
    main()
