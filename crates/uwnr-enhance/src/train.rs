//! Training of Shallow-UWnet on paired folders, underwater image in, clean image out, with the
//! loss `w_mse * MSE(out, clean) + w_perceptual * P(out, clean)`.
//!
//! The released recipe (mkartik/Shallow-UWnet `training.py` and `combined_loss.py`): Adam at
//! lr 2e-4 with PyTorch's defaults (betas 0.9/0.999, eps 1e-8), `P` = L1 between `vgg19_bn`
//! features, every image resized to 256x256, batch 1, and the lr multiplied by 0.7 every
//! `step_size` epochs. Here, as in UWNR training:
//! - random `crop x crop` windows (default 256; smaller images reflect-padded), a horizontal
//!   flip and a quarter turn, instead of squashing every image to a square;
//! - batch 4 by default;
//! - `P` = the VGG19 perceptual loss of [`uwnr_train::vgg`] (torchvision `vgg19`, not `_bn`,
//!   cut at UWNR's layers) when VGG19 weights are given, otherwise the documented stand-in
//!   `1 - SSIM` ([`uwnr_train::losses::ssim_loss`]), announced with a warning.
//!
//! The machinery is uwnr-train's: seeded initialisation ([`uwnr_train::init_seeded`]), data
//! order and sample plans as pure functions of `(seed, epoch, position)`, atomic checkpoints of
//! model + optimiser + [`RunState`], and CSV logs trimmed on resume, so a resumed run continues
//! exactly where it stopped. The channel-dropout masks of step `s` come from a generator seeded
//! by `(seed, s)`.
//!
//! Run folder layout:
//! ```text
//! config.json          the EnhanceTrainConfig of the run
//! data-report.txt      pairs used, files skipped, images padded or resized
//! metrics.csv          step, epoch, lr, mse, perceptual, total, secs_per_step
//! val.csv              step, epoch, PSNR, SSIM on the validation pairs
//! curves.png           loss terms (log) and validation PSNR against the step
//! checkpoints/last/    model + optimiser + state, and enhancer.safetensors
//! checkpoints/best/    the network with the best validation PSNR (enhancer.safetensors)
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use uwnr_core::io::DecodeLimits;
use uwnr_model::weights::SOURCE_METADATA_KEY;
use uwnr_train::TrainError;
use uwnr_train::augment::{epoch_order, mix64};
use uwnr_train::checkpoint::{
    BEST, CHECKPOINTS_DIR, LAST, RunState, check_run_folder, find_checkpoint,
    load_module_checkpoint, save_module_checkpoint,
};
use uwnr_train::csvlog::{CsvLog, VAL_HEADER};
use uwnr_train::losses::{Perceptual, ssim_loss};
use uwnr_train::plot::{LossSeries, TOTAL_COLOUR, draw_loss_curves, series_colour};
use uwnr_train::trainer::claim_run_folder;
pub use uwnr_train::trainer::{CONFIG_FILE, CURVES_FILE, DATA_REPORT_FILE, METRICS_FILE, VAL_FILE};
use uwnr_train::{Vgg19Features, init_seeded};

use crate::data::{self, TrainPair, ValPair};
use crate::error::{EnhanceError, Result};
use crate::model::{Dropout, IMAGE_CHANNELS, ShallowUwnet, ShallowUwnetConfig};

/// The network's weights inside each checkpoint folder (what `weights::load` and
/// `uwnr enhance apply --weights` take).
pub const ENHANCER_FILE: &str = "enhancer.safetensors";
/// Header of `metrics.csv`.
pub const METRICS_HEADER: &str = "step,epoch,lr,mse,perceptual,total,secs_per_step";
/// Learning rate of the released training script (`--lr 0.0002`).
pub const RELEASED_LR: f64 = 2e-4;
/// Factor applied to the learning rate every `step_size` epochs in the released script.
pub const RELEASED_LR_DECAY: f64 = 0.7;
/// Epochs between learning-rate decays: the value noted beside the released default (`#50`;
/// the default itself, 400, never decays within its 10 default epochs).
pub const DEFAULT_LR_STEP_EPOCHS: usize = 50;
/// Adam `(beta_1, beta_2)`: PyTorch's defaults, which the released script keeps.
pub const ADAM_BETAS: (f32, f32) = (0.9, 0.999);
/// Adam epsilon: PyTorch's default (burn's default is 1e-5).
pub const TORCH_ADAM_EPS: f32 = 1e-8;
/// Smallest crop: the 11x11 SSIM window of the stand-in loss must fit, with room to spare for
/// the two 2x2 poolings of the VGG19 cut points.
pub const MIN_CROP: usize = 16;
/// Stream tag of the per-step dropout masks ("dropout").
const STREAM_DROPOUT: u64 = 0x0064_726f_706f_7574;

