#!/usr/bin/env python3
"""Independent numpy re-implementation of uwnr-depth's built-in depth prior (src/builtin.rs),
used to check the values pinned in tests/suite/builtin.rs (`pinned_values`).

The antialiased bilinear resize is PIL's `Image.resize(..., BILINEAR)` on float ("F") images,
the filter uwnr_core::resize::resize_bilinear reproduces.

Run: python3 crates/render/uwnr-depth/tests/reference/builtin_depth_ref.py   (needs numpy, pillow)
"""

import numpy as np
from PIL import Image

GRID_LONG_SIDE = 48
RAMP_WEIGHT = 0.75
CONTRAST_WEIGHT = 0.25
SMOOTH_SIGMA_FRACTION = 1.5 / GRID_LONG_SIDE
MIN_CONTRAST_SPREAD = 5.0 / 255.0
GAUSS_TRUNCATE = 3.0
LUMA_601 = np.array([0.299, 0.587, 0.114])


def resize(a, w, h):
    if a.shape == (h, w):
        return a
    img = Image.fromarray(a.astype(np.float32), "F").resize((w, h), Image.BILINEAR)
    return np.asarray(img, dtype=np.float64)


def blur(a, sigma):
    r = int(np.ceil(GAUSS_TRUNCATE * sigma))
    k = np.exp(-np.arange(-r, r + 1) ** 2 / (2 * sigma * sigma))
    k /= k.sum()
    h, w = a.shape
    tmp = sum(kk * a[:, np.clip(np.arange(w) + i - r, 0, w - 1)] for i, kk in enumerate(k))
    return sum(kk * tmp[np.clip(np.arange(h) + i - r, 0, h - 1), :] for i, kk in enumerate(k))


def builtin_depth(rgb):
    """rgb: float array [h, w, 3] in [0, 1] -> depth [h, w] in [0, 1], far = 1."""
    h, w, _ = rgb.shape
    luma = rgb @ LUMA_601
    luma = luma - luma.mean()
    if max(w, h) <= GRID_LONG_SIDE:
        gw, gh = w, h
    else:
        s = GRID_LONG_SIDE / max(w, h)
        gw, gh = (min(max(1, int(np.floor(v * s + 0.5))), GRID_LONG_SIDE) for v in (w, h))
    m, m2 = resize(luma, gw, gh), resize(luma * luma, gw, gh)
    sigma = np.sqrt(np.maximum(m2 - m * m, 0))
    contrast = (sigma.max() - sigma) / max(sigma.max() - sigma.min(), MIN_CONTRAST_SPREAD)
    ramp = 1 - (np.arange(gh) + 0.5) / gh
    grid = blur(RAMP_WEIGHT * ramp[:, None] + CONTRAST_WEIGHT * contrast, SMOOTH_SIGMA_FRACTION * max(gw, gh))
    d = resize(grid, w, h)
    return (d - d.min()) / (d.max() - d.min())


def scene(width, height):
    """Same image as `scene` in tests/suite/builtin.rs."""
    y, x = np.mgrid[0:height, 0:width]
    fx, fy = x / width, y / height
    base = np.stack([0.3 + 0.4 * fx, 0.2 + 0.5 * fy, 0.6 - 0.3 * fx * fy], axis=-1)
    square = width // 24
    board = (fx >= 0.5) & (fy >= 0.5) & ((x // square + y // square) % 2 == 0)
    return np.where(board[..., None], base * 0.3, base)


if __name__ == "__main__":
    depth = builtin_depth(scene(144, 96))
    for x, y in [(0, 0), (72, 48), (108, 72), (36, 72), (143, 95)]:
        print(f"({x}, {y}): {depth[y, x]:.6f}")
