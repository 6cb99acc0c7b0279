//! Integration tests of `uwnr-enhance`, in one binary.

mod common;
mod eval;
mod parity;
mod training;
