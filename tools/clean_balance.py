#!/usr/bin/env python3
"""The clean balance of uwnr's water (`uwnr_model::water::CleanBalance::BANK`): per-channel gains that
bring an in-air photo to the white point of the real pairs' clean sides, from which the water
bank's waters were fitted.

A real pair's clean side is an enhanced version of its underwater photo, and enhancement leaves
some of the water's cast: the clean sides of `uieb-train` and LSUI's training part are bluer and
greener than photos taken in air. The bank's waters move *those* clean sides to the underwater
ones, so a photo taken in air is first brought to their white point. The gains are the ratio of
the two sets' mean chromaticities (each channel's share of R + G + B, averaged over pixels and
then over images at 128 x 128 px), which keeps the mean brightness:

    python3 tools/clean_balance.py --bank ../shared/data/paired/uieb-train/clean \\
        ../uwnr-splits/lsui-train/clean --in-air ../shared/data/inair

Needs NumPy and Pillow.
"""

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

EXTENSIONS = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff"}


def images(dirs: list[Path]) -> list[Path]:
    return sorted(p for d in dirs for p in d.rglob("*") if p.suffix.lower() in EXTENSIONS)


def chromaticity(files: list[Path]) -> np.ndarray:
    means = [
        np.asarray(Image.open(p).convert("RGB").resize((128, 128), Image.BILINEAR), dtype=np.float64)
        .reshape(-1, 3)
        .mean(0)
        for p in files
    ]
    m = np.mean(means, 0)
    return m / m.sum()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bank", type=Path, nargs="+", required=True, help="the bank's clean sides")
    ap.add_argument("--in-air", type=Path, nargs="+", required=True, help="photos taken in air")
    args = ap.parse_args()
    bank, air = images(args.bank), images(args.in_air)
    if not bank or not air:
        raise SystemExit("no images found")
    cb, ca = chromaticity(bank), chromaticity(air)
    print(f"bank clean sides ({len(bank)}): chromaticity {np.round(cb, 4).tolist()}")
    print(f"in air ({len(air)}): chromaticity {np.round(ca, 4).tolist()}")
    print(f"balance (R, G, B gains): {np.round(cb / ca, 3).tolist()}")


if __name__ == "__main__":
    main()
