//! Integration tests of `uwnr-metrics`, in one binary so that the workspace links few large test executables.

#[allow(dead_code)]
mod common;
mod distances;
#[cfg(feature = "onnx")]
mod inception_onnx;
mod reference_values;
mod shared_data;
