#!/usr/bin/env python3
"""Independent NumPy / OpenCV / scikit-image computations of the reference-based baselines'
building blocks, written to crates/render/uwnr-baselines/tests/fixtures/reference_values.json for
crates/render/uwnr-baselines/tests/suite/reference_values.rs to compare against.

- SUID quadtree background light on assets/samples/ref-green.png, following the public
  re-implementation vismiroglou/SUID_data_generation (score = mean - std over all channel values,
  recurse while the region holds more than 1% of the pixels), read off as mean, brightest and
  quarter-rank pixel;
- the red channel prior transmission of Galdran et al. 2015 with OpenCV's erode (15x15), clipped
  to [0.1, 1], and its median (lower middle element);
- Reinhard colour transfer in CIELAB with scikit-image's rgb2lab / lab2rgb, from a small
  synthetic clean image to ref-green.png.

Only PNG inputs are used, so both sides decode the same 8-bit values.

Run from the repository root: python3 tools/baselines_reference.py
"""

import json
from pathlib import Path

import cv2
import numpy as np
from PIL import Image
from skimage import color

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "crates/render/uwnr-baselines/tests/fixtures/reference_values.json"
MIN_FRACTION = 0.01
WINDOW = 15
T_FLOOR = 0.1
CLEAN_W, CLEAN_H = 7, 5


def load(name):
    img = Image.open(ROOT / "assets/samples" / name).convert("RGB")
    # float32 as uwnr stores pixels, then float64 for the statistics.
    return (np.asarray(img).astype(np.float32) / np.float32(255.0)).astype(np.float64)


def quadtree_region(img):
    h, w, _ = img.shape
    thr = MIN_FRACTION * h * w
    y0, x0 = 0, 0
    while h * w > thr and h >= 2 and w >= 2:
        hh, hw = h // 2, w // 2
        quads = [(y0, x0, hh, hw), (y0, x0 + hw, hh, w - hw), (y0 + hh, x0, h - hh, hw), (y0 + hh, x0 + hw, h - hh, w - hw)]
        scores = []
        for qy, qx, qh, qw in quads:
            sub = img[qy:qy + qh, qx:qx + qw, :]
            scores.append(sub.mean() - sub.std())
        y0, x0, h, w = quads[int(np.argmax(scores))]  # first maximum on ties
    return y0, x0, h, w


def backgrounds(img):
    y0, x0, h, w = quadtree_region(img)
    px = img[y0:y0 + h, x0:x0 + w, :].reshape(-1, 3)
    sums = px.sum(axis=1)
    order = np.argsort(-sums, kind="stable")
    return {
        "region_xywh": [int(x0), int(y0), int(w), int(h)],
        "mean": px.mean(axis=0).tolist(),
        "brightest": px[int(np.argmax(sums))].tolist(),
        "quarter_rank": px[order[min(int(len(px) * 0.25), len(px) - 1)]].tolist(),
    }


def red_channel_median(img, b):
    b = np.clip(np.asarray(b), 1e-3, 1 - 1e-3)
    norm = np.stack([(1 - img[..., 0]) / (1 - b[0]), img[..., 1] / b[1], img[..., 2] / b[2]], axis=-1)
    dark = cv2.erode(norm.min(axis=-1).astype(np.float32), np.ones((WINDOW, WINDOW), np.uint8))
    t = np.clip(1.0 - dark.astype(np.float64), T_FLOOR, 1.0).ravel()
    return float(np.sort(t)[(t.size - 1) // 2])


def synthetic_clean():
    """The same deterministic pattern the Rust test builds: warm, in-gamut colours."""
    y, x = np.mgrid[0:CLEAN_H, 0:CLEAN_W]
    r = 0.3 + 0.6 * x / (CLEAN_W - 1)
    g = 0.25 + 0.5 * y / (CLEAN_H - 1)
    b = 0.2 + 0.3 * ((x + y) % 3) / 2
    return np.stack([r, g, b], axis=-1).astype(np.float32).astype(np.float64)


def reinhard_lab(clean, ref):
    src = color.rgb2lab(clean)
    tgt = color.rgb2lab(ref)
    ms, ss = src.reshape(-1, 3).mean(0), src.reshape(-1, 3).std(0)
    mt, st = tgt.reshape(-1, 3).mean(0), tgt.reshape(-1, 3).std(0)
    out = color.lab2rgb((src - ms) * (st / ss) + mt)
    return np.clip(out, 0, 1), mt.tolist(), st.tolist()


def main():
    ref = load("ref-green.png")
    bg = backgrounds(ref)
    out, mt, st = reinhard_lab(synthetic_clean(), ref)
    values = {
        "source": "tools/baselines_reference.py",
        "reference": "assets/samples/ref-green.png",
        "quadtree": bg,
        "red_channel_median_transmission": red_channel_median(ref, bg["mean"]),
        "reinhard_lab": {
            "width": CLEAN_W,
            "height": CLEAN_H,
            "reference_mean": mt,
            "reference_std": st,
            # HWC, row-major.
            "output_hwc": out.reshape(-1).tolist(),
        },
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(values, indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}: background {np.round(bg['mean'], 4)}, "
          f"median t {values['red_channel_median_transmission']:.4f}")


if __name__ == "__main__":
    main()
