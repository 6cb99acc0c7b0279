//! What a task and its caller give the training loop, and what the loop gives back: the
//! [`Task`] a network implements, the run's [`Schedule`] and options, the events it reports and
//! the [`Summary`] of a session.

use std::path::{Path, PathBuf};

use burn::optim::ModuleOptimizer;
use burn::store::ModuleSnapshot;
use burn::tensor::Device;
use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;

use crate::checkpoint::RunState;
use crate::error::RunError;
use crate::loader::BatchSource;
use crate::plot::SheetLine;
use crate::settings::RunSettings;

/// A network's part of training: what the loop cannot know.
pub trait Task {
    /// The network (on the autodiff device while training).
    type Model: ModuleSnapshot;
    /// The task's error; the loop's own errors convert into it.
    type Error: From<RunError> + std::fmt::Display;
    /// Where its batches come from.
    type Source: BatchSource<Error = Self::Error>;

    /// The loss terms a step returns, in order, as `(csv column, legend name)`; the last is the
    /// total that was minimised.
    fn loss_terms(&self) -> Vec<(String, String)>;

    /// The autodiff device the network trains on.
    fn device(&self) -> &Device;

    /// A new network on [`Task::device`] (the loop seeds burn's generator around it for a fresh
    /// run, [`init_seeded`](super::init_seeded), and overwrites it from the checkpoint for a resumed one).
    fn build(&self) -> Result<Self::Model, Self::Error>;

    /// A new optimiser.
    fn optimizer(&self) -> ModuleOptimizer;

    /// The learning rate of step `step` (0-based), which lies in epoch `epoch`.
    fn lr(&self, step: usize, epoch: usize) -> f64;

    /// One optimisation step on `batch` (step number `step`, 0-based): forward, loss, backward,
    /// an optimiser update at `lr`. Returns the updated network and the loss terms.
    fn step(
        &self,
        model: Self::Model,
        optim: &mut ModuleOptimizer,
        batch: <Self::Source as BatchSource>::Batch,
        step: usize,
        lr: f64,
    ) -> Result<(Self::Model, Vec<f64>), Self::Error>;

    /// Whether there are validation pairs.
    fn has_validation(&self) -> bool;

    /// Scores the network on the validation pairs: mean PSNR and SSIM, per-pair scores, and the
    /// first `sheet_rows` pairs' images for the contact sheet (one per [`Task::sheet_columns`]).
    fn validate(&self, model: &Self::Model, sheet_rows: usize) -> Result<Scores, Self::Error>;

    /// Column headers of the validation contact sheet.
    fn sheet_columns(&self) -> Vec<String>;

    /// Writes the network's own weights file into the checkpoint folder being assembled.
    fn export(&self, model: &Self::Model, dir: &Path, state: &RunState) -> Result<(), Self::Error>;
}

/// What a task's validation measured.
#[derive(Clone, Debug, Default)]
pub struct Scores {
    /// Mean PSNR (dB).
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// `(name, psnr, ssim)` per pair.
    pub per_pair: Vec<(String, f64, f64)>,
    /// Rows of the contact sheet.
    pub sheet: Vec<SheetLine>,
}

impl Scores {
    /// Scores one validation pair: PSNR and SSIM of `output` against `target` (data range 1,
    /// as `uwnr eval` computes them), and a contact-sheet row of `row(output)` while the sheet
    /// has fewer than `sheet_rows` rows.
    pub fn add(
        &mut self,
        name: &str,
        output: Image,
        target: &Image,
        sheet_rows: usize,
        row: impl FnOnce(Image) -> Vec<Image>,
    ) -> Result<(), RunError> {
        let range = uwnr_metrics::DEFAULT_DATA_RANGE;
        let bad = |e: uwnr_metrics::MetricsError| RunError::BadImage {
            path: PathBuf::from(name),
            reason: format!("scoring the validation output: {e}"),
        };
        let psnr = uwnr_metrics::psnr(&output, target, range).map_err(bad)?;
        let ssim = uwnr_metrics::ssim(&output, target, range).map_err(bad)?;
        self.per_pair.push((name.to_string(), psnr, ssim));
        if self.sheet.len() < sheet_rows {
            self.sheet.push((name.to_string(), row(output)));
        }
        let n = self.per_pair.len() as f64;
        self.psnr = self.per_pair.iter().map(|r| r.1).sum::<f64>() / n;
        self.ssim = self.per_pair.iter().map(|r| r.2).sum::<f64>() / n;
        Ok(())
    }
}

/// Validation scores of one evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct ValResult {
    /// Steps done when it ran.
    pub step: usize,
    /// Epochs done.
    pub epoch: usize,
    /// Mean PSNR (dB) over the pairs.
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// `(name, psnr, ssim)` per pair.
    pub per_pair: Vec<(String, f64, f64)>,
    /// Seconds it took.
    pub secs: f64,
}