/// A run's configuration. `Default` is the released recipe with this crate's crops and batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EnhanceTrainConfig {
    /// The network.
    pub model: ShallowUwnetConfig,
    /// Passes over the training pairs.
    pub epochs: usize,
    /// Samples per optimisation step.
    pub batch_size: usize,
    /// Side of the square random crops.
    pub crop: usize,
    /// Adam learning rate of the first epochs.
    pub lr: f64,
    /// Factor applied to the learning rate every `lr_step_epochs` epochs.
    pub lr_decay: f64,
    /// Epochs between decays (0 = constant learning rate).
    pub lr_step_epochs: usize,
    /// Weight of the MSE term.
    pub w_mse: f64,
    /// Weight of the perceptual term (VGG19, or its 1 - SSIM stand-in).
    pub w_perceptual: f64,
    /// Seed of the initial weights, the data order, the crops and the dropout masks.
    pub seed: u64,
    /// Validate every this many epochs (0 = never); the last epoch is always validated.
    pub val_every_epochs: usize,
    /// Write a row of `metrics.csv` every this many steps (the mean over them).
    pub log_every_steps: usize,
    /// Write the `last` checkpoint when this many seconds have passed since the previous one
    /// (0 = only at epoch ends and when the session ends).
    pub checkpoint_every_secs: u64,
    /// Use at most this many pairs of each data folder (the first in name order).
    pub max_pairs_per_dir: Option<usize>,
    /// End the run after this many steps in total, its last epoch then partial (at most
    /// `epochs` whole epochs either way): how runs on sets of different sizes get the same budget.
    pub total_steps: Option<usize>,
}

impl Default for EnhanceTrainConfig {
    fn default() -> Self {
        Self {
            model: ShallowUwnetConfig::default(),
            epochs: 100,
            batch_size: 4,
            crop: 256,
            lr: RELEASED_LR,
            lr_decay: RELEASED_LR_DECAY,
            lr_step_epochs: DEFAULT_LR_STEP_EPOCHS,
            w_mse: 1.0,
            w_perceptual: 1.0,
            seed: 7,
            val_every_epochs: 5,
            log_every_steps: 10,
            checkpoint_every_secs: 900,
            max_pairs_per_dir: None,
            total_steps: None,
        }
    }
}

impl EnhanceTrainConfig {
    /// Checks every field that could make a run fail late; errors name the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &'static str, reason: String| {
            Err(EnhanceError::InvalidTrainConfig { field, reason })
        };
        if let Err(e) = self.model.validate() {
            return bad("model", e.to_string());
        }
        if self.epochs == 0 {
            return bad("epochs", "must be at least 1".into());
        }
        if self.batch_size == 0 {
            return bad("batch_size", "must be at least 1".into());
        }
        if self.crop < MIN_CROP {
            return bad("crop", format!("{} must be at least {MIN_CROP}", self.crop));
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad("lr", format!("{} must be positive", self.lr));
        }
        if !(self.lr_decay.is_finite() && self.lr_decay > 0.0 && self.lr_decay <= 1.0) {
            return bad("lr_decay", format!("{} must be in (0, 1]", self.lr_decay));
        }
        for (field, w) in [("w_mse", self.w_mse), ("w_perceptual", self.w_perceptual)] {
            if !(w.is_finite() && w >= 0.0) {
                return bad(field, format!("{w} must be finite and >= 0"));
            }
        }
        if self.w_mse + self.w_perceptual <= 0.0 {
            return bad("w_mse", "w_mse and w_perceptual cannot both be 0".into());
        }
        if self.log_every_steps == 0 {
            return bad("log_every_steps", "must be at least 1".into());
        }
        if self.max_pairs_per_dir == Some(0) {
            return bad("max_pairs_per_dir", "must be at least 1 when given".into());
        }
        if self.total_steps == Some(0) {
            return bad("total_steps", "must be at least 1 when given".into());
        }
        Ok(())
    }

    /// Learning rate of epoch `epoch` (0-based): `lr * lr_decay^floor(epoch / lr_step_epochs)`,
    /// PyTorch's `StepLR`. The released loop (`if epoch > 1 and epoch % step_size == 0`) gives
    /// the same for `step_size >= 2`.
    #[must_use]
    pub fn lr_at(&self, epoch: usize) -> f64 {
        let decays = epoch.checked_div(self.lr_step_epochs).unwrap_or(0);
        self.lr
            * self
                .lr_decay
                .powi(i32::try_from(decays).unwrap_or(i32::MAX))
    }

    /// Reads a config from JSON. Fields not given keep their defaults; unknown fields are an
    /// error.
    pub fn from_json_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| TrainError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| EnhanceError::ConfigFile {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// Pretty JSON of the config.
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self).map_err(|e| EnhanceError::InvalidTrainConfig {
            field: "config",
            reason: e.to_string(),
        })
    }
}

