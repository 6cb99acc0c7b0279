#!/usr/bin/env python3
"""How each training set of the downstream experiment looks beside the real test inputs.

For every paired folder (`underwater/` + `clean/`, matched by name) prints:
- the mean colour of the underwater images (0-255, R G B) and its blue-minus-red and
  green-minus-red;
- the mean RMS contrast of their luminance (per-image standard deviation, 0-255);
- the mean PSNR of underwater against clean: how strong the degradation is.

A folder without `underwater/` is taken as unpaired underwater images (searched recursively;
no PSNR). Images whose longer side exceeds 512 are downscaled first (as the experiment scores them).
Used for the discussion in docs/RESULTS.md:

    python3 tools/downstream_stats.py ../uwnr-runs/downstream-v1/data/* \
        ../shared/data/paired/euvp-dark ../shared/data/paired/uieb-val ../shared/data/paired/lsui \
        ../shared/data/references
"""

import sys
from pathlib import Path

import numpy as np
from PIL import Image

EXTS = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


def load(path: Path) -> np.ndarray:
    im = Image.open(path).convert("RGB")
    w, h = im.size
    if max(w, h) > 512:
        s = 512 / max(w, h)
        im = im.resize((max(1, round(w * s)), max(1, round(h * s))), Image.BILINEAR)
    return np.asarray(im, dtype=np.float64)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a - b) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def look(u: np.ndarray) -> tuple[np.ndarray, float]:
    """Mean colour and luminance RMS contrast of one image."""
    return u.reshape(-1, 3).mean(0), float((u @ np.array([0.299, 0.587, 0.114])).std())


def row(label: str, count: int, looks: list, psnr_cell: str) -> str:
    m = np.mean([l[0] for l in looks], 0)
    contrast = np.mean([l[1] for l in looks])
    return (
        f"| {label} | {count} | {m[0]:.0f} {m[1]:.0f} {m[2]:.0f} | {m[2] - m[0]:+.0f} | "
        f"{m[1] - m[0]:+.0f} | {contrast:.1f} | {psnr_cell} |"
    )


def unpaired(folder: Path) -> str:
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in EXTS)
    return row(f"{folder.name} (unpaired)", len(files), [look(load(f)) for f in files], "–")


def stats(folder: Path) -> str:
    if not (folder / "underwater").is_dir():
        return unpaired(folder)
    under = {p.stem: p for p in (folder / "underwater").iterdir() if p.suffix.lower() in EXTS}
    clean = {p.stem: p for p in (folder / "clean").iterdir() if p.suffix.lower() in EXTS}
    names = sorted(set(under) & set(clean))
    looks, psnrs = [], []
    for n in names:
        u, c = load(under[n]), load(clean[n])
        if u.shape != c.shape:
            c = np.asarray(
                Image.fromarray(c.astype(np.uint8)).resize((u.shape[1], u.shape[0]), Image.BILINEAR),
                dtype=np.float64,
            )
        looks.append(look(u))
        psnrs.append(psnr(u, c))
    return row(folder.name, len(names), looks, f"{np.mean(psnrs):.2f}")


def main() -> None:
    print("| set | pairs | mean R G B | B - R | G - R | luminance contrast | PSNR underwater vs clean (dB) |")
    print("|---|---:|---|---:|---:|---:|---:|")
    for arg in sys.argv[1:]:
        print(stats(Path(arg)), flush=True)


if __name__ == "__main__":
    main()
