//! What `uwnr train`, `uwnr enhance train` and `uwnr gan train` share: the run's config (the run folder's own on
//! resume, else `--config` or the defaults, then the common overrides), Ctrl-C, the progress
//! bar fed by uwnr-run's events, and the closing line.

use std::sync::atomic::AtomicBool;

use anyhow::{Context, Result, bail};
use indicatif::ProgressBar;
use uwnr_enhance::EnhanceTrainConfig;
use uwnr_gan_train::GanTrainConfig;
use uwnr_run::Event;
use uwnr_run::folder::{CONFIG_FILE, RunConfig};
use uwnr_train::TrainConfig;

use crate::cli::RunOpts;

/// The settings `RunOpts` can override, in a trainer's config.
pub struct Common<'a> {
    pub epochs: &'a mut usize,
    pub batch_size: &'a mut usize,
    pub crop: &'a mut usize,
    pub seed: &'a mut u64,
    pub lr: &'a mut f64,
    pub val_every_epochs: &'a mut usize,
}

/// A trainer's config as the command line sees it.
pub trait TrainerConfig: RunConfig + Default {
    /// Its fields that [`RunOpts`] overrides.
    fn common(&mut self) -> Common<'_>;
}

/// The trainers' configs name the common settings alike.
macro_rules! trainer_config {
    ($($t:ty),*) => {$(
        impl TrainerConfig for $t {
            fn common(&mut self) -> Common<'_> {
                Common {
                    epochs: &mut self.epochs,
                    batch_size: &mut self.batch_size,
                    crop: &mut self.crop,
                    seed: &mut self.run.seed,
                    lr: &mut self.lr,
                    val_every_epochs: &mut self.run.val_every_epochs,
                }
            }
        }
    )*};
}

trainer_config!(TrainConfig, EnhanceTrainConfig, GanTrainConfig);

/// The run's config: the run folder's `config.json` on resume, else `--config` or the
/// defaults; then the command-line overrides of [`RunOpts`] (the caller applies its own).
pub fn config<C: TrainerConfig>(a: &RunOpts) -> Result<C> {
    let saved = a.run.join(CONFIG_FILE);
    let mut cfg = if a.resume {
        if a.config.is_some() {
            bail!(
                "--resume uses the run's own {}; drop --config",
                saved.display()
            );
        }
        C::from_json_file(&saved).with_context(|| format!("reading {}", saved.display()))?
    } else if let Some(path) = &a.config {
        C::from_json_file(path).with_context(|| format!("reading {}", path.display()))?
    } else {
        C::default()
    };
    let c = cfg.common();
    let overrides = [
        (a.epochs, &mut *c.epochs),
        (a.batch_size, &mut *c.batch_size),
        (a.crop, &mut *c.crop),
        (a.val_every, &mut *c.val_every_epochs),
    ];
    for (given, field) in overrides {
        if let Some(v) = given {
            *field = v;
        }
    }
    if let Some(v) = a.seed {
        *c.seed = v;
    }
    if let Some(v) = a.lr {
        *c.lr = v;
    }
    Ok(cfg)
}

/// Ctrl-C ends the session at the next step with a checkpoint.
pub fn stop_flag() -> Result<std::sync::Arc<AtomicBool>> {
    super::stop_on_ctrl_c(
        "stopping after this step and writing a checkpoint (Ctrl-C again to abort)",
    )
}

/// A progress bar over the run's steps and the observer that drives it.
pub fn progress() -> ProgressBar {
    super::progress_bar("{spinner} step {pos}/{len} [{bar:30}] {per_sec} eta {eta} {msg}")
}

/// Shows one event of the loop on `bar`.
pub fn show(bar: &ProgressBar, e: Event<'_>) {
    show_scored(bar, e, ["PSNR", "SSIM"]);
}

/// [`show`], naming the two validation scores (trainers without pairs report stand-ins).
pub fn show_scored(bar: &ProgressBar, e: Event<'_>, [psnr, ssim]: [&str; 2]) {
    match e {
        Event::Message(m) => bar.suspend(|| eprintln!("{m}")),
        Event::Started {
            step, total_steps, ..
        } => {
            bar.set_length(total_steps as u64);
            bar.set_position(step as u64);
            bar.reset_eta();
        }
        Event::Step {
            step,
            epoch,
            losses,
            ..
        } => {
            bar.set_position(step as u64);
            let total = losses.last().copied().unwrap_or(f64::NAN);
            bar.set_message(format!("epoch {epoch} loss {total:.4}"));
        }
        Event::Validation(v) => bar.suspend(|| {
            eprintln!(
                "validation at step {} (epoch {}): {psnr} {:.2} dB, {ssim} {:.4} ({:.0} s)",
                v.step, v.epoch, v.psnr, v.ssim, v.secs
            );
        }),
        Event::Checkpoint { step, path } => {
            bar.suspend(|| eprintln!("checkpoint at step {step}: {}", path.display()));
        }
    }
}

/// What a session of a trainer that exports weights ended with, for [`closing_line`].
pub struct Ending<'a> {
    pub finished: bool,
    pub interrupted: bool,
    pub step: usize,
    pub session_steps: usize,
    /// What the weights are called (`weights`, `generator`).
    pub what: &'a str,
    pub last_weights: &'a std::path::Path,
    /// The validation score's name, the best value, its step and weights.
    pub best: Option<(&'a str, f64, usize, &'a std::path::Path)>,
}

/// The closing line of such a session: how it ended, where the weights are, the best checkpoint.
pub fn closing_line(e: &Ending<'_>) -> String {
    format!(
        "{} at step {} ({} steps this session); {}: {}{}",
        ended(e.finished, e.interrupted),
        e.step,
        e.session_steps,
        e.what,
        e.last_weights.display(),
        e.best
            .map(|(name, p, s, w)| format!("; best {name} {p:.2} dB at step {s}: {}", w.display()))
            .unwrap_or_default()
    )
}

/// How the session ended, as the closing line says it.
pub fn ended(finished: bool, interrupted: bool) -> &'static str {
    if finished {
        "finished"
    } else if interrupted {
        "stopped (resume with --resume)"
    } else {
        "paused (resume with --resume)"
    }
}
