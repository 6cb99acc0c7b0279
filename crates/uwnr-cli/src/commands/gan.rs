//! `uwnr gan`: the UWGAN-style GAN baseline (library: `uwnr_gan_train`).
//!
//! - `gan train`: unpaired adversarial training, with exact resume; rendering with the trained
//!   generator is `uwnr render --method uwgan` (and `uwnr dataset --method uwgan`).

use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_gan_train::{GanLoss, GanTrainConfig, TrainOptions};

use super::training;
use crate::cli::{GanAction, GanArgs, GanLossArg, GanTrainArgs};

pub fn run(a: &GanArgs) -> Result<ExitCode> {
    match &a.action {
        GanAction::Train(t) => train(t),
    }
}

fn train(a: &GanTrainArgs) -> Result<ExitCode> {
    let c = &a.opts;
    let mut cfg: GanTrainConfig = training::config(c)?;
    if let Some(l) = a.loss {
        cfg.loss = match l {
            GanLossArg::NonSaturating => GanLoss::NonSaturating,
            GanLossArg::LeastSquares => GanLoss::LeastSquares,
        };
    }
    cfg.validate().context("checking the GAN training config")?;
    let device = super::device(c.device)?;
    let mut opts = TrainOptions::new(a.clean.clone(), c.run.clone(), device);
    opts.resume = c.resume;
    opts.max_steps = c.max_steps;

    let stop = training::stop_flag()?;
    let bar = training::progress();
    let summary = uwnr_gan_train::train(&cfg, &opts, &a.references, &stop, &mut |e| {
        training::show_scored(&bar, e, ["colour-moment PSNR", "SSIM to clean"]);
    })
    .with_context(|| format!("training run {}", c.run.display()))?;
    bar.finish_and_clear();
    eprintln!(
        "{}",
        training::closing_line(&training::Ending {
            finished: summary.finished,
            interrupted: summary.interrupted,
            step: summary.step,
            session_steps: summary.session_steps,
            what: "generator",
            last_weights: &summary.last_weights,
            best: summary
                .best
                .zip(summary.best_weights.as_deref())
                .map(|((p, s), w)| ("colour-moment PSNR", p, s, w)),
        })
    );
    Ok(ExitCode::SUCCESS)
}
