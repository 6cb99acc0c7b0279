#!/usr/bin/env python3
"""Reference values for crates/render/uwnr-metrics, computed with numpy / scipy / scikit-image.

What each number is (the Rust crate follows the same definitions):

- PSNR: `skimage.metrics.peak_signal_noise_ratio(target, pred, data_range=1.0)` on float64
  RGB in [0, 1]; `psnr_gray` does the same on ITU-R BT.601 luma
  Y = 0.299 R + 0.587 G + 0.114 B (OpenCV's RGB2GRAY weights, kept in float64).
- SSIM: `skimage.metrics.structural_similarity(target, pred, channel_axis=2,
  gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0)`
  (Wang et al. 2004); `ssim_uniform7` is skimage's default 7x7 uniform window with
  sample covariance (what the FUnIE-GAN and Shallow-UWnet evaluation scripts call).
- UIQM: a vectorised re-implementation of `Evaluation/uqim_utils.py` of
  xahidbuffon/FUnIE-GAN with integer block counts (`int(W / window)`, the Python 3 fix
  that circulates), on the image quantised to 8 bits (0..255, as the scripts read
  files), computed in float64. Preset `funie_gan`: RGB
  channel order and 10x10 blocks (as that file calls it). Preset `shallow_uwnet`: 8x8
  blocks and the channels taken in BGR order, as mkartik/Shallow-UWnet's
  `uiqm_utils.py` receives them from `cv2.imread`. One deliberate difference: where a
  channel has no edges at all the reference divides 0 by 0 (NaN); here that Sobel map
  stays 0 and its EME term is 0.
- UCIQE: a re-implementation of `nmetrics` in `nevaluate.py` of
  xueleichen/PSNR-SSIM-UCIQE-UIQM-Python (after its 2022 fix of con_l): skimage
  `rgb2lab`; sigma_c = population std of chroma sqrt(a^2 + b^2); con_l = mean of the
  top round(1%) of L minus mean of the bottom round(1%) (at least one pixel);
  mu_s = mean of chroma / L (0 where chroma or L is 0).
- Frechet distance: pytorch-fid's formula with `scipy.linalg.sqrtm` (`fd_sqrtm`), and
  the same quantity with the trace of sqrt(S1 S2) as the nuclear norm of
  Xc1 Xc2^T / sqrt((n1-1)(n2-1)) from numpy's SVD (`fd_exact`), which stays accurate when
  n < d, where sqrtm of a singular product loses digits.
- KID: the unbiased MMD^2 with k(x, y) = (x.y / d + 1)^3 of torch-fidelity /
  clean-fid, on whole sets of equal size (the value every subset gives when the subset
  size equals the set size).

Images are 8-bit PNGs written into the fixtures folder and read back as u8 / 255 in
float32 (what uwnr's decoder produces), then widened to float64.

Run from the repository root:  python3 tools/metrics_reference.py
Writes crates/render/uwnr-metrics/tests/fixtures/{*.png, metrics_expected.json, frechet_expected.json}.
"""

import json
import math
from pathlib import Path

import numpy as np
import scipy.linalg
from PIL import Image
from scipy import ndimage
from skimage.color import rgb2lab
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "assets" / "samples"
OUT_DIR = ROOT / "crates" / "render" / "uwnr-metrics" / "tests" / "fixtures"
SEED = 1234

LUMA_BT601 = np.array([0.299, 0.587, 0.114])
UIQM_C = (0.0282, 0.2953, 3.5753)
UISM_LAMBDA = (0.299, 0.587, 0.144)  # sic: 0.144, as in the FUnIE-GAN code
UICM_W = (-0.0268, 0.1586)
UCIQE_C = (0.4680, 0.2745, 0.2576)
PRESETS = {"funie_gan": (10, False), "shallow_uwnet": (8, True)}  # (block, bgr)


# ---------------------------------------------------------------- images


def save_png(name, u8):
    Image.fromarray(u8, "RGB").save(OUT_DIR / name)


def load_float(name):
    u8 = np.asarray(Image.open(OUT_DIR / name).convert("RGB"))
    return (u8.astype(np.float32) / np.float32(255.0)).astype(np.float64)


def quantise(x):
    return np.round(np.clip(x, 0.0, 1.0) * 255.0).astype(np.uint8)


