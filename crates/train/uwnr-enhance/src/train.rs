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
//! Training is a [`uwnr_run::Task`]: the loop, the prefetching batch thread, the seeded data
//! order and sample plans, atomic checkpoints of model + optimiser + [`RunState`] with
//! `enhancer.safetensors` in each, CSV logs trimmed on resume, curves and validation contact
//! sheets (underwater | enhanced | clean) are uwnr-run's, so a resumed run continues exactly
//! where it stopped. The channel-dropout masks of step `s` come from a generator seeded by
//! `(seed, s)`. The run folder's layout is described in [`uwnr_run::folder`]; `metrics.csv`
//! holds `mse, perceptual, total`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Deserializer, Serialize};
use uwnr_model::weights::SOURCE_METADATA_KEY;
/// Where and how to train (what is not part of the run's config).
pub use uwnr_run::TrainOptions as EnhanceTrainOptions;
use uwnr_run::checkpoint::{BEST, CHECKPOINTS_DIR, LAST, RunState};
use uwnr_run::folder::{check_run_folder, check_saved_config};
use uwnr_run::plan::mix64;
use uwnr_run::{Event, Prepared, RunSettings, Schedule, Scores, Task};
use uwnr_train::Vgg19Features;
use uwnr_train::losses::{Perceptual, ssim_loss};

use crate::data::{self, Batch, Batches, ValPair};
use crate::error::{EnhanceError, Result};
use crate::model::{Dropout, IMAGE_CHANNELS, ShallowUwnet, ShallowUwnetConfig};

/// The network's weights inside each checkpoint folder (what `weights::load` and
/// `uwnr enhance apply --weights` take).
pub const ENHANCER_FILE: &str = "enhancer.safetensors";
/// `metrics.csv` columns of the loss terms and their legend names in `curves.png` (the
/// perceptual term's legend says what stood for it).
const LOSS_COLUMNS: [&str; 3] = ["mse", "perceptual", "total"];
/// Column headers of a validation contact sheet.
const SHEET_COLUMNS: [&str; 3] = ["underwater", "enhanced", "clean"];
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
    /// Seed (of the initial weights, the data order, the crops and the dropout masks), logging,
    /// validation, checkpoint and prefetch cadence; their keys sit at the top level of the
    /// JSON.
    #[serde(flatten, deserialize_with = "run_settings")]
    pub run: RunSettings,
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
            run: RunSettings::defaults(7, 5),
            max_pairs_per_dir: None,
            total_steps: None,
        }
    }
}

