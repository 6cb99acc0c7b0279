#!/usr/bin/env python3
"""Writes a tiny ONNX stand-in for the InceptionV3 feature network, and its test vector.

crates/render/uwnr-metrics reads a user's InceptionV3 (pool3, 2048-d) through tract-onnx. We
cannot ship Inception weights, so the Rust test runs this tiny model instead: it has
the same interface as pytorch-fid's InceptionV3 exported to ONNX with a fixed input,

    input  "input"  float32 [1, 3, 299, 299]   (RGB, scaled to [-1, 1])
    output "pool3"  float32 [1, D, 1, 1]       (D = 8 here, 2048 for the real network)

and computes Conv(3 -> D, 5x5, stride 4, pad 2) -> Relu -> GlobalAveragePool. The ReLU
makes the output depend non-linearly on the input, so a wrong input range ([0, 1]
instead of [-1, 1]), a channel swap or a different resize changes the numbers.

The expected output is computed here from a small PNG with pytorch-fid's
preprocessing: u8 / 255 as float32, `torch.nn.functional.interpolate(x, (299, 299),
mode="bilinear", align_corners=False)` (no antialiasing), then `2 x - 1`, then the
model evaluated with `onnx.reference.ReferenceEvaluator`.

Files written to crates/render/uwnr-metrics/tests/fixtures/:
- tiny_inception.onnx
- inception_input.png          (a 37x23 RGB image, seeded)
- inception_expected.json      (the D features, plus the resized pixels at a few places)

Run from the repository root:  python3 tools/make_tiny_inception_onnx.py
Needs numpy, pillow, onnx and torch.
"""

import json
from pathlib import Path

import numpy as np
import onnx
import torch
import torch.nn.functional as F
from onnx import TensorProto, helper, numpy_helper
from onnx.reference import ReferenceEvaluator
from PIL import Image

SEED = 20220617
FEATURE_DIM = 8
SIDE = 299
OPSET = 13
IR_VERSION = 8
INPUT_W, INPUT_H = 37, 23

OUT_DIR = Path(__file__).resolve().parent.parent / "crates" / "render" / "uwnr-metrics" / "tests" / "fixtures"


def build_model(rng):
    w = rng.normal(0.0, 0.3, size=(FEATURE_DIM, 3, 5, 5)).astype(np.float32)
    b = rng.normal(0.0, 0.1, size=(FEATURE_DIM,)).astype(np.float32)
    nodes = [
        helper.make_node(
            "Conv", ["input", "conv_w", "conv_b"], ["conv"], kernel_shape=[5, 5], strides=[4, 4], pads=[2, 2, 2, 2]
        ),
        helper.make_node("Relu", ["conv"], ["relu"]),
        helper.make_node("GlobalAveragePool", ["relu"], ["pool3"]),
    ]
    graph = helper.make_graph(
        nodes,
        "tiny_inception",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, [1, 3, SIDE, SIDE])],
        [helper.make_tensor_value_info("pool3", TensorProto.FLOAT, [1, FEATURE_DIM, 1, 1])],
        initializer=[numpy_helper.from_array(w, "conv_w"), numpy_helper.from_array(b, "conv_b")],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = IR_VERSION
    onnx.checker.check_model(model)
    return model


def main():
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(SEED)
    model = build_model(rng)
    onnx.save(model, OUT_DIR / "tiny_inception.onnx")

    # A smooth colour pattern plus noise, so the upsampled image is not trivial.
    yy, xx = np.mgrid[0:INPUT_H, 0:INPUT_W]
    base = np.stack(
        [
            0.5 + 0.4 * np.sin(xx / 5.0),
            0.5 + 0.4 * np.cos(yy / 4.0),
            0.5 + 0.3 * np.sin((xx + yy) / 7.0),
        ],
        axis=-1,
    )
    noisy = np.clip(base + rng.normal(0.0, 0.08, size=base.shape), 0.0, 1.0)
    u8 = np.round(noisy * 255.0).astype(np.uint8)
    Image.fromarray(u8, "RGB").save(OUT_DIR / "inception_input.png")

    x = torch.from_numpy(u8.astype(np.float32) / np.float32(255.0)).permute(2, 0, 1)[None]
    resized = F.interpolate(x, size=(SIDE, SIDE), mode="bilinear", align_corners=False)
    scaled = (2.0 * resized - 1.0).numpy().astype(np.float32)
    (out,) = ReferenceEvaluator(model).run(None, {"input": scaled})
    features = out.reshape(-1).astype(np.float64)

    probes = [(0, 0, 0), (1, 150, 77), (2, 298, 298), (0, 13, 290), (2, 200, 3)]
    expected = {
        "feature_dim": FEATURE_DIM,
        "features": features.tolist(),
        "resized_probes": [
            {"c": c, "y": y, "x": xpos, "value": float(resized[0, c, y, xpos])} for (c, y, xpos) in probes
        ],
    }
    with open(OUT_DIR / "inception_expected.json", "w") as f:
        json.dump(expected, f, indent=1)
    print("features:", features)


if __name__ == "__main__":
    main()
