#!/usr/bin/env python3
"""Where a render folder's FID and KID come from, against the real set of tools/realism_probe.py:
FID split into its mean term |mu - mu_real|^2 and its covariance term, the trace of the features'
covariance (their spread), KID x1000, KID x1000 once the features are shifted to the real mean
(what is left when only the mean differs no more), and the folder's mean RGB (per image, then over
images) beside the real set's.

    target/fid-venv/bin/python tools/realism_decompose.py --inception target/fid/inception-fid-pool3.onnx \\
        --real runs/realism/crops-b/clean NAME=DIR [NAME=DIR...]

The real set's features are cached as realism_probe.py caches them.
"""

import argparse
import sys
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fid_parity import fid_exact, kid_u_statistic, list_images  # noqa: E402
from realism_probe import features, real_features  # noqa: E402


def mean_rgb(files: list[Path]) -> np.ndarray:
    return np.mean([np.asarray(Image.open(p).convert("RGB"), dtype=np.float64).reshape(-1, 3).mean(0) / 255 for p in files], 0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inception", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--cache", type=Path, default=Path("target/realism/real-features.npy"))
    ap.add_argument("sets", nargs="+", help="NAME=DIR")
    args = ap.parse_args()

    import onnxruntime as ort

    session = ort.InferenceSession(str(args.inception), providers=["CPUExecutionProvider"])
    plain = argparse.Namespace(blur=0.0, noise=0.0, jpeg=0)
    fr = real_features(session, args.real, args.cache)
    mr = fr.mean(0)
    rgb = mean_rgb(list_images(args.real))
    print(f"real\tn={len(fr)}\ttrace(C) {np.trace(np.cov(fr, rowvar=False)):.1f}\tmean RGB {np.round(rgb, 3).tolist()}")
    print("set\tFID\tmean term\tcovariance term\ttrace(C)\tKID x1000\tKID x1000, mean matched\tmean RGB")
    for spec in args.sets:
        name, _, d = spec.partition("=")
        files = list_images(Path(d))
        f = features(session, files, plain)
        fid = fid_exact(f, fr)
        mean_term = float(((f.mean(0) - mr) ** 2).sum())
        print(
            f"{name}\t{fid:.1f}\t{mean_term:.1f}\t{fid - mean_term:.1f}\t{np.trace(np.cov(f, rowvar=False)):.1f}\t"
            f"{1000 * kid_u_statistic(f, fr):.1f}\t{1000 * kid_u_statistic(f - f.mean(0) + mr, fr):.1f}\t"
            f"{np.round(mean_rgb(files), 3).tolist()}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
