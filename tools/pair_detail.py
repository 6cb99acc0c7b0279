#!/usr/bin/env python3
"""How a pair's two sides differ in fine detail and in noise, for real and synthetic pair sets.

For every pair (a folder with `underwater/` and `clean/`, same names; a `uwnr dataset` folder's
`clean/` names carry a `_k` suffix that is matched to the underwater file of the same stem):

- sharpness: the luminance's finest band (Y minus a Gaussian of sigma 1 px) over its middle band
  (Gaussian sigma 1 minus sigma 3), as standard deviations. A uniform change of contrast scales
  both bands alike and leaves it; a lens blur lowers it. Reported as the underwater side's over
  the clean side's (1: as sharp as the clean side);
- noise: Immerkaer's estimate ("Fast noise variance estimation", 1996) of the luminance's noise
  standard deviation in 8-bit levels, for each side.

Images are read at a 256 px shorter side (as the downstream training sees them). Prints the mean
and the 10th and 90th percentiles of each figure per set.

A DIR without `underwater/` and `clean/` is a folder of single images (real photos, or a
dataset's `underwater/` side): its rows give the images' own sharpness and noise, not a ratio.
That is how the default camera stage was matched to real photos (`docs/RESULTS.md`, "The matched
camera").

Usage: python3 tools/pair_detail.py NAME=DIR [NAME=DIR ...] [--limit N]   (numpy, scipy, Pillow)
"""
import argparse
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

SIDE = 256
EXTS = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"}


def luminance(path):
    im = Image.open(path).convert("RGB")
    w, h = im.size
    s = SIDE / min(w, h)
    if s < 1:
        im = im.resize((max(1, round(w * s)), max(1, round(h * s))), Image.BICUBIC)
    a = np.asarray(im, dtype=np.float64)
    return a @ np.array([0.299, 0.587, 0.114])


def sharpness(y):
    g1 = ndimage.gaussian_filter(y, 1.0)
    g3 = ndimage.gaussian_filter(y, 3.0)
    mid = (g1 - g3).std()
    return (y - g1).std() / mid if mid > 1e-6 else np.nan


def noise(y):
    # Immerkaer 1996: sigma = sqrt(pi/2) / (6 (W-2)(H-2)) * sum |I * M|
    m = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float64)
    r = ndimage.convolve(y, m, mode="reflect")[1:-1, 1:-1]
    return np.sqrt(np.pi / 2) * np.abs(r).mean() / 6.0


def f(v):
    v = np.asarray(v)
    return f"{v.mean():.3f} ({np.percentile(v, 10):.3f}, {np.percentile(v, 90):.3f})"


def evenly(items, limit):
    """At most `limit` of `items`, evenly spaced over the list."""
    if len(items) <= limit:
        return items
    return [items[i] for i in np.linspace(0, len(items) - 1, limit).round().astype(int)]


def pairs(root):
    root = Path(root)
    uw = {p.stem: p for p in (root / "underwater").iterdir() if p.suffix.lower() in EXTS}
    for c in sorted((root / "clean").iterdir()):
        if c.suffix.lower() not in EXTS:
            continue
        u = uw.get(c.stem)
        if u is None:
            continue
        yield u, c


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("sets", nargs="+")
    ap.add_argument("--limit", type=int, default=400)
    a = ap.parse_args()
    sets = [spec.split("=", 1) for spec in a.sets]
    paired = [(n, d) for n, d in sets if (Path(d) / "underwater").is_dir()]
    singles = [(n, d) for n, d in sets if not (Path(d) / "underwater").is_dir()]
    if paired:
        print("| set | pairs | sharpness, underwater / clean (mean, p10, p90) "
              "| noise, underwater (levels) | noise, clean |")
        print("|---|---:|---|---|---|")
    for name, d in paired:
        ps = evenly(list(pairs(d)), a.limit)
        ratio, nu, nc = [], [], []
        for u, c in ps:
            yu, yc = luminance(u), luminance(c)
            ratio.append(sharpness(yu) / sharpness(yc))
            nu.append(noise(yu))
            nc.append(noise(yc))
        r = np.array(ratio)
        print(f"| {name} | {len(ps)} | {f(r[np.isfinite(r)])} | {f(nu)} | {f(nc)} |")
    if singles:
        if paired:
            print()
        print("| images | count | sharpness (mean, p10, p90) | noise (levels) |")
        print("|---|---:|---|---|")
    for name, d in singles:
        fs = evenly(sorted(p for p in Path(d).iterdir() if p.suffix.lower() in EXTS), a.limit)
        sh, nz = [], []
        for p in fs:
            y = luminance(p)
            sh.append(sharpness(y))
            nz.append(noise(y))
        sh = np.array(sh)
        print(f"| {name} | {len(fs)} | {f(sh[np.isfinite(sh)])} | {f(nz)} |")

if __name__ == "__main__":
    main()
