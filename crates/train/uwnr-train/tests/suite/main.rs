//! Integration tests of `uwnr-train`, in one binary so that the workspace links few large test executables.
//! The `model_*` modules test burn's generator against the authors' PyTorch outputs and against
//! the engine that renders (`uwnr-model`), whose fixtures they read.

mod adversarial;
mod common;
mod losses;
mod model_anchored;
mod model_engine;
mod model_parity;
mod model_tiling;
mod training;
