#!/usr/bin/env python3
"""Checks that `uwnr eval --inception` computes the FID and KID the field computes.

On two image folders, runs `uwnr eval --images A --real B --inception FILE.onnx --seed S --json`
and compares its `fid` and `kid` with a NumPy/SciPy computation on features extracted here from
the same files with the same ONNX network (onnxruntime) and the same preprocessing
(pytorch-fid's: u8 / 255, `F.interpolate(299x299, bilinear, align_corners=False)` without
antialiasing, `2 x - 1`). Files are taken as uwnr takes them: one level, sorted, by extension.

- FID as pytorch-fid's `calculate_frechet_distance`: `numpy.cov` (divisor n - 1),
  `scipy.linalg.sqrtm(sigma1 @ sigma2, disp=False)` with its `eps = 1e-6` offset when the
  product is singular, the real part kept. With fewer images than dimensions (2048) the
  covariances are singular and sqrtm loses digits, so the same quantity is also given exactly:
  `tr(sqrt(S1 S2))` as the nuclear norm of `Xc1 Xc2^T / sqrt((n1-1)(n2-1))` (NumPy's SVD).
- KID as uwnr-metrics defines it (Bińkowski et al. 2018, torch-fidelity / clean-fid): the
  unbiased MMD^2 with `k(x, y) = (x.y / d + 1)^3`, averaged over 100 subsets of
  `m = min(1000, n1, n2)` samples drawn without replacement from each set. uwnr draws the
  subsets with its own generator, so the comparison value is the expectation of that estimator
  over subsets, the complete U-statistic: within-set kernel sums over all i != j divided by
  n (n - 1), the cross sum over all pairs divided by n1 n2. It is exact when m equals both set
  sizes; otherwise uwnr's mean differs from it by about its standard error
  (`kid_std / sqrt(100)`), which is printed beside the difference. NumPy's own 100-subset
  estimate (`numpy.random.RandomState(seed)`, as clean-fid draws) is printed too.

Usage, from the repository root (the venv of tools/export_fid_inception.py):

    target/fid-venv/bin/python tools/fid_parity.py --inception target/fid/inception-fid-pool3.onnx \
        --images RENDERS_DIR --real REAL_DIR [--seed 0] [--uwnr target/release/uwnr]

The uwnr binary is `--uwnr`, else $UWNR_BIN, else target/release/uwnr.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import scipy.linalg
import torch
import torch.nn.functional as F
from PIL import Image

IMAGE_EXTS = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}
SIDE = 299
KID_SUBSETS = 100
KID_SUBSET_SIZE = 1000


def list_images(folder: Path) -> list[Path]:
    """uwnr's `expand_images` on one folder: regular files one level down, sorted, by extension."""
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTS)


def features(session, files: list[Path]) -> np.ndarray:
    out = []
    for p in files:
        u8 = np.asarray(Image.open(p).convert("RGB"))
        x = torch.from_numpy(u8.astype(np.float32) / np.float32(255.0)).permute(2, 0, 1)[None]
        x = F.interpolate(x, size=(SIDE, SIDE), mode="bilinear", align_corners=False)
        x = (2.0 * x - 1.0).numpy()
        (f,) = session.run(None, {"input": x})
        out.append(f.reshape(-1).astype(np.float64))
    return np.stack(out)


def sqrtm(m: np.ndarray) -> np.ndarray:
    """`scipy.linalg.sqrtm(m, disp=False)[0]` as pytorch-fid calls it (SciPy 1.18 drops `disp`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            return scipy.linalg.sqrtm(m, disp=False)[0]
        except TypeError:
            return scipy.linalg.sqrtm(m)


def fid_pytorch_fid(f1: np.ndarray, f2: np.ndarray, eps: float = 1e-6) -> float:
    """pytorch-fid's `calculate_frechet_distance` on `numpy.mean` / `numpy.cov` statistics."""
    mu1, mu2 = f1.mean(0), f2.mean(0)
    sigma1, sigma2 = np.cov(f1, rowvar=False), np.cov(f2, rowvar=False)
    diff = mu1 - mu2
    covmean = sqrtm(sigma1.dot(sigma2))
    if not np.isfinite(covmean).all():
        offset = np.eye(sigma1.shape[0]) * eps
        covmean = sqrtm((sigma1 + offset).dot(sigma2 + offset))
    if np.iscomplexobj(covmean):
        covmean = covmean.real
    return float(diff.dot(diff) + np.trace(sigma1) + np.trace(sigma2) - 2 * np.trace(covmean))


def fid_exact(f1: np.ndarray, f2: np.ndarray) -> float:
    """The same distance with tr(sqrt(S1 S2)) as a nuclear norm (exact for singular covariances)."""
    n1, n2 = len(f1), len(f2)
    x1, x2 = f1 - f1.mean(0), f2 - f2.mean(0)
    diff = f1.mean(0) - f2.mean(0)
    tr1 = np.sum(x1 * x1) / (n1 - 1)
    tr2 = np.sum(x2 * x2) / (n2 - 1)
    nuclear = np.linalg.svd(x1 @ x2.T, compute_uv=False).sum() / np.sqrt((n1 - 1) * (n2 - 1))
    return float(diff.dot(diff) + tr1 + tr2 - 2 * nuclear)