/// The run settings of a config file, over Shallow-UWnet's defaults.
fn run_settings<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<RunSettings, D::Error> {
    RunSettings::deserialize_over(EnhanceTrainConfig::default().run, d)
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
        self.run.validate()?;
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
        let text = std::fs::read_to_string(path).map_err(|source| uwnr_run::RunError::Io {
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

/// How a session ended.
#[derive(Clone, Debug, PartialEq)]
pub struct EnhanceTrainSummary {
    /// Steps done in total.
    pub step: usize,
    /// Steps done in this session.
    pub session_steps: usize,
    /// The run reached its last step.
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

/// Trains (or resumes) the run of `opts.run_dir` with `cfg`. `stop` ends the session cleanly
/// (checkpoint written) at the next step boundary; `observer` receives progress events (the
/// loss terms of a step are `mse, perceptual, total`).
pub fn train(
    cfg: &EnhanceTrainConfig,
    opts: &EnhanceTrainOptions,
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<EnhanceTrainSummary> {
    cfg.validate()?;
    let run = &opts.run_dir;
    check_run_folder(run, opts.resume)?;
    if opts.resume {
        check_saved_config(cfg, run)?;
    }
    let data::Data { pairs, val, report } = data::load(
        &opts.data,
        opts.val.as_deref(),
        cfg.crop,
        cfg.max_pairs_per_dir,
        &opts.limits,
    )?;
    let prepared = Prepared {
        config_json: cfg.to_json()?,
        pairs: pairs.len(),
        report: report.to_text(),
    };
    let device = opts.device.clone().autodiff();
    let perceptual = match &opts.vgg19 {
        Some(p) => Perceptual::Vgg(Box::new(Vgg19Features::load(p, &device)?)),
        None if cfg.w_perceptual > 0.0 => {
            observer(Event::Message(
                "warning: no --vgg19 weights: the perceptual term is replaced by its stand-in, 1 - SSIM",
            ));
            Perceptual::Ssim
        }
        None => Perceptual::Off,
    };
    observer(Event::Message(&format!(
        "perceptual term: {}",
        perceptual.describe()
    )));
    let source = Arc::new(Batches {
        pairs: Arc::new(pairs),
        seed: cfg.run.seed,
        batch_size: cfg.batch_size,
        crop: cfg.crop,
    });
    let task = EnhanceTask {
        cfg,
        device,
        inner: opts.device.clone(),
        perceptual,
        val,
    };
    let schedule = Schedule::new(&cfg.run, cfg.epochs, cfg.batch_size, cfg.total_steps);
    let session = opts.session();
    let s = uwnr_run::train(
        &task, source, &prepared, &schedule, &session, stop, observer,
    )?;
    let best = run.join(CHECKPOINTS_DIR).join(BEST).join(ENHANCER_FILE);
    Ok(EnhanceTrainSummary {
        step: s.step,
        session_steps: s.session_steps,
        finished: s.finished,
        interrupted: s.interrupted,
        best: s.best,
        last_weights: run.join(CHECKPOINTS_DIR).join(LAST).join(ENHANCER_FILE),
        best_weights: best.is_file().then_some(best),
        train_secs: s.train_secs,
    })
}

/// Shallow-UWnet's part of a run.
struct EnhanceTask<'a> {
    cfg: &'a EnhanceTrainConfig,
    /// The autodiff training device.
    device: Device,
    /// The same device without autodiff, for validation.
    inner: Device,
    perceptual: Perceptual,
    val: Vec<ValPair>,
}

impl Task for EnhanceTask<'_> {
    type Model = ShallowUwnet;
    type Error = EnhanceError;
    type Source = Batches;

    fn loss_terms(&self) -> Vec<(String, String)> {
        let perceptual = match self.perceptual {
            Perceptual::Vgg(_) => "perceptual (VGG19)",
            Perceptual::Ssim => "perceptual (1 - SSIM)",
            Perceptual::Off => "perceptual (off)",
        };
        let legends = ["MSE", perceptual, "total"];
        LOSS_COLUMNS
            .iter()
            .zip(legends)
            .map(|(c, l)| ((*c).to_string(), l.to_string()))
            .collect()
    }

    fn device(&self) -> &Device {
        &self.device
    }

    fn build(&self) -> Result<ShallowUwnet> {
        self.cfg.model.init(&self.device)
    }

    fn optimizer(&self) -> ModuleOptimizer {
        AdamConfig::new()
            .with_beta_1(ADAM_BETAS.0)
            .with_beta_2(ADAM_BETAS.1)
            .with_epsilon(TORCH_ADAM_EPS)
            .init()
    }

    fn lr(&self, _step: usize, epoch: usize) -> f64 {
        self.cfg.lr_at(epoch)
    }

    /// Forward with seeded channel dropout, the weighted loss, backward, an Adam update.
    fn step(
        &self,
        model: ShallowUwnet,
        optim: &mut ModuleOptimizer,
        batch: Batch,
        step: usize,
        lr: f64,
    ) -> Result<(ShallowUwnet, Vec<f64>)> {
        let (b, c) = (self.cfg.batch_size, self.cfg.crop);
        let shape = [b, IMAGE_CHANNELS, c, c];
        let x = Tensor::<4>::from_data(TensorData::new(batch.input, shape), &self.device);
        let y = Tensor::<4>::from_data(TensorData::new(batch.target, shape), &self.device);
        let mut rng = ChaCha8Rng::seed_from_u64(mix64(
            mix64(self.cfg.run.seed ^ STREAM_DROPOUT) ^ step as u64,
        ));
        let mut dropout = Dropout {
            p: self.cfg.model.dropout,
            rng: &mut rng,
        };
        let out = model.forward_train(x, &mut dropout); // [b, 3, c, c]
        let mse = (out.clone() - y.clone()).powi_scalar(2).mean();
        let per = match (&self.perceptual, self.cfg.w_perceptual > 0.0) {
            (Perceptual::Vgg(v), true) => v.perceptual_loss(out, y),
            (Perceptual::Ssim, true) => ssim_loss(out, y),
            _ => Tensor::<1>::zeros([1], &self.device),
        };
        let total = mse.clone() * self.cfg.w_mse + per.clone() * self.cfg.w_perceptual;
        let terms = Tensor::cat(vec![mse.detach(), per.detach(), total.clone().detach()], 0); // [3]
        let grads = GradientsParams::from_grads(total.backward(), &model);
        let model = optim.step(lr, model, grads);
        let v = terms
            .into_data()
            .try_to_vec::<f32>()
            .map_err(|e| uwnr_model::ModelError::Backend(format!("reading loss values: {e:?}")))?;
        let g = |i: usize| v.get(i).copied().map_or(f64::NAN, f64::from);
        Ok((model, vec![g(0), g(1), g(2)]))
    }

    fn has_validation(&self) -> bool {
        !self.val.is_empty()
    }

    /// Scores the network on the validation pairs at their native size (outputs rounded to
    /// 8 bits, as saved files would be).
    fn validate(&self, model: &ShallowUwnet, sheet_rows: usize) -> Result<Scores> {
        let mut scores = Scores::default();
        for v in &self.val {
            let out = crate::infer::enhance(model, &v.input, &self.inner)?.quantised();
            scores.add(&v.name, out, &v.target, sheet_rows, |out| {
                vec![v.input.clone(), out, v.target.clone()]
            })?;
        }
        Ok(scores)
    }

    fn sheet_columns(&self) -> Vec<String> {
        SHEET_COLUMNS.iter().map(|c| (*c).to_string()).collect()
    }

    /// Writes `enhancer.safetensors` into the checkpoint folder being assembled.
    fn export(&self, model: &ShallowUwnet, dir: &Path, state: &RunState) -> Result<()> {
        let path = dir.join(ENHANCER_FILE);
        let mut meta = BTreeMap::new();
        meta.insert(
            SOURCE_METADATA_KEY.to_string(),
            format!(
                "uwnr enhance train, step {}, epoch {}",
                state.step, state.epoch
            ),
        );
        crate::weights::save(model, &self.cfg.model, &path, &meta).map_err(|e| {
            uwnr_run::RunError::Checkpoint {
                path,
                reason: format!("writing the enhancer weights: {e}"),
            }
            .into()
        })
    }
}

#[cfg(test)]
mod tests;
