#!/usr/bin/env python3
"""Writes the tiny ONNX "depth models" used by crates/render/uwnr-depth/tests.

They are not depth networks: each computes a known function of its input so the Rust
tests can re-compute the expected output and compare numerically:

    disparity = sigmoid(sum_c W[c] * x[c] + B)        (a 1x1 convolution, then Sigmoid)

where x is the ImageNet-normalised NCHW input. The sigmoid is monotonic but not affine,
so after uwnr's min-max normalisation the result still depends on the per-channel mean
and std used to normalise the input (a purely linear model would hide a wrong mean).

Files written to crates/render/uwnr-depth/tests/fixtures/:
- tiny_fixed.onnx     input [1,3,8,12] (fixed H=8, W=12), output [1,1,8,12]
- tiny_dynamic.onnx   input [1,3,"height","width"], output [1,"height","width"] (Squeeze)
- tiny_bad_output.onnx input [1,3,"height","width"], output [1,3,"height","width"]
                       (a 3-channel output that must be rejected)

Run from the repository root:  python3 tools/make_tiny_depth_onnx.py
Needs the `onnx` and `numpy` packages. The weights below are repeated in
crates/render/uwnr-depth/tests/suite/onnx.rs; change both together.
"""

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

# Weights of the 1x1 convolution (R, G, B) and its bias; distinct and of mixed sign so
# a channel swap or a missing normalisation changes the result.
W = [0.8, -0.5, 0.3]
B = 0.1

FIXED_H, FIXED_W = 8, 12
OPSET = 13
IR_VERSION = 8

OUT_DIR = Path(__file__).resolve().parent.parent / "crates" / "render" / "uwnr-depth" / "tests" / "fixtures"


def conv_weights(out_channels):
    """Initializers of a 1x1 conv from 3 channels to `out_channels`."""
    if out_channels == 1:
        w = np.array(W, dtype=np.float32).reshape(1, 3, 1, 1)
        b = np.array([B], dtype=np.float32)
    else:
        w = np.eye(3, dtype=np.float32).reshape(3, 3, 1, 1)
        b = np.zeros(3, dtype=np.float32)
    return [numpy_helper.from_array(w, "conv_w"), numpy_helper.from_array(b, "conv_b")]


def save(graph, name):
    model = helper.make_model(
        graph,
        opset_imports=[helper.make_opsetid("", OPSET)],
        producer_name="uwnr make_tiny_depth_onnx.py",
    )
    model.ir_version = IR_VERSION
    onnx.checker.check_model(model, full_check=True)
    path = OUT_DIR / name
    onnx.save(model, path)
    print(f"wrote {path} ({path.stat().st_size} bytes)")


def fixed():
    x = helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, FIXED_H, FIXED_W])
    y = helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, 1, FIXED_H, FIXED_W])
    nodes = [
        helper.make_node("Conv", ["image", "conv_w", "conv_b"], ["lin"], kernel_shape=[1, 1]),
        helper.make_node("Sigmoid", ["lin"], ["disparity"]),
    ]
    save(helper.make_graph(nodes, "tiny_fixed", [x], [y], conv_weights(1)), "tiny_fixed.onnx")


def dynamic():
    x = helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "height", "width"])
    y = helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, "height", "width"])
    axes = numpy_helper.from_array(np.array([1], dtype=np.int64), "squeeze_axes")
    nodes = [
        helper.make_node("Conv", ["image", "conv_w", "conv_b"], ["lin"], kernel_shape=[1, 1]),
        helper.make_node("Sigmoid", ["lin"], ["sig"]),
        helper.make_node("Squeeze", ["sig", "squeeze_axes"], ["disparity"]),
    ]
    graph = helper.make_graph(nodes, "tiny_dynamic", [x], [y], conv_weights(1) + [axes])
    save(graph, "tiny_dynamic.onnx")


def bad_output():
    x = helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "height", "width"])
    y = helper.make_tensor_value_info("rgb", TensorProto.FLOAT, [1, 3, "height", "width"])
    nodes = [helper.make_node("Conv", ["image", "conv_w", "conv_b"], ["rgb"], kernel_shape=[1, 1])]
    save(helper.make_graph(nodes, "tiny_bad_output", [x], [y], conv_weights(3)), "tiny_bad_output.onnx")


if __name__ == "__main__":
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    fixed()
    dynamic()
    bad_output()
