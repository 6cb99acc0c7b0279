//! Integration tests of `uwnr-baselines`, in one binary so that the workspace links few large test executables.

mod golden;
mod properties;
mod reference_values;
