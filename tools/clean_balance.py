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

With --bank-underwater (the bank's underwater sides, in the same order as --bank's clean sides:
the same file names), it also fits how far a clean side's white point follows its own water
(`BANK_WATER_SHARE`, `CleanBalance::following`): per image, each channel's share of R + G + B,
then the least-squares slope `share` of (clean - mean clean) on (underwater - mean underwater)
over the three channels, the two means (`BANK_CLEAN_CHROMATICITY`,
`BANK_UNDERWATER_CHROMATICITY`), and the slope fitted on each --bank folder alone with the other
held out:

    python3 tools/clean_balance.py --bank ../shared/data/paired/uieb-train/clean \\
        ../uwnr-splits/lsui-train/clean --in-air ../shared/data/inair \\
        --bank-underwater ../shared/data/paired/uieb-train/underwater \\
        ../uwnr-splits/lsui-train/underwater

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


def image_chromaticity(p: Path) -> np.ndarray:
    m = np.asarray(Image.open(p).convert("RGB").resize((128, 128), Image.BILINEAR), dtype=np.float64)
    m = m.reshape(-1, 3).mean(0)
    return m / m.sum()


def share_fit(c: np.ndarray, u: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    cb, ub = c.mean(0), u.mean(0)
    return float(((c - cb) * (u - ub)).sum() / ((u - ub) ** 2).sum()), cb, ub


def follow(clean_dirs: list[Path], water_dirs: list[Path]) -> None:
    if len(clean_dirs) != len(water_dirs):
        raise SystemExit("--bank-underwater needs one folder per --bank folder")
    parts = []
    for cd, wd in zip(clean_dirs, water_dirs):
        pairs = [(p, wd / p.name) for p in images([cd]) if (wd / p.name).exists()]
        if not pairs:
            raise SystemExit(f"no pairs between {cd} and {wd}")
        c = np.array([image_chromaticity(a) for a, _ in pairs])
        u = np.array([image_chromaticity(b) for _, b in pairs])
        parts.append((cd, c, u))
    c = np.concatenate([p[1] for p in parts])
    u = np.concatenate([p[2] for p in parts])
    share, cb, ub = share_fit(c, u)
    fixed = ((c - cb) ** 2).sum()
    follows = ((c - cb - share * (u - ub)) ** 2).sum()
    print(f"bank pairs ({len(c)}): clean chromaticity {np.round(cb, 4).tolist()}, "
          f"underwater {np.round(ub, 4).tolist()}")
    print(f"share of the water's cast the clean side keeps: {share:.3f} "
          f"(residual {follows / fixed:.3f} of the fixed balance's)")
    for i, (cd, ci, ui) in enumerate(parts):
        rest = [p for j, p in enumerate(parts) if j != i]
        if not rest:
            continue
        si, cbi, ubi = share_fit(ci, ui)
        co = np.concatenate([p[1] for p in rest])
        uo = np.concatenate([p[2] for p in rest])
        e0 = ((co - cbi) ** 2).sum()
        e1 = ((co - cbi - si * (uo - ubi)) ** 2).sum()
        print(f"  fitted on {cd} alone: {si:.3f}; on the others, residual {e1 / e0:.3f} of the fixed balance's")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bank", type=Path, nargs="+", required=True, help="the bank's clean sides")
    ap.add_argument("--in-air", type=Path, nargs="+", required=True, help="photos taken in air")
    ap.add_argument("--bank-underwater", type=Path, nargs="+",
                    help="the bank's underwater sides, one folder per --bank folder")
    args = ap.parse_args()
    bank, air = images(args.bank), images(args.in_air)
    if not bank or not air:
        raise SystemExit("no images found")
    cb, ca = chromaticity(bank), chromaticity(air)
    print(f"bank clean sides ({len(bank)}): chromaticity {np.round(cb, 4).tolist()}")
    print(f"in air ({len(air)}): chromaticity {np.round(ca, 4).tolist()}")
    print(f"balance (R, G, B gains): {np.round(cb / ca, 3).tolist()}")
    if args.bank_underwater:
        follow(args.bank, args.bank_underwater)


if __name__ == "__main__":
    main()
