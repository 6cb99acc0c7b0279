//! Integration tests of `uwnr-baselines`, in one binary so that the workspace links few large test executables.

mod golden;
mod properties;
mod reference_values;

/// A render's record as the JSON a manifest holds.
fn value(record: &impl serde::Serialize) -> serde_json::Value {
    serde_json::to_value(record).unwrap()
}
