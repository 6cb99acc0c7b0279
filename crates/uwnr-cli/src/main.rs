//! `uwnr`: render clean photos into underwater images (UWNR, CVPR-W 2022) and the tools around it.
//!
//! The binary only parses arguments and calls library code; every command lives in `commands/`.

mod cli;
mod commands;
mod inputs;
mod report;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let args = cli::Cli::parse();
    match commands::run(args) {
        Ok(code) => code,
        Err(err) => {
            // One line a user can act on: the context chain joined by ": ".
            eprintln!("uwnr: error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