/// Where and how to train (what is not part of the run's config).
#[derive(Clone, Debug)]
pub struct EnhanceTrainOptions {
    /// Training folders (`underwater/` + `clean/`, or `raw-890/` + `reference-890/`).
    pub data: Vec<PathBuf>,
    /// Validation folder (same layouts), scored at native resolution.
    pub val: Option<PathBuf>,
    /// The run folder.
    pub run_dir: PathBuf,
    /// Continue the run in `run_dir` from its last checkpoint.
    pub resume: bool,
    /// VGG19 weights (safetensors, torchvision keys) for the perceptual term.
    pub vgg19: Option<PathBuf>,
    /// Compute device (without autodiff; training enables it).
    pub device: Device,
    /// Stop (with a checkpoint) after this many steps in this session.
    pub max_steps: Option<usize>,
    /// Image decoding limits.
    pub limits: DecodeLimits,
}

impl EnhanceTrainOptions {
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
            limits: DecodeLimits::default(),
        }
    }
}

/// What the loop reports as it goes.
#[derive(Debug)]
pub enum EnhanceEvent<'a> {
    /// Something worth telling the user (the data report, warnings).
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
        /// Unweighted MSE.
        mse: f64,
        /// Unweighted perceptual term (0 when its weight is 0).
        perceptual: f64,
        /// The weighted loss that was minimised.
        total: f64,
    },
    /// A validation finished.
    Validation {
        /// Steps done.
        step: usize,
        /// Epochs done.
        epoch: usize,
        /// Mean PSNR (dB) of the enhanced validation images against their clean partners.
        psnr: f64,
        /// Mean SSIM.
        ssim: f64,
    },
    /// The `last` checkpoint was written.
    Checkpoint {
        /// Steps done.
        step: usize,
        /// Its folder.
        path: &'a Path,
    },
}

/// How a session ended.
#[derive(Clone, Debug, PartialEq)]
pub struct EnhanceTrainSummary {
    /// Steps done in total.
    pub step: usize,
    /// Steps done in this session.
    pub session_steps: usize,
    /// The run reached its last epoch.
    pub finished: bool,
    /// The stop flag ended the session.
    pub interrupted: bool,
    /// Best validation PSNR and its step.
    pub best: Option<(f64, usize)>,
    /// `enhancer.safetensors` of the `last` checkpoint.
    pub last_weights: PathBuf,
    /// `enhancer.safetensors` of the `best` checkpoint, once there is one.
    pub best_weights: Option<PathBuf>,
    /// Seconds of training behind the `last` checkpoint, summed over the sessions that made it
    /// (work lost to a stop before a checkpoint is not counted).
    pub train_secs: f64,
}

/// Loss values of one step (or their mean over a log window).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct StepLoss {
    mse: f64,
    perceptual: f64,
    total: f64,
}

impl StepLoss {
    fn is_finite(&self) -> bool {
        self.mse.is_finite() && self.perceptual.is_finite() && self.total.is_finite()
    }
}

