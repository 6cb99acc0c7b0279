//! `uwnr experiment downstream`: the paper's Table 1 for any data (library: `uwnr_experiment`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use uwnr_core::io::DecodeLimits;
use uwnr_dataset::Renderer;
use uwnr_experiment::enhance::train::EnhanceTrainConfig;
use uwnr_experiment::{DownstreamSpec, Event, ExperimentError, TrainingSet};
use uwnr_run::Event as RunEvent;

use crate::cli::{BaselineOpts, DepthOpts, MethodArg, ModelOpts};

/// Enhancer crop side when no --enhance-config is given.
const DEFAULT_CROP: usize = 128;

#[derive(Debug, Args)]
pub struct ExperimentArgs {
    #[command(subcommand)]
    pub action: ExperimentAction,
}

#[derive(Debug, Subcommand)]
pub enum ExperimentAction {
    /// Render one training set per method from the same clean images and references, train
    /// Shallow-UWnet on each with the same budget, score each on real paired test sets, and
    /// write OUT/results.md, OUT/results.json and OUT/examples.png (the paper's Table 1).
    Downstream(Box<DownstreamArgs>),
}

#[derive(Debug, Args)]
pub struct DownstreamArgs {
    /// Clean images: files or folders (searched recursively).
    #[arg(long, num_args = 1.., value_name = "DIR|FILE")]
    pub clean: Vec<PathBuf>,
    /// Real underwater references: files or folders (searched recursively).
    #[arg(long, num_args = 1.., value_name = "DIR|FILE")]
    pub references: Vec<PathBuf>,
    /// Real paired test sets (underwater/ + clean/).
    #[arg(long, num_args = 1.., value_name = "DIR", required = true)]
    pub test: Vec<PathBuf>,
    /// Real paired training sets, trained on with the same budget as reference rows.
    #[arg(long, num_args = 1.., value_name = "DIR")]
    pub real: Vec<PathBuf>,
    /// Output folder (run the same command again to continue).
    #[arg(long, short = 'o', value_name = "OUT", required = true)]
    pub out: PathBuf,
    /// Rendering methods, one training set each.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "uwnr,uwgan,jerlov,uisa,seathru,reinhard"
    )]
    pub methods: Vec<MethodArg>,
    /// Renders per clean image, each after a different reference.
    #[arg(long, short = 'k', value_name = "K", default_value_t = 4)]
    pub per_image: usize,
    /// Size of the synthetic pairs: native or WxH (scaled to cover, centre-cropped).
    #[arg(long, value_name = "native|WxH", default_value = "256x256")]
    pub size: uwnr_dataset::Size,
    /// Seed of the reference draw, the methods' parameters and training.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Training samples each network sees (the same for every training set).
    #[arg(long, value_name = "SAMPLES", default_value_t = 6000)]
    pub budget: usize,
    /// Enhancer training config (JSON, see `uwnr enhance train`); epochs and learning-rate
    /// steps are set from the budget.
    #[arg(long, value_name = "FILE")]
    pub enhance_config: Option<PathBuf>,
    /// Override: enhancer crop side (default 128, or the --enhance-config file's).
    #[arg(long)]
    pub crop: Option<usize>,
    /// Override: enhancer batch size.
    #[arg(long)]
    pub batch_size: Option<usize>,
    /// VGG19 weights (safetensors, torchvision keys) for the enhancer's perceptual term.
    #[arg(long, value_name = "FILE")]
    pub vgg19: Option<PathBuf>,
    /// Test images with a longer side above this are downscaled to it before scoring
    /// (0 = score at native size).
    #[arg(long, value_name = "PIXELS", default_value_t = 512)]
    pub eval_max_side: usize,
    /// Test images per test set shown in examples.png.
    #[arg(long, value_name = "N", default_value_t = 2)]
    pub examples: usize,
    /// Rendering threads (default: the number of CPU cores).
    #[arg(long, short = 'j', value_name = "J")]
    pub jobs: Option<usize>,
    #[command(flatten)]
    pub baseline: BaselineOpts,
    #[command(flatten)]
    pub depth: DepthOpts,
    #[command(flatten)]
    pub model: ModelOpts,
    /// GAN generator for the uwgan set (`generator.safetensors` of a `uwnr gan train` run);
    /// default the bundled one. (--weights is the UWNR network's.)
    #[arg(long, value_name = "FILE")]
    pub gan_weights: Option<PathBuf>,
}

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
        let renderer = match super::method::baseline_method(m, &a.baseline, have_refs)? {
            Some(method) => Renderer::Baseline(method),
            None if m == MethodArg::Uwgan => super::gan_renderer(
                &crate::cli::ModelOpts {
                    weights: a.gan_weights.clone(),
                    ..a.model.clone()
                },
                crate::cli::PrecisionArg::F32,
            )?,
            None => super::network_renderer(&a.model)?,
        };
        sets.push(TrainingSet {
            name: super::method::method_name(m).to_string(),
            renderer,
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
            uwnr_dataset::DepthPolicy::default(),
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
