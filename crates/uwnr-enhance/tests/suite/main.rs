//! Integration tests of `uwnr-enhance`, in one binary.

mod parity;