/// Trains (or resumes) the run of `opts.run_dir` with `cfg`. `stop` ends the session cleanly
/// (checkpoint written) at the next step boundary; `observer` receives progress events.
pub fn train(
    cfg: &EnhanceTrainConfig,
    opts: &EnhanceTrainOptions,
    stop: &AtomicBool,
    observer: &mut dyn FnMut(EnhanceEvent<'_>),
) -> Result<EnhanceTrainSummary> {
    cfg.validate()?;
    let run = &opts.run_dir;
    check_run_folder(run, opts.resume)?;
    if opts.resume {
        check_saved_config(cfg, run)?;
    }

    let data = data::load(
        &opts.data,
        opts.val.as_deref(),
        cfg.crop,
        cfg.max_pairs_per_dir,
        &opts.limits,
    )?;
    let data::Data { pairs, val, report } = data;
    // Shown before anything is checked, so a refused start still lists what was skipped.
    let report = report.to_text();
    observer(EnhanceEvent::Message(report.trim_end()));
    let steps_per_epoch = pairs.len() / cfg.batch_size;
    if steps_per_epoch == 0 {
        return Err(TrainError::NoData(format!(
            "{} training pairs, fewer than one batch of {}",
            pairs.len(),
            cfg.batch_size
        ))
        .into());
    }
    // The data has loaded: only now is the folder claimed.
    if !opts.resume {
        claim_run_folder(run, &cfg.to_json()?)?;
    }
    write_file(&run.join(DATA_REPORT_FILE), &report)?;
    let total_steps = cfg.total_steps.map_or(cfg.epochs * steps_per_epoch, |t| {
        t.min(cfg.epochs * steps_per_epoch)
    });

    let device = opts.device.clone().autodiff();
    let adam = AdamConfig::new()
        .with_beta_1(ADAM_BETAS.0)
        .with_beta_2(ADAM_BETAS.1)
        .with_epsilon(TORCH_ADAM_EPS);
    let ck_last = run.join(CHECKPOINTS_DIR).join(LAST);
    let ck_best = run.join(CHECKPOINTS_DIR).join(BEST);
    let (mut model, mut optim, mut state) = if opts.resume {
        let dir = find_checkpoint(&ck_last).ok_or_else(|| TrainError::Checkpoint {
            path: ck_last.clone(),
            reason: "no checkpoint to resume from".into(),
        })?;
        let (m, o, s) = load_module_checkpoint(&dir, cfg.model.init(&device)?, adam.init())?;
        s.check_resumable(&dir, steps_per_epoch, pairs.len(), cfg.seed)?;
        observer(EnhanceEvent::Message(&format!(
            "resuming at step {} (epoch {}, batch {})",
            s.step, s.epoch, s.batch_in_epoch
        )));
        (m, o, s)
    } else {
        let m = init_seeded(cfg.seed, &device, || cfg.model.init(&device))?;
        let s = RunState::start(steps_per_epoch, pairs.len(), cfg.seed);
        (m, adam.init(), s)
    };
    let keep = opts.resume.then_some(state.step);
    let metrics = CsvLog::open(&run.join(METRICS_FILE), METRICS_HEADER, keep)?;
    let val_log = CsvLog::open(&run.join(VAL_FILE), VAL_HEADER, keep)?;

    let perceptual = match &opts.vgg19 {
        Some(p) => Perceptual::Vgg(Box::new(Vgg19Features::load(p, &device)?)),
        None if cfg.w_perceptual > 0.0 => {
            observer(EnhanceEvent::Message(
                "warning: no --vgg19 weights: the perceptual term is replaced by its stand-in, 1 - SSIM",
            ));
            Perceptual::Ssim
        }
        None => Perceptual::Off,
    };
    observer(EnhanceEvent::Message(&format!(
        "perceptual term: {}",
        perceptual.describe()
    )));
    observer(EnhanceEvent::Started {
        step: state.step,
        total_steps,
        steps_per_epoch,
    });

    let ctx = Ctx {
        cfg,
        run,
        ck_best: &ck_best,
        val: &val,
        inner: &opts.device,
        metrics: &metrics,
        val_log: &val_log,
        perceptual_name: match perceptual {
            Perceptual::Vgg(_) => "perceptual (VGG19)",
            Perceptual::Ssim => "perceptual (1 - SSIM)",
            Perceptual::Off => "perceptual (off)",
        },
    };
    let mut summary = EnhanceTrainSummary {
        step: state.step,
        session_steps: 0,
        finished: false,
        interrupted: false,
        best: state.best,
        last_weights: ck_last.join(ENHANCER_FILE),
        best_weights: None,
        train_secs: state.train_secs,
    };
    let mut window = LogWindow::default();
    let mut last_ck = Instant::now();
    let session_clock = Instant::now();
    let base_secs = state.train_secs;
    let mut order: Option<(usize, Vec<usize>)> = None;
    // Step of the last checkpoint written in this session.
    let mut saved_at: Option<usize> = None;

    while state.step < total_steps {
        if stop.load(Ordering::Relaxed) {
            summary.interrupted = true;
            break;
        }
        if opts.max_steps.is_some_and(|m| summary.session_steps >= m) {
            break;
        }
        let t0 = Instant::now();
        if order.as_ref().is_none_or(|(e, _)| *e != state.epoch) {
            order = Some((state.epoch, epoch_order(cfg.seed, state.epoch, pairs.len())));
        }
        let epoch_order = order.as_ref().map(|o| o.1.as_slice()).unwrap_or_default();
        let lr = cfg.lr_at(state.epoch);
        let (next, loss) = train_step(
            model,
            &mut optim,
            cfg,
            &perceptual,
            &pairs,
            epoch_order,
            &state,
            lr,
            &device,
        )?;
        model = next;
        if !loss.is_finite() {
            return Err(EnhanceError::NonFiniteLoss {
                step: state.step,
                mse: loss.mse,
                perceptual: loss.perceptual,
                total: loss.total,
            });
        }
        let epoch_of_step = state.epoch;
        state.step += 1;
        state.batch_in_epoch += 1;
        summary.session_steps += 1;
        summary.step = state.step;
        window.add(&loss, t0.elapsed().as_secs_f64());
        observer(EnhanceEvent::Step {
            step: state.step,
            epoch: epoch_of_step,
            lr,
            mse: loss.mse,
            perceptual: loss.perceptual,
            total: loss.total,
        });
        if state.step.is_multiple_of(cfg.log_every_steps) || state.step == total_steps {
            window.flush(&metrics, state.step, epoch_of_step, lr)?;
        }
        let mut want_ck = cfg.checkpoint_every_secs > 0
            && last_ck.elapsed().as_secs() >= cfg.checkpoint_every_secs;
        if state.batch_in_epoch == steps_per_epoch {
            state.epoch += 1;
            state.batch_in_epoch = 0;
            want_ck = true;
            let due = cfg.val_every_epochs > 0
                && (state.epoch.is_multiple_of(cfg.val_every_epochs) || state.epoch == cfg.epochs);
            if due && !val.is_empty() {
                ctx.validate(&model, &mut state, observer)?;
                summary.best = state.best;
            }
        }
        if want_ck {
            state.train_secs = base_secs + session_clock.elapsed().as_secs_f64();
            save_last(&ck_last, &model, &optim, cfg, &state)?;
            saved_at = Some(state.step);
            observer(EnhanceEvent::Checkpoint {
                step: state.step,
                path: &ck_last,
            });
            ctx.curves()?;
            last_ck = Instant::now();
        }
    }
    summary.finished = state.step >= total_steps;
    // The epoch and learning rate of the last step done.
    let last_epoch = if state.batch_in_epoch == 0 {
        state.epoch.saturating_sub(1)
    } else {
        state.epoch
    };
    window.flush(&metrics, state.step, last_epoch, cfg.lr_at(last_epoch))?;
    if (summary.session_steps > 0 || !opts.resume) && saved_at != Some(state.step) {
        state.train_secs = base_secs + session_clock.elapsed().as_secs_f64();
        save_last(&ck_last, &model, &optim, cfg, &state)?;
        observer(EnhanceEvent::Checkpoint {
            step: state.step,
            path: &ck_last,
        });
    }
    ctx.curves()?;
    summary.best = state.best;
    let best = ck_best.join(ENHANCER_FILE);
    summary.best_weights = best.is_file().then_some(best);
    summary.train_secs = state.train_secs;
    Ok(summary)
}

/// One optimisation step on the batch the state points at: forward with seeded channel
/// dropout, the weighted loss, backward, an Adam update at `lr`.
#[allow(clippy::too_many_arguments)]
fn train_step(
    model: ShallowUwnet,
    optim: &mut ModuleOptimizer,
    cfg: &EnhanceTrainConfig,
    perceptual: &Perceptual,
    pairs: &[TrainPair],
    order: &[usize],
    state: &RunState,
    lr: f64,
    device: &Device,
) -> Result<(ShallowUwnet, StepLoss)> {
    let (b, c) = (cfg.batch_size, cfg.crop);
    let (x, y) = data::batch(
        pairs,
        order,
        cfg.seed,
        state.epoch,
        state.batch_in_epoch * b,
        b,
        c,
    );
    let x = Tensor::<4>::from_data(TensorData::new(x, [b, IMAGE_CHANNELS, c, c]), device);
    let y = Tensor::<4>::from_data(TensorData::new(y, [b, IMAGE_CHANNELS, c, c]), device);
    let mut rng =
        ChaCha8Rng::seed_from_u64(mix64(mix64(cfg.seed ^ STREAM_DROPOUT) ^ state.step as u64));
    let mut dropout = Dropout {
        p: cfg.model.dropout,
        rng: &mut rng,
    };
    let out = model.forward_train(x, &mut dropout); // [b, 3, c, c]
    let mse = (out.clone() - y.clone()).powi_scalar(2).mean();
    let per = match (perceptual, cfg.w_perceptual > 0.0) {
        (Perceptual::Vgg(v), true) => v.perceptual_loss(out, y),
        (Perceptual::Ssim, true) => ssim_loss(out, y),
        _ => Tensor::<1>::zeros([1], device),
    };
    let total = mse.clone() * cfg.w_mse + per.clone() * cfg.w_perceptual;
    let terms = Tensor::cat(vec![mse.detach(), per.detach(), total.clone().detach()], 0); // [3]
    let grads = GradientsParams::from_grads(total.backward(), &model);
    let model = optim.step(lr, model, grads);
    let v = terms
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| uwnr_model::ModelError::Backend(format!("reading loss values: {e:?}")))?;
    let g = |i: usize| v.get(i).copied().map_or(f64::NAN, f64::from);
    Ok((
        model,
        StepLoss {
            mse: g(0),
            perceptual: g(1),
            total: g(2),
        },
    ))
}

