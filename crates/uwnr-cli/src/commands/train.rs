//! `uwnr train`: trains the generator on paired folders (library: `uwnr_train::train`).

use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_model::GeneratorConfig;
use uwnr_train::{ColorCast, LightFieldLoss, TrainConfig, TrainOptions};

use super::training;
use crate::cli::{LightFieldLossArg, TrainArgs};

pub fn run(a: &TrainArgs) -> Result<ExitCode> {
    let c = &a.common;
    let cfg = config(a)?;
    let device = super::device(c.opts.device)?;
    let mut opts = TrainOptions::new(c.data.clone(), c.opts.run.clone(), device);
    opts.val = c.val.clone();
    opts.resume = c.opts.resume;
    opts.vgg19 = c.vgg19.clone();
    opts.max_steps = c.opts.max_steps;
    opts.val_refs = a.val_refs.clone();

    let stop = training::stop_flag()?;
    let bar = training::progress();
    let summary = uwnr_train::train(&cfg, &opts, &stop, &mut |e| training::show(&bar, e))
        .with_context(|| format!("training run {}", c.opts.run.display()))?;
    bar.finish_and_clear();
    eprintln!(
        "{} at step {} ({} steps this session){}",
        training::ended(summary.finished, summary.interrupted),
        summary.step,
        summary.session_steps,
        summary
            .best
            .map(|(p, s)| format!("; best validation PSNR {p:.2} dB at step {s}"))
            .unwrap_or_default()
    );
    Ok(ExitCode::SUCCESS)
}

/// The run's config ([`training::config`]), then the overrides only `uwnr train` has.
fn config(a: &TrainArgs) -> Result<TrainConfig> {
    let mut cfg: TrainConfig = training::config(&a.common.opts)?;
    if let Some(v) = a.width {
        cfg.model = GeneratorConfig {
            base_width: v,
            ..cfg.model
        };
    }
    if let Some(v) = a.light_field_map {
        cfg.model.light_field = v;
    }
    if let Some(v) = a.light_field_loss {
        cfg.light_field_loss = match v {
            LightFieldLossArg::Paper => LightFieldLoss::Paper,
            LightFieldLossArg::Released => LightFieldLoss::Released,
        };
    }
    if a.color_cast && cfg.augment.color_cast.is_none() {
        cfg.augment.color_cast = Some(ColorCast::default());
    }
    cfg.validate().context("checking the training config")?;
    Ok(cfg)
}
