//! Integration tests of `uwnr-core`, in one binary so that the workspace links few large test executables.

#[allow(dead_code)]
mod common;
mod dark_channel;
mod io;
mod lightfield;
mod ops;
mod resize;
