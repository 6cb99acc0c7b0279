//! Integration tests of `uwnr-dataset`, in one binary so that the workspace links few large test
//! executables. The baselines render here (fast, no network weights); the network path is
//! exercised end to end by the CLI tests.

mod common;
mod depth;
mod generate;
mod shards;
mod verify;