def make_images(rng):
    """Writes the input PNGs; returns (no-reference image names, (target, pred) pairs)."""

    def sample(name, size):
        im = Image.open(SAMPLES / name).convert("RGB")
        return np.asarray(im.resize(size, Image.BOX)) if size else np.asarray(im)

    room = sample("clean-room.jpg", (120, 90))
    statues = sample("clean-statues.jpg", (77, 115))
    blue = sample("ref-blue.jpg", (128, 96))
    green = sample("ref-green.png", None)  # 256x256
    save_png("room_120x90.png", room)
    save_png("statues_77x115.png", statues)
    save_png("blue_128x96.png", blue)
    save_png("green_256.png", green)

    f = room.astype(np.float64) / 255.0
    save_png("room_120x90_pred.png", quantise(0.9 * f + 0.05 + rng.normal(0.0, 0.03, f.shape)))
    f = blue.astype(np.float64) / 255.0
    save_png("blue_128x96_pred.png", quantise(f**0.8))
    g = green[40:160, 60:220].astype(np.float64) / 255.0  # 160x120
    save_png("green_160x120.png", quantise(g))
    save_png("green_160x120_pred.png", quantise(ndimage.gaussian_filter(g, (1.0, 1.0, 0.0)) + 0.02))
    synth = rng.integers(0, 256, size=(41, 33, 3)).astype(np.uint8)
    save_png("synth_33x41.png", synth)
    save_png("synth_33x41_pred.png", quantise(synth / 255.0 + rng.normal(0.0, 0.05, synth.shape)))

    images = ["room_120x90.png", "statues_77x115.png", "blue_128x96.png", "green_256.png", "synth_33x41.png"]
    pairs = [
        ("room_120x90.png", "room_120x90_pred.png"),
        ("blue_128x96.png", "blue_128x96_pred.png"),
        ("green_160x120.png", "green_160x120_pred.png"),
        ("synth_33x41.png", "synth_33x41_pred.png"),
    ]
    return images, pairs


# ---------------------------------------------------------------- full-reference


def luma(x):
    return x @ LUMA_BT601


def full_reference(target, pred):
    return {
        "psnr": peak_signal_noise_ratio(target, pred, data_range=1.0),
        "psnr_gray": peak_signal_noise_ratio(luma(target), luma(pred), data_range=1.0),
        "ssim": structural_similarity(
            target,
            pred,
            channel_axis=2,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
            data_range=1.0,
        ),
        "ssim_gray": structural_similarity(
            luma(target), luma(pred), gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0
        ),
        "ssim_uniform7": structural_similarity(target, pred, channel_axis=2, data_range=1.0),
    }


# ---------------------------------------------------------------- UIQM


def trimmed_mean(v, alpha=0.1):
    # The FUnIE-GAN mean drops ceil(aK) values on the left plus one more, floor(aK) on
    # the right, and divides by K - ceil(aK) - floor(aK).
    s = np.sort(v)
    k = s.size
    t_l = math.ceil(alpha * k)
    t_r = math.floor(alpha * k)
    return float(s[t_l + 1 : k - t_r].sum()) / (k - t_l - t_r)


def uicm(x):
    c0, c1, c2 = (x[..., i].ravel() for i in range(3))
    rg = c0 - c1
    yb = (c0 + c1) / 2.0 - c2
    mu_rg, mu_yb = trimmed_mean(rg), trimmed_mean(yb)
    s_rg = float(np.mean((rg - mu_rg) ** 2))
    s_yb = float(np.mean((yb - mu_yb) ** 2))
    return UICM_W[0] * math.hypot(mu_rg, mu_yb) + UICM_W[1] * math.sqrt(s_rg + s_yb)


def sobel_scaled(ch):
    mag = np.hypot(ndimage.sobel(ch, 0), ndimage.sobel(ch, 1))
    m = mag.max()
    return mag * (255.0 / m) if m > 0 else np.zeros_like(mag)


def blocks(x, ws):
    k1, k2 = x.shape[1] // ws, x.shape[0] // ws
    x = x[: k2 * ws, : k1 * ws]
    shape = (k2, ws, k1, ws) + x.shape[2:]
    axes = (1, 3) + tuple(range(4, x.ndim + 2))
    b = x.reshape(shape)
    return b.max(axis=axes), b.min(axis=axes), k1 * k2


def eme(x, ws):
    mx, mn, nb = blocks(x, ws)
    ok = (mn != 0) & (mx != 0)
    terms = np.zeros_like(mx)
    terms[ok] = np.log(mx[ok] / mn[ok])
    return 2.0 / nb * float(terms.sum())


def uism(x, ws):
    return sum(lam * eme(sobel_scaled(x[..., c]) * x[..., c], ws) for c, lam in enumerate(UISM_LAMBDA))


def uiconm(x, ws):
    mx, mn, nb = blocks(x, ws)
    top, bot = mx - mn, mx + mn
    ok = (top != 0) & (bot != 0)
    terms = np.zeros_like(mx)
    r = top[ok] / bot[ok]
    terms[ok] = r * np.log(r)
    return -1.0 / nb * float(terms.sum())


def uiqm(img, preset):
    ws, bgr = PRESETS[preset]
    # The reference scripts read 8-bit files; EME's exact-zero tests need those integers
    # (u8 / 255 * 255 in floating point is off by an ulp, and an ulp-sized Sobel response
    # where the integers cancel exactly turns a 0 term into log(max / 1e-13)).
    x = np.round(np.clip(img, 0.0, 1.0) * 255.0)
    if bgr:
        x = x[..., ::-1]
    parts = {"uicm": uicm(x), "uism": uism(x, ws), "uiconm": uiconm(x, ws)}
    parts["uiqm"] = UIQM_C[0] * parts["uicm"] + UIQM_C[1] * parts["uism"] + UIQM_C[2] * parts["uiconm"]
    return parts


# ---------------------------------------------------------------- UCIQE


