#!/usr/bin/env python3
"""Mean colour of both sides of a paired set, per channel: what its water does to R, G and B.

Usage: python3 tools/pair_channels.py DIR... (each with clean/ and underwater/, files paired by
name without extension; `--limit N` pairs per set, default 400, taken in name order). Prints, per
set, the mean R/G/B of the clean and the underwater sides (0-255) and their ratio, underwater over
clean. docs/RESULTS.md compares synthetic sets with real pairs this way. Needs numpy and Pillow.
"""
import sys
from pathlib import Path

import numpy as np
from PIL import Image

EXTS = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


def by_stem(folder):
    return {p.stem: p for p in sorted(folder.iterdir()) if p.suffix.lower() in EXTS}


def channel_means(d, limit):
    clean, under = by_stem(d / "clean"), by_stem(d / "underwater")
    stems = sorted(set(clean) & set(under))[:limit]
    if not stems:
        raise ValueError(f"{d}: no pairs (clean/ and underwater/ with the same names)")
    c_sum, u_sum = np.zeros(3), np.zeros(3)
    for s in stems:
        c = Image.open(clean[s]).convert("RGB")
        u = Image.open(under[s]).convert("RGB")
        if u.size != c.size:
            u = u.resize(c.size, Image.BILINEAR)
        c_sum += np.asarray(c, dtype=np.float64).reshape(-1, 3).mean(0)
        u_sum += np.asarray(u, dtype=np.float64).reshape(-1, 3).mean(0)
    return len(stems), c_sum / len(stems), u_sum / len(stems)


def main(argv):
    args, limit = argv[1:], 400
    if args[:1] == ["--limit"]:
        if len(args) < 2 or not args[1].isdigit() or int(args[1]) == 0:
            print("error: --limit needs a positive number", file=sys.stderr)
            return 2
        limit, args = int(args[1]), args[2:]
    if not args:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    lines = []
    for d in args:
        try:
            n, c, u = channel_means(Path(d), limit)
        except (OSError, ValueError) as e:
            print(f"error: {e}", file=sys.stderr)
            return 1
        lines.append(f"| {d} | {n} | {rgb(c, 0)} | {rgb(u, 0)} | {rgb(u / c, 2)} |")
    print("| pairs | n | clean R/G/B | underwater R/G/B | ratio R/G/B |")
    print("|---|---:|---|---|---|")
    print("\n".join(lines))
    return 0


def rgb(v, digits):
    return "/".join(f"{x:.{digits}f}" for x in v)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
