#!/usr/bin/env python3
"""Quick realism scores while developing a lever: FID and KID of image folders against the real
set of tools/realism_table.sh, with the real set's Inception features computed once and cached.

The figures are the ones `uwnr eval --inception` gives up to its KID subset noise: the same
network (onnxruntime on the ONNX of export_fid_inception.py), the same preprocessing and FID
(tools/fid_parity.py's functions; FID exact through the SVD), KID as the complete U-statistic
(the expectation of uwnr's 100-subset estimate). The table in docs/RESULTS.md is made with
`uwnr eval`, not with this script.

    target/fid-venv/bin/python tools/realism_probe.py --inception target/fid/inception-fid-pool3.onnx \
        --real runs/realism/crops-b/clean DIR [DIR...]

Optional transforms probe a camera stage before it is built, on copies in memory:
--blur SIGMA (Gaussian, px), --noise STD (u8 levels), --jpeg QUALITY.
"""

import argparse
import hashlib
import io
import sys
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image, ImageFilter

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fid_parity import SIDE, fid_exact, kid_u_statistic, list_images  # noqa: E402


def load(p: Path, args, rng) -> np.ndarray:
    img = Image.open(p).convert("RGB")
    if args.blur > 0:
        img = img.filter(ImageFilter.GaussianBlur(args.blur))
    u8 = np.asarray(img)
    if args.noise > 0:
        u8 = np.clip(u8 + rng.normal(0, args.noise, u8.shape), 0, 255).round().astype(np.uint8)
    if args.jpeg > 0:
        buf = io.BytesIO()
        Image.fromarray(u8).save(buf, "JPEG", quality=args.jpeg)
        u8 = np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))
    return u8


def features(session, files, args) -> np.ndarray:
    rng = np.random.default_rng(0)
    out = []
    batch = []
    for i, p in enumerate(files):
        u8 = load(p, args, rng)
        x = torch.from_numpy(u8.astype(np.float32) / np.float32(255.0)).permute(2, 0, 1)[None]
        x = F.interpolate(x, size=(SIDE, SIDE), mode="bilinear", align_corners=False)
        batch.append((2.0 * x - 1.0).numpy())
        if len(batch) == 1 or i == len(files) - 1:
            (f,) = session.run(None, {"input": np.concatenate(batch)})
            out.append(f.reshape(len(batch), -1).astype(np.float64))
            batch = []
    return np.concatenate(out)


def real_features(session, real: Path, cache: Path) -> np.ndarray:
    """The Inception features of the real set's images, cached beside `cache` under a key of
    their paths."""
    real_files = list_images(real)
    key = hashlib.sha256("\n".join(str(p) for p in real_files).encode()).hexdigest()[:16]
    cached = cache.with_name(f"{cache.stem}-{key}.npy")
    if cached.exists():
        return np.load(cached)
    fr = features(session, real_files, argparse.Namespace(blur=0.0, noise=0.0, jpeg=0))
    cached.parent.mkdir(parents=True, exist_ok=True)
    np.save(cached, fr)
    return fr


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inception", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--cache", type=Path, default=Path("target/realism/real-features.npy"))
    ap.add_argument("--blur", type=float, default=0.0)
    ap.add_argument("--noise", type=float, default=0.0)
    ap.add_argument("--jpeg", type=int, default=0)
    ap.add_argument("dirs", type=Path, nargs="+")
    args = ap.parse_args()

    import onnxruntime as ort

    session = ort.InferenceSession(str(args.inception), providers=["CPUExecutionProvider"])
    fr = real_features(session, args.real, args.cache)
    for d in args.dirs:
        f = features(session, list_images(d), args)
        print(f"{d}\tn={len(f)}\tFID {fid_exact(f, fr):.1f}\tKIDx1000 {1000 * kid_u_statistic(f, fr):.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