def uciqe(img):
    lab = rgb2lab(img)
    lum, a, b = lab[..., 0].ravel(), lab[..., 1].ravel(), lab[..., 2].ravel()
    chroma = np.sqrt(a**2 + b**2)
    sigma_c = float(np.sqrt(np.mean((chroma - chroma.mean()) ** 2)))
    top = max(1, int(np.round(0.01 * lum.size)))
    s = np.sort(lum)
    con_l = float(s[::-1][:top].mean() - s[:top].mean())
    ok = (chroma != 0) & (lum != 0)
    sat = np.zeros_like(chroma)
    sat[ok] = chroma[ok] / lum[ok]
    mu_s = float(sat.mean())
    value = UCIQE_C[0] * sigma_c + UCIQE_C[1] * con_l + UCIQE_C[2] * mu_s
    return {"sigma_c": sigma_c, "con_l": con_l, "mu_s": mu_s, "uciqe": value}


# ---------------------------------------------------------------- Frechet distance and KID


def fd_sqrtm(a, b):
    """pytorch-fid's calculate_frechet_distance on np.cov statistics."""
    mu1, mu2 = a.mean(0), b.mean(0)
    s1, s2 = np.atleast_2d(np.cov(a, rowvar=False)), np.atleast_2d(np.cov(b, rowvar=False))
    diff = mu1 - mu2
    covmean = scipy.linalg.sqrtm(s1.dot(s2))
    if not np.isfinite(covmean).all():
        offset = np.eye(s1.shape[0]) * 1e-6
        covmean = scipy.linalg.sqrtm((s1 + offset).dot(s2 + offset))
    if np.iscomplexobj(covmean):
        covmean = covmean.real
    return float(diff.dot(diff) + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(covmean))


def fd_exact(a, b):
    n1, n2 = len(a), len(b)
    x1, x2 = a - a.mean(0), b - b.mean(0)
    # Singular values near 0 come out accurate to eps * s_max (no square root of rounding).
    tr_sqrt = np.linalg.svd(x1 @ x2.T, compute_uv=False).sum() / math.sqrt((n1 - 1) * (n2 - 1))
    diff = a.mean(0) - b.mean(0)
    tr1 = (x1**2).sum() / (n1 - 1)
    tr2 = (x2**2).sum() / (n2 - 1)
    return float(diff.dot(diff) + tr1 + tr2 - 2.0 * tr_sqrt)


def mmd2_poly(x, y):
    d = x.shape[1]
    m = x.shape[0]
    kxx = (x @ x.T / d + 1.0) ** 3
    kyy = (y @ y.T / d + 1.0) ** 3
    kxy = (x @ y.T / d + 1.0) ** 3
    return float(
        (kxx.sum() - np.trace(kxx) + kyy.sum() - np.trace(kyy)) / (m * (m - 1)) - 2.0 * kxy.sum() / (m * m)
    )


def feature_cases(rng):
    def gauss(n, d, shift, scale):
        mix = rng.normal(0.0, 1.0, (d, d)) * scale / math.sqrt(d)
        return rng.normal(0.0, 1.0, (n, d)) @ mix + shift

    cases = []
    for name, n1, n2, d in [
        ("n_gt_d", 60, 50, 6),
        ("n_lt_d", 10, 12, 32),
        ("n_lt_d_unequal", 5, 40, 20),
        ("kid_equal", 30, 30, 12),
    ]:
        a = gauss(n1, d, 0.0, 1.0)
        b = gauss(n2, d, rng.normal(0.0, 0.5, d), 1.3)
        case = {"name": name, "a": a.tolist(), "b": b.tolist(), "fd_sqrtm": fd_sqrtm(a, b), "fd_exact": fd_exact(a, b)}
        if n1 == n2:
            case["kid_full"] = mmd2_poly(a, b)
        cases.append(case)
    a = gauss(15, 8, 0.0, 1.0)
    cases.append({"name": "identical", "a": a.tolist(), "b": a.tolist(), "fd_sqrtm": fd_sqrtm(a, a), "fd_exact": 0.0})
    return cases


# ---------------------------------------------------------------- main


def main():
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(SEED)
    images, pairs = make_images(rng)

    no_ref = {}
    for name in images:
        img = load_float(name)
        no_ref[name] = {"uciqe": uciqe(img), **{f"uiqm_{p}": uiqm(img, p) for p in PRESETS}}
    full_ref = [{"target": t, "pred": p, **full_reference(load_float(t), load_float(p))} for t, p in pairs]

    with open(OUT_DIR / "metrics_expected.json", "w") as f:
        json.dump({"no_reference": no_ref, "full_reference": full_ref}, f, indent=1)
    with open(OUT_DIR / "frechet_expected.json", "w") as f:
        json.dump({"cases": feature_cases(rng)}, f)

    for name, v in no_ref.items():
        print(f"{name}: UIQM {v['uiqm_funie_gan']['uiqm']:.4f}  UCIQE {v['uciqe']['uciqe']:.4f}")
    for v in full_ref:
        print(f"{v['pred']}: PSNR {v['psnr']:.3f}  SSIM {v['ssim']:.4f}")


if __name__ == "__main__":
    main()
