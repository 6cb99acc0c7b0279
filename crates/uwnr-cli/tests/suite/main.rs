//! End-to-end tests of the `uwnr` binary, in one test executable.

mod cli;
#[allow(dead_code)]
mod common;
mod dataset;
mod depth_response;
mod enhance;
mod experiment;
mod gan;
mod golden;
mod haze;
mod labels;
mod methods;
mod realism_training;
mod serve;
mod strength;