/// Writes the `last` checkpoint: model, optimiser, state and `enhancer.safetensors`.
fn save_last(
    dir: &Path,
    model: &ShallowUwnet,
    optim: &ModuleOptimizer,
    cfg: &EnhanceTrainConfig,
    state: &RunState,
) -> Result<()> {
    let export = model.valid();
    save_module_checkpoint(dir, model, Some(optim), state, &|tmp: &Path| {
        export_weights(&export, &cfg.model, tmp, state)
    })?;
    Ok(())
}

/// Writes `enhancer.safetensors` into the checkpoint folder being assembled.
fn export_weights(
    net: &ShallowUwnet,
    config: &ShallowUwnetConfig,
    tmp: &Path,
    state: &RunState,
) -> uwnr_train::Result<()> {
    let path = tmp.join(ENHANCER_FILE);
    let mut meta = BTreeMap::new();
    meta.insert(
        SOURCE_METADATA_KEY.to_string(),
        format!(
            "uwnr enhance train, step {}, epoch {}",
            state.step, state.epoch
        ),
    );
    crate::weights::save(net, config, &path, &meta).map_err(|e| TrainError::Checkpoint {
        path,
        reason: format!("writing the enhancer weights: {e}"),
    })
}

/// Everything validation and plotting need.
struct Ctx<'a> {
    cfg: &'a EnhanceTrainConfig,
    run: &'a Path,
    ck_best: &'a Path,
    val: &'a [ValPair],
    inner: &'a Device,
    metrics: &'a CsvLog,
    val_log: &'a CsvLog,
    perceptual_name: &'static str,
}

