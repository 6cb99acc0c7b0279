//! Integration tests of `uwnr-depth`, in one binary so that the workspace links few large test executables.

mod builtin;
mod maps;
#[cfg(feature = "onnx")]
mod onnx;
mod rgbd_eval;
