//! `uwnr train`: trains the generator on paired folders (library: `uwnr_train::train`).

use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use uwnr_model::GeneratorConfig;
use uwnr_train::trainer::CONFIG_FILE;
use uwnr_train::{ColorCast, Event, LightFieldLoss, TrainConfig, TrainOptions};

use crate::cli::{LightFieldLossArg, TrainArgs};

pub fn run(a: &TrainArgs) -> Result<ExitCode> {
    let cfg = config(a)?;
    let device = super::device(a.device)?;
    let mut opts = TrainOptions::new(a.data.clone(), a.run.clone(), device);
    opts.val = a.val.clone();
    opts.resume = a.resume;
    opts.vgg19 = a.vgg19.clone();
    opts.max_steps = a.max_steps;
    opts.val_refs = a.val_refs.clone();

    let stop = super::stop_on_ctrl_c(
        "stopping after this step and writing a checkpoint (Ctrl-C again to abort)",
    )?;

    let bar =
        super::progress_bar("{spinner} step {pos}/{len} [{bar:30}] {per_sec} eta {eta} {msg}");
    let mut observer = |e: Event<'_>| match e {
        Event::Message(m) => bar.suspend(|| eprintln!("{m}")),
        Event::Started {
            step, total_steps, ..
        } => {
            bar.set_length(total_steps as u64);
            bar.set_position(step as u64);
            bar.reset_eta();
        }
        Event::Step {
            step, epoch, loss, ..
        } => {
            bar.set_position(step as u64);
            bar.set_message(format!("epoch {epoch} loss {:.4}", loss.total));
        }
        Event::Validation(v) => bar.suspend(|| {
            eprintln!(
                "validation at step {} (epoch {}): PSNR {:.2} dB, SSIM {:.4} ({:.0} s)",
                v.step, v.epoch, v.psnr, v.ssim, v.secs
            );
        }),
        Event::Checkpoint { step, path } => {
            bar.suspend(|| eprintln!("checkpoint at step {step}: {}", path.display()));
        }
    };
    let summary = uwnr_train::train(&cfg, &opts, &stop, &mut observer)
        .with_context(|| format!("training run {}", a.run.display()))?;
    bar.finish_and_clear();
    let state = if summary.finished {
        "finished"
    } else if summary.interrupted {
        "stopped (resume with --resume)"
    } else {
        "paused (resume with --resume)"
    };
    eprintln!(
        "{state} at step {} ({} steps this session){}",
        summary.step,
        summary.session_steps,
        summary
            .best
            .map(|(p, s)| format!("; best validation PSNR {p:.2} dB at step {s}"))
            .unwrap_or_default()
    );
    Ok(ExitCode::SUCCESS)
}

/// The run's config: the run folder's `config.json` on resume, else `--config` or the paper's
/// defaults; then the command-line overrides.
fn config(a: &TrainArgs) -> Result<TrainConfig> {
    let saved = a.run.join(CONFIG_FILE);
    let mut cfg = if a.resume {
        if a.config.is_some() {
            bail!(
                "--resume uses the run's own {}; drop --config",
                saved.display()
            );
        }
        TrainConfig::from_json_file(&saved)
            .with_context(|| format!("reading {}", saved.display()))?
    } else if let Some(path) = &a.config {
        TrainConfig::from_json_file(path).with_context(|| format!("reading {}", path.display()))?
    } else {
        TrainConfig::default()
    };
    if let Some(v) = a.epochs {
        cfg.epochs = v;
    }
    if let Some(v) = a.batch_size {
        cfg.batch_size = v;
    }
    if let Some(v) = a.crop {
        cfg.crop = v;
    }
    if let Some(v) = a.seed {
        cfg.seed = v;
    }
    if let Some(v) = a.lr {
        cfg.lr = v;
    }
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
    if let Some(v) = a.val_every {
        cfg.val_every_epochs = v;
    }
    cfg.validate().context("checking the training config")?;
    Ok(cfg)
}
