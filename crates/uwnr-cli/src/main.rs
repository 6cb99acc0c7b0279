//! `uwnr`: render clean photos into underwater images (UWNR, CVPR-W 2022) and the tools around it.
//!
//! The binary only parses arguments and calls library code; every command lives in `commands/`.

mod cli;
mod commands;
mod inputs;
mod report;

use clap::Parser;

/// Exit status of a command whose standard output was closed by its reader (`uwnr info | head`):
/// 128 + SIGPIPE, what a shell reports for a tool the signal stopped.
const BROKEN_PIPE_STATUS: i32 = 141;

/// Rust ignores SIGPIPE, so printing to a closed pipe panics in `println!`. The reader has
/// gone and wants no more: stop quietly, as tools stopped by SIGPIPE do, instead of printing a
/// panic message. Other panics keep the default report.
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let msg = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(BROKEN_PIPE_STATUS);
        }
        default(info);
    }));
}

fn main() -> std::process::ExitCode {
    quiet_on_broken_pipe();
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