/// The run's length and cadence (from the task's config).
#[derive(Clone, Debug, PartialEq)]
pub struct Schedule {
    /// Passes over the training pairs.
    pub epochs: usize,
    /// Samples per step (for messages).
    pub batch_size: usize,
    /// End the run after this many steps in total (at most `epochs` whole epochs either way).
    pub total_steps: Option<usize>,
    /// Seed, logging, validation, checkpoint and prefetch cadence.
    pub run: RunSettings,
}

impl Schedule {
    /// The schedule of a run of `epochs` passes in batches of `batch_size`, ended after
    /// `total_steps` steps when given, with the config's run settings.
    #[must_use]
    pub fn new(
        run: &RunSettings,
        epochs: usize,
        batch_size: usize,
        total_steps: Option<usize>,
    ) -> Self {
        Self {
            epochs,
            batch_size,
            total_steps,
            run: run.clone(),
        }
    }
}

/// Where and how a trainer runs (what is not part of the run's config): its data, its run
/// folder, this session's limits. Every trainer takes these.
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// Training folders (`underwater/` + `clean/`, or `raw-890/` + `reference-890/`).
    pub data: Vec<PathBuf>,
    /// Validation folder (same layouts), scored at native resolution.
    pub val: Option<PathBuf>,
    /// The run folder.
    pub run_dir: PathBuf,
    /// Continue the run in `run_dir` from its last checkpoint.
    pub resume: bool,
    /// VGG19 weights (safetensors, torchvision keys) for a perceptual term.
    pub vgg19: Option<PathBuf>,
    /// Compute device (without autodiff; training enables it).
    pub device: Device,
    /// Stop (with a checkpoint) after this many steps in this session.
    pub max_steps: Option<usize>,
    /// PSNR reference lines drawn on the validation curve (e.g. baselines).
    pub val_refs: Vec<f64>,
    /// Image decoding limits.
    pub limits: DecodeLimits,
}

impl TrainOptions {
    /// Options with defaults for everything but the data, the run folder and the device.
    #[must_use]
    pub fn new(data: Vec<PathBuf>, run_dir: PathBuf, device: Device) -> Self {
        Self {
            data,
            val: None,
            run_dir,
            resume: false,
            vgg19: None,
            device,
            max_steps: None,
            val_refs: Vec::new(),
            limits: DecodeLimits::default(),
        }
    }

    /// This session as the loop sees it.
    #[must_use]
    pub fn session(&self) -> Session {
        Session {
            run_dir: self.run_dir.clone(),
            resume: self.resume,
            max_steps: self.max_steps,
            val_refs: self.val_refs.clone(),
        }
    }
}

/// Where the run lives and what this session does (not part of the run's config).
#[derive(Clone, Debug)]
pub struct Session {
    /// The run folder.
    pub run_dir: PathBuf,
    /// Continue the run in `run_dir` from its last checkpoint.
    pub resume: bool,
    /// Stop (with a checkpoint) after this many steps in this session.
    pub max_steps: Option<usize>,
    /// PSNR reference lines drawn on the validation curve (e.g. baselines).
    pub val_refs: Vec<f64>,
}

/// What the data loading left for the loop.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The run's config as JSON (written to `config.json` when the folder is claimed).
    pub config_json: String,
    /// Training pairs (recorded in the state; a resume must see the same number).
    pub pairs: usize,
    /// The data report (shown, and written to `data-report.txt`).
    pub report: String,
}

/// What the loop reports as it goes.
#[derive(Debug)]
pub enum Event<'a> {
    /// Something worth telling the user (the data report, set-up, warnings).
    Message(&'a str),
    /// Training starts at `step` of `total_steps`.
    Started {
        /// Steps already done.
        step: usize,
        /// Steps of the whole run.
        total_steps: usize,
        /// Steps per epoch.
        steps_per_epoch: usize,
    },
    /// A step finished.
    Step {
        /// Steps done.
        step: usize,
        /// Epoch of the step (0-based).
        epoch: usize,
        /// Learning rate used.
        lr: f64,
        /// Its loss terms, in [`Task::loss_terms`] order (the last is the total).
        losses: &'a [f64],
    },
    /// A validation finished.
    Validation(&'a ValResult),
    /// The `last` checkpoint was written.
    Checkpoint {
        /// Steps done.
        step: usize,
        /// Its folder.
        path: &'a Path,
    },
}

/// How a session ended.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Steps done in total.
    pub step: usize,
    /// Steps done in this session.
    pub session_steps: usize,
    /// `(step, loss terms)` of every step of this session.
    pub losses: Vec<(usize, Vec<f64>)>,
    /// The run reached its last step.
    pub finished: bool,
    /// The stop flag ended the session.
    pub interrupted: bool,
    /// Best validation PSNR and its step.
    pub best: Option<(f64, usize)>,
    /// The last validation of this session.
    pub last_val: Option<ValResult>,
    /// The `last` checkpoint folder.
    pub last_dir: PathBuf,
    /// The `best` checkpoint folder, once there is one.
    pub best_dir: Option<PathBuf>,
    /// Seconds of training behind the `last` checkpoint, summed over the sessions that made it
    /// (work lost to a stop before a checkpoint is not counted).
    pub train_secs: f64,
}
