//! Integration tests of `uwnr-train`, in one binary so that the workspace links few large test executables.

mod losses;
mod training;