def poly3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a @ b.T / a.shape[1] + 1.0) ** 3


def kid_u_statistic(f1: np.ndarray, f2: np.ndarray) -> float:
    """Expectation over subsets of the subset KID estimator: the complete U-statistic."""
    n1, n2 = len(f1), len(f2)
    k11, k22, k12 = poly3(f1, f1), poly3(f2, f2), poly3(f1, f2)
    within1 = (k11.sum() - np.trace(k11)) / (n1 * (n1 - 1))
    within2 = (k22.sum() - np.trace(k22)) / (n2 * (n2 - 1))
    return float(within1 + within2 - 2.0 * k12.mean())


def kid_subsets(f1: np.ndarray, f2: np.ndarray, seed: int) -> tuple[float, float]:
    """clean-fid's `kernel_distance` with uwnr's subset count and size rule."""
    m = min(KID_SUBSET_SIZE, len(f1), len(f2))
    rng = np.random.RandomState(seed)
    values = []
    for _ in range(KID_SUBSETS):
        x = f1[rng.choice(len(f1), m, replace=False)]
        y = f2[rng.choice(len(f2), m, replace=False)]
        kxx, kyy, kxy = poly3(x, x), poly3(y, y), poly3(x, y)
        values.append(
            (kxx.sum() - np.trace(kxx) + kyy.sum() - np.trace(kyy)) / (m * (m - 1)) - 2.0 * kxy.sum() / (m * m)
        )
    return float(np.mean(values)), float(np.std(values))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inception", type=Path, required=True, help="the ONNX file of export_fid_inception.py")
    ap.add_argument("--images", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=0, help="KID subset seed (uwnr eval --seed)")
    ap.add_argument("--uwnr", type=Path, default=Path(os.environ.get("UWNR_BIN", "target/release/uwnr")))
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args()

    import onnxruntime as ort

    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "eval.json"
        cmd = [
            str(args.uwnr), "eval", "--images", str(args.images), "--real", str(args.real),
            "--inception", str(args.inception), "--seed", str(args.seed), "--json", str(report),
        ]
        print("$", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        sets = json.loads(report.read_text())["sets"]

    session = ort.InferenceSession(str(args.inception), providers=["CPUExecutionProvider"])
    a_files, b_files = list_images(args.images), list_images(args.real)
    fa, fb = features(session, a_files), features(session, b_files)
    if (len(fa), len(fb)) != (int(sets["n_images"]), int(sets["n_real"])):
        sys.exit(f"uwnr scored {sets['n_images']} / {sets['n_real']} images, this script {len(fa)} / {len(fb)}")

    fid_ref = fid_pytorch_fid(fa, fb)
    fid_svd = fid_exact(fa, fb)
    kid_u = kid_u_statistic(fa, fb)
    kid_np, kid_np_std = kid_subsets(fa, fb, args.seed)
    m = min(KID_SUBSET_SIZE, len(fa), len(fb))
    exact_kid = m == len(fa) == len(fb)
    kid_se = sets["kid_std"] / np.sqrt(KID_SUBSETS)

    print(f"images {len(fa)}, real {len(fb)}, KID subsets {KID_SUBSETS} of {m}")
    print(f"FID  uwnr {sets['fid']:.6f}")
    print(f"     scipy sqrtm (pytorch-fid) {fid_ref:.6f}   uwnr - scipy {sets['fid'] - fid_ref:+.3e}")
    print(f"     numpy SVD (exact)         {fid_svd:.6f}   uwnr - svd   {sets['fid'] - fid_svd:+.3e}")
    print(f"KID  uwnr {sets['kid']:.8f} (x1000 {1000 * sets['kid']:.4f}, subset std x1000 {1000 * sets['kid_std']:.4f})")
    print(
        f"     numpy U-statistic {kid_u:.8f}   uwnr - numpy {sets['kid'] - kid_u:+.3e}"
        + ("   (exact: every subset is the whole set)" if exact_kid else f"   (uwnr's standard error {kid_se:.3e})")
    )
    print(f"     numpy {KID_SUBSETS} subsets {kid_np:.8f} (std {kid_np_std:.3e})   uwnr - numpy subsets {sets['kid'] - kid_np:+.3e}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                {
                    "n_images": len(fa), "n_real": len(fb), "kid_subset_size": m, "seed": args.seed,
                    "uwnr": {"fid": sets["fid"], "kid": sets["kid"], "kid_std": sets["kid_std"]},
                    "numpy": {
                        "fid_sqrtm": fid_ref, "fid_svd": fid_svd, "kid_u_statistic": kid_u,
                        "kid_subsets": kid_np, "kid_subsets_std": kid_np_std,
                    },
                },
                indent=1,
            )
            + "\n"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
