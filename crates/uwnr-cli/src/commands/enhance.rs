//! `uwnr enhance`: the Shallow-UWnet enhancer of the downstream experiment (library:
//! `uwnr_enhance`).
//!
//! - `enhance train`: trains it on paired folders (underwater -> clean), with exact resume;
//! - `enhance apply`: enhances images or folders of images with trained weights;
//! - `enhance eval`: scores weights, or no enhancement at all, on a paired test folder.

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use serde_json::json;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb, save_rgb, write_atomic};
use uwnr_enhance::{EnhanceTrainConfig, EnhanceTrainOptions, EvalReport, ShallowUwnet};
use uwnr_train::Device;

use super::training;
use crate::cli::{
    EnhanceAction, EnhanceApplyArgs, EnhanceArgs, EnhanceEvalArgs, EnhanceTrainArgs, Pairing,
};
use crate::inputs::{Job, expand_images, plan_jobs};
use crate::report::Batch;

pub fn run(a: &EnhanceArgs) -> Result<ExitCode> {
    match &a.action {
        EnhanceAction::Train(t) => train(t),
        EnhanceAction::Apply(t) => apply(t),
        EnhanceAction::Eval(t) => eval(t),
    }
}

fn train(a: &EnhanceTrainArgs) -> Result<ExitCode> {
    let c = &a.common;
    let cfg: EnhanceTrainConfig = training::config(&c.opts)?;
    cfg.validate()
        .context("checking the enhancer training config")?;
    let device = super::device(c.opts.device)?;
    let mut opts = EnhanceTrainOptions::new(c.data.clone(), c.opts.run.clone(), device);
    opts.val = c.val.clone();
    opts.resume = c.opts.resume;
    opts.vgg19 = c.vgg19.clone();
    opts.max_steps = c.opts.max_steps;

    let stop = training::stop_flag()?;
    let bar = training::progress();
    let summary = uwnr_enhance::train(&cfg, &opts, &stop, &mut |e| training::show(&bar, e))
        .with_context(|| format!("training run {}", c.opts.run.display()))?;
    bar.finish_and_clear();
    eprintln!(
        "{}",
        training::closing_line(&training::Ending {
            finished: summary.finished,
            interrupted: summary.interrupted,
            step: summary.step,
            session_steps: summary.session_steps,
            what: "weights",
            last_weights: &summary.last_weights,
            best: summary
                .best
                .zip(summary.best_weights.as_deref())
                .map(|((p, s), w)| ("validation PSNR", p, s, w)),
        })
    );
    Ok(ExitCode::SUCCESS)
}

/// Loads enhancer weights with a one-line error.
fn load_net(path: &Path, device: &Device) -> Result<ShallowUwnet> {
    let (net, _) = uwnr_enhance::weights::load(path, device)
        .with_context(|| format!("loading enhancer weights {}", path.display()))?;
    Ok(net)
}

fn apply(a: &EnhanceApplyArgs) -> Result<ExitCode> {
    let images = expand_images(&a.images, "input")?;
    let single_file = images.len() == 1 && is_image_path(&a.output) && !a.output.is_dir();
    let jobs: Vec<Job> = if single_file {
        vec![Job {
            clean: 0,
            reference: None,
            output: a.output.clone(),
        }]
    } else {
        if is_image_path(&a.output) && !a.output.is_dir() {
            bail!(
                "--output {} names an image file, but {} images were given: pass a directory",
                a.output.display(),
                images.len()
            );
        }
        std::fs::create_dir_all(&a.output)
            .with_context(|| format!("creating output directory {}", a.output.display()))?;
        plan_jobs(
            &images,
            &[],
            Pairing::Cycle,
            0,
            &a.output,
            a.format.extension(),
        )
    };
    let device = super::device(a.device)?;
    let net = load_net(&a.weights, &device)?;
    let limits = DecodeLimits::default();
    let mut batch = Batch::new(jobs.len(), "enhancing");
    for job in &jobs {
        let input = &images[job.clean];
        let result = (|| -> Result<()> {
            let img = load_rgb(input, &limits).context("reading image")?;
            let out = uwnr_enhance::enhance(&net, &img, &device).context("enhancing")?;
            save_rgb(&job.output, &out)
                .with_context(|| format!("writing {}", job.output.display()))?;
            Ok(())
        })();
        match result {
            Ok(()) => batch.ok(),
            Err(e) => batch.fail(input.clone(), &e),
        }
    }
    let all_ok = batch.finish("enhance");
    if single_file && all_ok {
        eprintln!("wrote {}", a.output.display());
    }
    Ok(if all_ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn eval(a: &EnhanceEvalArgs) -> Result<ExitCode> {
    let device = super::device(a.device)?;
    let net = match &a.weights {
        Some(p) => Some(load_net(p, &device)?),
        None => None,
    };
    let label = match &a.weights {
        Some(p) => format!("enhancer {}", p.display()),
        None => "no enhancement (the underwater input is scored)".to_string(),
    };
    let report = uwnr_enhance::evaluate_dir(
        net.as_ref(),
        &a.data,
        &device,
        a.save.as_deref(),
        a.max_side,
        &DecodeLimits::default(),
    )
    .with_context(|| format!("evaluating on {}", a.data.display()))?;
    print_table(&label, &report);
    let downscaled = report
        .per_image
        .iter()
        .filter(|s| s.downscaled_from.is_some())
        .count();
    if let (Some(n), true) = (a.max_side, downscaled > 0) {
        eprintln!("note: {downscaled} pair(s) downscaled to a longer side of {n} before scoring");
    }
    if !report.skipped.is_empty() {
        eprintln!(
            "{} file(s) without a partner, not scored:",
            report.skipped.len()
        );
        for s in &report.skipped {
            eprintln!("  {s}");
        }
    }
    if let Some(path) = &a.json {
        let doc = json!({
            "enhancer": a.weights.as_ref().map(|p| p.display().to_string()),
            "label": label,
            "data": a.data.display().to_string(),
            "max_side": a.max_side,
            "report": report,
        });
        let text = serde_json::to_string_pretty(&doc).context("encoding the scores as JSON")?;
        write_atomic(path, |out| out.write_all(text.as_bytes()))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(dir) = &a.save {
        eprintln!("outputs written to {}", dir.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// The per-image scores and their means, on stdout.
fn print_table(label: &str, r: &EvalReport) {
    let width = r
        .per_image
        .iter()
        .map(|s| s.name.len())
        .chain(["mean".len()])
        .max()
        .unwrap_or(4);
    println!("# {label}");
    println!(
        "{:<width$}  {:>8}  {:>7}  {:>7}  {:>7}",
        "image", "PSNR", "SSIM", "UIQM", "UCIQE"
    );
    let row = |name: &str, p: f64, s: f64, q: f64, c: f64| {
        println!("{name:<width$}  {p:>8.3}  {s:>7.4}  {q:>7.4}  {c:>7.4}");
    };
    for s in &r.per_image {
        row(&s.name, s.psnr, s.ssim, s.uiqm, s.uciqe);
    }
    row("mean", r.psnr, r.ssim, r.uiqm, r.uciqe);
}
