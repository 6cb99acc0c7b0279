//! `uwnr experiment downstream`: the paper's Table 1 for any data (library: `uwnr_experiment`).

use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_core::io::DecodeLimits;
use uwnr_experiment::enhance::train::EnhanceTrainConfig;
use uwnr_experiment::{DownstreamSpec, Event, ExperimentError, TrainingSet};
use uwnr_render::MethodKind;
use uwnr_run::Event as RunEvent;

use crate::cli::{
    DeviceArg, DownstreamArgs, ExperimentAction, ExperimentArgs, ModelOpts, PrecisionArg,
};

/// Enhancer crop side when no --enhance-config is given.
const DEFAULT_CROP: usize = 128;

pub fn run(a: &ExperimentArgs) -> Result<ExitCode> {
    match &a.action {
        ExperimentAction::Downstream(d) => downstream(d),
    }
}

fn training_sets(a: &DownstreamArgs) -> Result<Vec<TrainingSet>> {
    let have_refs = !a.references.is_empty();
    super::method::refuse_inapplicable(&a.methods, &a.baseline, have_refs)?;
    let mut sets = Vec::new();
    for &m in &a.methods {
        // The GAN's generator is --gan-weights (--weights is the UWNR network's).
        let model = ModelOpts {
            weights: if m == MethodKind::Uwgan {
                a.gan_weights.clone()
            } else {
                a.model.weights.clone()
            },
            // Renders run on the engine; --device is where the enhancers train.
            device: DeviceArg::Engine,
            ..a.model.clone()
        };
        sets.push(TrainingSet {
            name: m.name().to_string(),
            renderer: super::method::renderer(
                m,
                &a.baseline,
                &model,
                PrecisionArg::F32,
                have_refs,
            )?,
        });
    }
    Ok(sets)
}

fn downstream(a: &DownstreamArgs) -> Result<ExitCode> {
    let mut train = match &a.enhance_config {
        Some(p) => EnhanceTrainConfig::from_json_file(p)
            .with_context(|| format!("reading {}", p.display()))?,
        // Crops of 128 from the 256x256 pairs: a quarter of the cost of whole pairs (measured
        // with libtorch on 2 cores: 0.98 s per step of 4 x 128² or of 1 x 256²).
        None => EnhanceTrainConfig {
            crop: DEFAULT_CROP,
            ..EnhanceTrainConfig::default()
        },
    };
    if let Some(v) = a.crop {
        train.crop = v;
    }
    if let Some(v) = a.batch_size {
        train.batch_size = v;
    }
    let sets = training_sets(a)?;
    let spec = DownstreamSpec {
        clean: a.clean.clone(),
        references: a.references.clone(),
        tests: a.test.clone(),
        real: a.real.clone(),
        out: a.out.clone(),
        per_image: a.per_image,
        size: a.size,
        seed: a.seed,
        depth: super::depth_source(&a.depth)?,
        depth_policy: super::depth_policy(
            &a.depth,
            a.baseline.depth_scale,
            uwnr_render::DepthPolicy::default(),
        ),
        train,
        budget: a.budget,
        eval_max_side: (a.eval_max_side > 0).then_some(a.eval_max_side),
        examples: a.examples,
        jobs: a.jobs.unwrap_or_else(|| {
            std::thread::available_parallelism()
                .map(usize::from)
                .unwrap_or(1)
        }),
        device: super::device(a.model.device)?,
        vgg19: a.vgg19.clone(),
        limits: DecodeLimits::default(),
        target: a
            .target
            .as_deref()
            .map(|dir| uwnr_dataset::WaterTarget::load(dir, &DecodeLimits::default()))
            .transpose()?,
        camera: a.camera,
    };

    let stop = super::stop_on_ctrl_c(
        "stopping at the next safe point (Ctrl-C again to abort; run the same command to continue)",
    )?;

    let bar = super::progress_bar("{spinner} {prefix} {pos}/{len} [{bar:30}] eta {eta} {msg}");
    let mut observer = |e: Event<'_>| match e {
        Event::Stage(s) => {
            bar.suspend(|| eprintln!("== {s}"));
            bar.set_position(0);
            bar.set_length(0);
            bar.set_message("");
        }
        Event::Dataset(name, e) => match e {
            uwnr_dataset::Event::Start { todo, .. } => {
                bar.set_prefix(format!("{name} pairs"));
                bar.set_length(todo as u64);
                bar.set_position(0);
                bar.reset_eta();
            }
            uwnr_dataset::Event::Pair(_) => bar.inc(1),
            uwnr_dataset::Event::Failed(f) => {
                bar.inc(f.ids.len() as u64);
                bar.suspend(|| eprintln!("uwnr: failed: {}: {}", f.source, f.reason));
            }
            uwnr_dataset::Event::Note(n) => bar.suspend(|| eprintln!("{n}")),
        },
        Event::Train(name, e) => match e {
            RunEvent::Started {
                step, total_steps, ..
            } => {
                bar.set_prefix(format!("{name} steps"));
                bar.set_length(total_steps as u64);
                bar.set_position(step as u64);
                bar.reset_eta();
            }
            RunEvent::Step { step, losses, .. } => {
                bar.set_position(step as u64);
                let total = losses.last().copied().unwrap_or(f64::NAN);
                bar.set_message(format!("loss {total:.4}"));
            }
            RunEvent::Message(m) => bar.suspend(|| eprintln!("{m}")),
            _ => {}
        },
        Event::Scored {
            row,
            test,
            scores,
            cached,
        } => bar.suspend(|| {
            eprintln!(
                "{row} on {test}: PSNR {:.2} SSIM {:.3} UIQM {:.3} UCIQE {:.3} ({} images{})",
                scores.psnr,
                scores.ssim,
                scores.uiqm,
                scores.uciqe,
                scores.images,
                if cached {
                    ", from an earlier session"
                } else {
                    ""
                }
            );
        }),
    };
    let result = uwnr_experiment::run_downstream(&spec, &sets, &stop, &mut observer);
    bar.finish_and_clear();
    match result {
        Ok(_) => {
            eprintln!(
                "wrote {} and {}",
                a.out.join(uwnr_experiment::run::RESULTS_MD).display(),
                a.out.join(uwnr_experiment::run::RESULTS_JSON).display()
            );
            Ok(ExitCode::SUCCESS)
        }
        Err(ExperimentError::Stopped) => {
            eprintln!("stopped; run the same command again to continue");
            Ok(ExitCode::from(130))
        }
        Err(e) => Err(e.into()),
    }
}