impl Ctx<'_> {
    /// Scores the network on the validation pairs at their native size (outputs rounded to
    /// 8 bits, as saved files would be), logs the means, and writes the `best` checkpoint when
    /// the PSNR improves.
    fn validate(
        &self,
        model: &ShallowUwnet,
        state: &mut RunState,
        observer: &mut dyn FnMut(EnhanceEvent<'_>),
    ) -> Result<()> {
        let t0 = Instant::now();
        let net = model.valid();
        let (mut psnr, mut ssim) = (0.0, 0.0);
        for v in self.val {
            let out = data::quantised(&crate::infer::enhance(&net, &v.input, self.inner)?)?;
            let score = |e: uwnr_metrics::MetricsError| EnhanceError::BadPair {
                path: PathBuf::from(&v.name),
                reason: format!("scoring the validation output: {e}"),
            };
            psnr += uwnr_metrics::psnr(&out, &v.target, uwnr_metrics::DEFAULT_DATA_RANGE)
                .map_err(score)?;
            ssim += uwnr_metrics::ssim(&out, &v.target, uwnr_metrics::DEFAULT_DATA_RANGE)
                .map_err(score)?;
        }
        let n = self.val.len().max(1) as f64;
        let (psnr, ssim) = (psnr / n, ssim / n);
        self.val_log.append(&[
            state.step.to_string(),
            state.epoch.to_string(),
            format!("{psnr:.4}"),
            format!("{ssim:.5}"),
            format!("{:.1}", t0.elapsed().as_secs_f64()),
        ])?;
        observer(EnhanceEvent::Validation {
            step: state.step,
            epoch: state.epoch,
            psnr,
            ssim,
        });
        if state.best.is_none_or(|(b, _)| psnr > b) {
            state.best = Some((psnr, state.step));
            let snapshot = state.clone();
            save_module_checkpoint(self.ck_best, &net, None, &snapshot, &|tmp: &Path| {
                export_weights(&net, &self.cfg.model, tmp, &snapshot)
            })?;
        }
        Ok(())
    }

    /// Redraws `curves.png` from the logs.
    fn curves(&self) -> Result<()> {
        let rows: Vec<Vec<f64>> = self
            .metrics
            .rows()?
            .into_iter()
            .filter(|r| r.len() >= 6)
            .collect();
        let column = |i: usize| -> Vec<(usize, f64)> {
            rows.iter().map(|r| (r[0] as usize, r[i])).collect()
        };
        let series = vec![
            LossSeries {
                name: "MSE".into(),
                colour: series_colour(0),
                points: column(3),
            },
            LossSeries {
                name: self.perceptual_name.into(),
                colour: series_colour(1),
                points: column(4),
            },
            LossSeries {
                name: "total".into(),
                colour: TOTAL_COLOUR,
                points: column(5),
            },
        ];
        let val: Vec<(usize, f64)> = self
            .val_log
            .rows()?
            .into_iter()
            .filter(|r| r.len() >= 3)
            .map(|r| (r[0] as usize, r[2]))
            .collect();
        draw_loss_curves(&self.run.join(CURVES_FILE), &series, &val, &[])?;
        Ok(())
    }
}

