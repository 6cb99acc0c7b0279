//! Integration tests of `uwnr-model`, in one binary so that the workspace links few large test executables.

mod anchored;
mod common;
mod engine;
mod parity;
mod tiling;
