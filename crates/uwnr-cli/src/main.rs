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

/// The training wing's commands (the `train` feature). A build without them (the README's first
/// install line) names the install that has them, where clap would only say "unrecognized
/// subcommand".
const TRAINING_COMMANDS: [&str; 5] = ["train", "enhance", "gan", "experiment", "water"];

/// The one-line error for `uwnr COMMAND` when COMMAND is one of the training wing's.
#[cfg_attr(feature = "train", allow(dead_code))]
fn missing_training_command(command: &str) -> Option<String> {
    TRAINING_COMMANDS.contains(&command).then(|| {
        format!(
            "uwnr: error: `uwnr {command}` is in the training wing, which this build leaves out; \
             install every command with `cargo install --locked --path crates/uwnr-cli`"
        )
    })
}

fn main() -> std::process::ExitCode {
    quiet_on_broken_pipe();
    #[cfg(not(feature = "train"))]
    if let Some(message) = std::env::args()
        .nth(1)
        .as_deref()
        .and_then(missing_training_command)
    {
        eprintln!("{message}");
        return std::process::ExitCode::from(2);
    }
    let args = cli::Cli::parse();
    match commands::run(args) {
        Ok(code) => code,
        Err(err) => {
            // One line a user can act on: the context chain joined by ": ", each cause once
            // (an error's message includes its cause, uwnr_core::error).
            eprintln!("uwnr: error: {}", report::line(&err));
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::missing_training_command;

    #[test]
    fn a_training_command_names_the_install_that_has_it() {
        let message = missing_training_command("train").unwrap();
        assert!(message.contains("`uwnr train`"), "{message}");
        assert!(
            message.contains("cargo install --locked --path crates/uwnr-cli`"),
            "{message}"
        );
        assert_eq!(missing_training_command("render"), None);
        assert_eq!(missing_training_command("dataset"), None);
    }

    /// The list is the commands the `train` feature adds, no more and no fewer.
    #[cfg(feature = "train")]
    #[test]
    fn the_list_is_the_training_wings_commands() {
        use super::TRAINING_COMMANDS;
        use clap::CommandFactory;
        let all = crate::cli::Cli::command();
        for name in TRAINING_COMMANDS {
            assert!(all.find_subcommand(name).is_some(), "{name}");
        }
        let render_wing = [
            "render",
            "lightfield",
            "depth",
            "info",
            "convert",
            "eval",
            "dataset",
            "serve",
            "help",
        ];
        for sub in all.get_subcommands() {
            let name = sub.get_name();
            assert!(
                TRAINING_COMMANDS.contains(&name) || render_wing.contains(&name),
                "{name} is in neither wing's list"
            );
        }
    }
}