/// Mean of the losses since the last `metrics.csv` row.
#[derive(Default)]
struct LogWindow {
    sum: StepLoss,
    secs: f64,
    n: usize,
}

impl LogWindow {
    fn add(&mut self, v: &StepLoss, secs: f64) {
        self.sum.mse += v.mse;
        self.sum.perceptual += v.perceptual;
        self.sum.total += v.total;
        self.secs += secs;
        self.n += 1;
    }

    fn flush(&mut self, log: &CsvLog, step: usize, epoch: usize, lr: f64) -> Result<()> {
        if self.n == 0 {
            return Ok(());
        }
        let k = 1.0 / self.n as f64;
        let s = self.sum;
        log.append(&[
            step.to_string(),
            epoch.to_string(),
            format!("{lr:.6e}"),
            format!("{:.6}", s.mse * k),
            format!("{:.6}", s.perceptual * k),
            format!("{:.6}", s.total * k),
            format!("{:.3}", self.secs * k),
        ])?;
        *self = Self::default();
        Ok(())
    }
}

/// On resume, the run's `config.json` must equal `cfg`; the error names the changed fields.
fn check_saved_config(cfg: &EnhanceTrainConfig, run: &Path) -> Result<()> {
    let cfg_path = run.join(CONFIG_FILE);
    let saved = EnhanceTrainConfig::from_json_file(&cfg_path)?;
    if &saved != cfg {
        return Err(EnhanceError::ConfigChanged {
            fields: changed_fields(&saved, cfg),
            path: cfg_path,
        });
    }
    Ok(())
}

/// The dotted names of the fields that differ between two configs (e.g. `model.width`).
fn changed_fields(a: &EnhanceTrainConfig, b: &EnhanceTrainConfig) -> Vec<String> {
    fn walk(prefix: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
        match (a, b) {
            (serde_json::Value::Object(x), serde_json::Value::Object(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                for k in keys {
                    let name = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    let null = serde_json::Value::Null;
                    walk(
                        &name,
                        x.get(k).unwrap_or(&null),
                        y.get(k).unwrap_or(&null),
                        out,
                    );
                }
            }
            _ if a != b => out.push(prefix.to_string()),
            _ => {}
        }
    }
    let mut out = Vec::new();
    match (serde_json::to_value(a), serde_json::to_value(b)) {
        (Ok(x), Ok(y)) => walk("", &x, &y, &mut out),
        _ => out.push("config".into()),
    }
    if out.is_empty() {
        out.push("config".into());
    }
    out
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    uwnr_core::io::write_atomic(path, |out| out.write_all(text.as_bytes()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_the_released_recipe_with_crops() {
        let c = EnhanceTrainConfig::default();
        c.validate().unwrap();
        assert_eq!(c.model, ShallowUwnetConfig::default());
        assert_eq!((c.lr, c.lr_decay), (2e-4, 0.7));
        assert_eq!((c.batch_size, c.crop), (4, 256));
        assert_eq!((c.w_mse, c.w_perceptual), (1.0, 1.0));
    }

    #[test]
    fn lr_decays_by_steps_of_epochs() {
        let c = EnhanceTrainConfig {
            lr: 1.0,
            lr_decay: 0.5,
            lr_step_epochs: 3,
            ..EnhanceTrainConfig::default()
        };
        let got: Vec<f64> = (0..8).map(|e| c.lr_at(e)).collect();
        assert_eq!(got, [1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.25, 0.25]);
        let constant = EnhanceTrainConfig {
            lr_step_epochs: 0,
            ..c
        };
        assert_eq!(constant.lr_at(1000), 1.0);
        // The released default: x0.7 at epochs 50, 100, ...
        let d = EnhanceTrainConfig::default();
        assert_eq!(d.lr_at(49), 2e-4);
        assert!((d.lr_at(50) - 1.4e-4).abs() < 1e-15);
        assert!((d.lr_at(100) - 0.98e-4).abs() < 1e-15);
    }

    #[test]
    fn json_round_trip_partial_files_and_unknown_fields() {
        let c = EnhanceTrainConfig {
            model: ShallowUwnetConfig {
                width: 8,
                ..ShallowUwnetConfig::default()
            },
            max_pairs_per_dir: Some(3),
            ..EnhanceTrainConfig::default()
        };
        let back: EnhanceTrainConfig = serde_json::from_str(&c.to_json().unwrap()).unwrap();
        assert_eq!(back, c);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.json");
        std::fs::write(&path, r#"{"epochs": 3, "model": {"width": 16}}"#).unwrap();
        let partial = EnhanceTrainConfig::from_json_file(&path).unwrap();
        assert_eq!((partial.epochs, partial.model.width), (3, 16));
        assert_eq!(partial.model.blocks, 3);
        assert_eq!(partial.batch_size, 4);
        for bad in [r#"{"epoch": 3}"#, r#"{"model": {"widht": 8}}"#, "[1]"] {
            std::fs::write(&path, bad).unwrap();
            let err = EnhanceTrainConfig::from_json_file(&path).unwrap_err();
            assert!(
                matches!(err, EnhanceError::ConfigFile { .. }),
                "{bad}: {err}"
            );
        }
    }

    #[test]
    fn invalid_fields_are_named() {
        let d = EnhanceTrainConfig::default;
        for (c, field) in [
            (EnhanceTrainConfig { epochs: 0, ..d() }, "epochs"),
            (
                EnhanceTrainConfig {
                    batch_size: 0,
                    ..d()
                },
                "batch_size",
            ),
            (EnhanceTrainConfig { crop: 8, ..d() }, "crop"),
            (EnhanceTrainConfig { lr: -1.0, ..d() }, "lr"),
            (
                EnhanceTrainConfig {
                    lr_decay: 1.5,
                    ..d()
                },
                "lr_decay",
            ),
            (
                EnhanceTrainConfig {
                    w_perceptual: f64::NAN,
                    ..d()
                },
                "w_perceptual",
            ),
            (
                EnhanceTrainConfig {
                    w_mse: 0.0,
                    w_perceptual: 0.0,
                    ..d()
                },
                "w_mse",
            ),
            (
                EnhanceTrainConfig {
                    log_every_steps: 0,
                    ..d()
                },
                "log_every_steps",
            ),
            (
                EnhanceTrainConfig {
                    max_pairs_per_dir: Some(0),
                    ..d()
                },
                "max_pairs_per_dir",
            ),
            (
                EnhanceTrainConfig {
                    model: ShallowUwnetConfig {
                        width: 3,
                        ..ShallowUwnetConfig::default()
                    },
                    ..d()
                },
                "model",
            ),
        ] {
            match c.validate() {
                Err(EnhanceError::InvalidTrainConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("expected InvalidTrainConfig for {field}, got {other:?}"),
            }
        }
    }

    #[test]
    fn changed_fields_are_named_with_their_path() {
        let a = EnhanceTrainConfig::default();
        let b = EnhanceTrainConfig {
            epochs: 3,
            model: ShallowUwnetConfig {
                width: 8,
                ..ShallowUwnetConfig::default()
            },
            ..EnhanceTrainConfig::default()
        };
        assert_eq!(changed_fields(&a, &b), ["epochs", "model.width"]);
    }
}
