//! Unpaired adversarial training of the GAN baseline as a [`uwnr_run::Task`]: clean in-air
//! images with depth on one side, real underwater references on the other.
//!
//! Each step does UWGAN's alternating updates (its `train`: one discriminator update, then the
//! generator's), with one Adam whose state is keyed by parameter id, so the two parts of the
//! one [`Gan`] module keep separate moments:
//! 1. render the batch with the water codes `z` of the batch (no gradient into the generator),
//!    `d_loss = L_D(D(reference), D(render))`, gradients of the discriminator's parameters only
//!    ([`GradientsParams::from_module`] on `model.discriminator`), an Adam update;
//! 2. `g_steps` times: render again with the updated discriminator, `g_loss = L_G(D(render))`,
//!    gradients of the generator's parameters only, an Adam update.
//!
//! The losses ([`GanLoss`]): UWGAN's non-saturating one (sigmoid cross-entropy,
//! `L_D = softplus(−D(real)) + softplus(D(fake))`, `L_G = softplus(−D(fake))`, means over the
//! patches), or least squares (LSGAN as CycleGAN uses it, `L_D = ½[(D(real) − 1)² + D(fake)²]`,
//! `L_G = (D(fake) − 1)²`). UWGAN's penalties on negative parameters are not needed: the
//! parameterisation bounds them ([`crate::imaging`]). `metrics.csv` holds `d_loss, g_loss,
//! total`, the total being `d_loss + g_loss` of the step (the two are minimised by different
//! players; their sum is only a summary).
//!
//! The defaults are UWGAN's released recipe (`uwgan_main.py`: Adam lr 2e-4, β₁ 0.5, 256x256
//! images, z of 100) with random crops instead of squashing every image to 256x256, a batch of 8
//! instead of 64 (CPU), and one generator update per discriminator update as in the paper (the
//! released loop does two, "different from paper": set `g_steps: 2`).
//!
//! # Validation without pairs
//!
//! There is no target to score a render against, so validation renders the first `val_images`
//! clean images (centre crops, water codes from seeds `0, 1, ...`), shows them as contact-sheet
//! rows (clean | rendered), and reports two documented proxies in the loop's PSNR/SSIM slots:
//! - **psnr = colour-moment PSNR**: `10 log10(1 / MSE)` between the render's per-channel mean and
//!   standard deviation (6 numbers) and the same moments averaged over all references. Higher =
//!   the renders' colour statistics are closer to real underwater images. The loop keeps the
//!   checkpoint with the highest value as `best`: a cheap stand-in for the FID the papers use,
//!   blind to texture and haze structure.
//! - **ssim = SSIM(render, clean)**: how much scene structure the water leaves (1 = unchanged).
//!   Not a quality score on its own (no water at all scores 1); shown to catch a generator that
//!   washes the scene out.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use serde::{Deserialize, Deserializer, Serialize};
use uwnr_core::Image;
pub use uwnr_run::TrainOptions;
use uwnr_run::checkpoint::{BEST, CHECKPOINTS_DIR, LAST, RunState};
use uwnr_run::folder::{check_run_folder, check_saved_config};
use uwnr_run::{Event, Prepared, RunSettings, Schedule, Scores, Task};

use crate::data::{self, Batch, Batches, CleanSample, moments};
use crate::error::{GanError, Result, to_vec};
use crate::imaging::RGB;
use crate::model::{Gan, GanConfig};
use crate::weights::{GENERATOR_FILE, save_generator};

/// `metrics.csv` columns of the loss terms (the last is the total).
const LOSS_COLUMNS: [&str; 3] = ["d_loss", "g_loss", "total"];
/// Column headers of a validation contact sheet.
const SHEET_COLUMNS: [&str; 2] = ["clean", "rendered"];
/// UWGAN's learning rate (`uwgan_main.py`, `learning_rate 0.0002`, DCGAN's).
pub const UWGAN_LR: f64 = 2e-4;
/// UWGAN's Adam β₁ (`beta1 0.5`, DCGAN's); β₂ is TensorFlow's default.
pub const UWGAN_BETAS: (f32, f32) = (0.5, 0.999);
/// Adam epsilon: TensorFlow's default 1e-8 (burn's default is 1e-5).
pub const ADAM_EPS: f32 = 1e-8;
/// UWGAN's image side (`output_height = output_width = 256`).
pub const UWGAN_SIZE: usize = 256;
/// Metadata key naming what produced an exported generator.
pub const SOURCE_METADATA_KEY: &str = "uwnr.source";

/// The adversarial loss.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum GanLoss {
    /// Sigmoid cross-entropy with the generator's non-saturating objective (UWGAN, WaterGAN).
    #[default]
    NonSaturating,
    /// Least squares (LSGAN, as CycleGAN uses it).
    LeastSquares,
}

impl GanLoss {
    /// The discriminator's loss on its logits for real and fake patches.
    pub fn discriminator(self, real: Tensor<4>, fake: Tensor<4>) -> Tensor<1> {
        match self {
            Self::NonSaturating => softplus(real.neg()).mean() + softplus(fake).mean(),
            Self::LeastSquares => {
                ((real - 1.0).powi_scalar(2).mean() + fake.powi_scalar(2).mean()) * 0.5
            }
        }
    }

    /// The generator's loss on the discriminator's logits for its renders.
    pub fn generator(self, fake: Tensor<4>) -> Tensor<1> {
        match self {
            Self::NonSaturating => softplus(fake.neg()).mean(),
            Self::LeastSquares => (fake - 1.0).powi_scalar(2).mean(),
        }
    }
}

/// `ln(1 + eˣ)`, computed as `max(x, 0) + ln(1 + e^−|x|)` so large logits do not overflow.
fn softplus(x: Tensor<4>) -> Tensor<4> {
    x.clone().clamp_min(0.0) + x.abs().neg().exp().log1p()
}

/// A run's configuration. `Default` is UWGAN's recipe with this crate's crops and batch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GanTrainConfig {
    /// Both networks.
    pub model: GanConfig,
    /// The adversarial loss.
    pub loss: GanLoss,
    /// Passes over the clean images.
    pub epochs: usize,
    /// Samples per step.
    pub batch_size: usize,
    /// Side of the square random crops (clean and reference).
    pub crop: usize,
    /// Adam learning rate (constant).
    pub lr: f64,
    /// Generator updates per discriminator update.
    pub g_steps: usize,
    /// Clean images rendered at each validation (the first, in load order; 0 = no validation).
    pub val_images: usize,
    /// Seed (of the initial weights, the data order, the crops, the references and the codes),
    /// logging, validation, checkpoint and prefetch cadence; their keys sit at the top level of
    /// the JSON.
    #[serde(flatten, deserialize_with = "run_settings")]
    pub run: RunSettings,
    /// Use at most this many images of each folder (the first in name order).
    pub max_images_per_dir: Option<usize>,
    /// End the run after this many steps in total.
    pub total_steps: Option<usize>,
}

impl Default for GanTrainConfig {
    fn default() -> Self {
        Self {
            model: GanConfig::default(),
            loss: GanLoss::default(),
            epochs: 50,
            batch_size: 8,
            crop: UWGAN_SIZE,
            lr: UWGAN_LR,
            g_steps: 1,
            val_images: 8,
            run: RunSettings::defaults(7, 1),
            max_images_per_dir: None,
            total_steps: None,
        }
    }
}

/// The run settings of a config file, over the GAN's defaults.
fn run_settings<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<RunSettings, D::Error> {
    RunSettings::deserialize_over(GanTrainConfig::default().run, d)
}

impl GanTrainConfig {
    /// Checks every field that could make a run fail late; errors name the field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &'static str, reason: String| {
            Err(GanError::InvalidTrainConfig { field, reason })
        };
        self.model.validate()?;
        if self.epochs == 0 {
            return bad("epochs", "must be at least 1".into());
        }
        if self.batch_size == 0 {
            return bad("batch_size", "must be at least 1".into());
        }
        let min = self.model.discriminator.min_input();
        if self.crop < min {
            return bad(
                "crop",
                format!(
                    "{} is below the discriminator's smallest input, {min}",
                    self.crop
                ),
            );
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad("lr", format!("{} must be positive", self.lr));
        }
        if self.g_steps == 0 {
            return bad("g_steps", "must be at least 1".into());
        }
        self.run.validate()?;
        if self.max_images_per_dir == Some(0) {
            return bad("max_images_per_dir", "must be at least 1 when given".into());
        }
        if self.total_steps == Some(0) {
            return bad("total_steps", "must be at least 1 when given".into());
        }
        Ok(())
    }

    /// Pretty JSON of the config.
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self).map_err(|e| GanError::InvalidTrainConfig {
            field: "config",
            reason: e.to_string(),
        })
    }
}

/// How a session ended.
#[derive(Clone, Debug, PartialEq)]
pub struct GanTrainSummary {
    /// Steps done in total.
    pub step: usize,
    /// Steps done in this session.
    pub session_steps: usize,
    /// `(step, [d_loss, g_loss, total])` of every step of this session.
    pub losses: Vec<(usize, Vec<f64>)>,
    /// The run reached its last step.
    pub finished: bool,
    /// The stop flag ended the session.
    pub interrupted: bool,
    /// Best validation proxy (colour-moment PSNR) and its step.
    pub best: Option<(f64, usize)>,
    /// `generator.safetensors` of the `last` checkpoint.
    pub last_weights: PathBuf,
    /// `generator.safetensors` of the `best` checkpoint, once there is one.
    pub best_weights: Option<PathBuf>,
}

/// Trains (or resumes) the run of `opts.run_dir`: clean folders are `opts.data` (layouts in
/// [`crate::data`]), underwater references `references`. `opts.val` and `opts.vgg19` are not
/// used (validation renders clean training images, see the module docs). `stop` ends the
/// session cleanly at the next step boundary; `observer` receives progress events.
pub fn train(
    cfg: &GanTrainConfig,
    opts: &TrainOptions,
    references: &[PathBuf],
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<GanTrainSummary> {
    cfg.validate()?;
    let run = &opts.run_dir;
    check_run_folder(run, opts.resume)?;
    if opts.resume {
        check_saved_config(cfg, run)?;
    }
    let data::Data {
        clean,
        references,
        reference_moments,
        report,
    } = data::load(
        &opts.data,
        references,
        cfg.crop,
        cfg.max_images_per_dir,
        &opts.limits,
    )?;
    let val = clean
        .iter()
        .take(cfg.val_images)
        .map(|c| ValImage::new(c, cfg.crop))
        .collect::<Result<Vec<_>>>()?;
    let prepared = Prepared {
        config_json: cfg.to_json()?,
        pairs: clean.len(),
        report,
    };
    let source = Arc::new(Batches {
        clean: Arc::new(clean),
        references: Arc::new(references),
        seed: cfg.run.seed,
        batch_size: cfg.batch_size,
        crop: cfg.crop,
        z_dim: cfg.model.generator.z_dim,
    });
    let task = GanTask {
        cfg,
        device: opts.device.clone().autodiff(),
        inner: opts.device.clone(),
        val,
        reference_moments,
    };
    let schedule = Schedule::new(&cfg.run, cfg.epochs, cfg.batch_size, cfg.total_steps);
    let s = uwnr_run::train(
        &task,
        source,
        &prepared,
        &schedule,
        &opts.session(),
        stop,
        observer,
    )?;
    let best = run.join(CHECKPOINTS_DIR).join(BEST).join(GENERATOR_FILE);
    Ok(GanTrainSummary {
        step: s.step,
        session_steps: s.session_steps,
        losses: s.losses,
        finished: s.finished,
        interrupted: s.interrupted,
        best: s.best,
        last_weights: run.join(CHECKPOINTS_DIR).join(LAST).join(GENERATOR_FILE),
        best_weights: best.is_file().then_some(best),
    })
}

/// A clean image rendered at each validation.
struct ValImage {
    name: String,
    clean: Image,
    depth: Image,
}

impl ValImage {
    fn new(c: &CleanSample, crop: usize) -> Result<Self> {
        let (clean, depth) = c.centre(crop)?;
        Ok(Self {
            name: c.name.clone(),
            clean,
            depth,
        })
    }
}

/// The GAN's part of a run.
struct GanTask<'a> {
    cfg: &'a GanTrainConfig,
    /// The autodiff training device.
    device: Device,
    /// The same device without autodiff, for validation.
    inner: Device,
    val: Vec<ValImage>,
    /// What the colour-moment proxy compares renders to.
    reference_moments: [f64; 6],
}

impl GanTask<'_> {
    /// The batch as tensors: clean, depth, reference, z.
    fn tensors(&self, batch: Batch) -> (Tensor<4>, Tensor<4>, Tensor<4>, Tensor<2>) {
        let (b, c, d) = (self.cfg.batch_size, self.cfg.crop, &self.device);
        let t4 =
            |v: Vec<f32>, ch: usize| Tensor::<4>::from_data(TensorData::new(v, [b, ch, c, c]), d);
        let z = Tensor::<2>::from_data(
            TensorData::new(batch.z, [b, self.cfg.model.generator.z_dim]),
            d,
        );
        (
            t4(batch.clean, RGB),
            t4(batch.depth, 1),
            t4(batch.reference, RGB),
            z,
        )
    }
}

/// Colour-moment PSNR of `image` against `target` moments: `10 log10(1 / MSE)` over the six
/// moments (capped at 100 dB for identical moments).
fn moment_psnr(image: &Image, target: &[f64; 6]) -> f64 {
    let m = moments(image.data());
    let mse = m
        .iter()
        .zip(target)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / 6.0;
    if mse <= 1e-10 {
        100.0
    } else {
        -10.0 * mse.log10()
    }
}

impl Task for GanTask<'_> {
    type Model = Gan;
    type Error = GanError;
    type Source = Batches;

    fn loss_terms(&self) -> Vec<(String, String)> {
        let kind = match self.cfg.loss {
            GanLoss::NonSaturating => "non-saturating",
            GanLoss::LeastSquares => "least squares",
        };
        let legends = [
            format!("discriminator ({kind})"),
            format!("generator ({kind})"),
            "total (d + g)".to_string(),
        ];
        LOSS_COLUMNS
            .iter()
            .zip(legends)
            .map(|(c, l)| ((*c).to_string(), l))
            .collect()
    }

    fn device(&self) -> &Device {
        &self.device
    }

    fn build(&self) -> Result<Gan> {
        self.cfg.model.init(&self.device)
    }

    fn optimizer(&self) -> ModuleOptimizer {
        AdamConfig::new()
            .with_beta_1(UWGAN_BETAS.0)
            .with_beta_2(UWGAN_BETAS.1)
            .with_epsilon(ADAM_EPS)
            .init()
    }

    fn lr(&self, _step: usize, _epoch: usize) -> f64 {
        self.cfg.lr
    }

    /// A discriminator update, then `g_steps` generator updates (see the module docs).
    fn step(
        &self,
        model: Gan,
        optim: &mut ModuleOptimizer,
        batch: Batch,
        _step: usize,
        lr: f64,
    ) -> Result<(Gan, Vec<f64>)> {
        let (clean, depth, reference, z) = self.tensors(batch);
        let loss = self.cfg.loss;
        let (fake, _) = model
            .generator
            .forward(clean.clone(), depth.clone(), z.clone())?;
        let real_logits = model.discriminator.forward(reference); // [b, 1, p, p]
        let fake_logits = model.discriminator.forward(fake.detach());
        let d_loss = loss.discriminator(real_logits, fake_logits);
        let mut grads = d_loss.backward();
        let d_grads = GradientsParams::from_module(&mut grads, &model.discriminator);
        let mut model = optim.step(lr, model, d_grads);
        let mut g_value = Tensor::<1>::zeros([1], &self.device);
        for _ in 0..self.cfg.g_steps {
            let (fake, _) = model
                .generator
                .forward(clean.clone(), depth.clone(), z.clone())?;
            let g_loss = loss.generator(model.discriminator.forward(fake));
            let mut grads = g_loss.backward();
            let g_grads = GradientsParams::from_module(&mut grads, &model.generator);
            model = optim.step(lr, model, g_grads);
            g_value = g_loss.detach();
        }
        let v = to_vec(Tensor::cat(vec![d_loss.detach(), g_value], 0))?;
        let (d, g) = (f64::from(v[0]), f64::from(v[1]));
        Ok((model, vec![d, g, d + g]))
    }

    fn has_validation(&self) -> bool {
        !self.val.is_empty()
    }

    /// Renders the validation images (codes from seeds 0, 1, ...) and scores the two proxies.
    fn validate(&self, model: &Gan, sheet_rows: usize) -> Result<Scores> {
        let mut scores = Scores::default();
        for (i, v) in self.val.iter().enumerate() {
            let out =
                crate::infer::render(&model.generator, &v.clean, &v.depth, i as u64, &self.inner)?
                    .quantised();
            let psnr = moment_psnr(&out, &self.reference_moments);
            let ssim = uwnr_metrics::ssim(&out, &v.clean, uwnr_metrics::DEFAULT_DATA_RANGE)?;
            scores.per_pair.push((v.name.clone(), psnr, ssim));
            if scores.sheet.len() < sheet_rows {
                scores
                    .sheet
                    .push((v.name.clone(), vec![v.clean.clone(), out]));
            }
        }
        let n = scores.per_pair.len().max(1) as f64;
        scores.psnr = scores.per_pair.iter().map(|r| r.1).sum::<f64>() / n;
        scores.ssim = scores.per_pair.iter().map(|r| r.2).sum::<f64>() / n;
        Ok(scores)
    }

    fn sheet_columns(&self) -> Vec<String> {
        SHEET_COLUMNS.iter().map(|c| (*c).to_string()).collect()
    }

    /// Writes `generator.safetensors` into the checkpoint folder being assembled.
    fn export(&self, model: &Gan, dir: &Path, state: &RunState) -> Result<()> {
        let mut meta = BTreeMap::new();
        meta.insert(
            SOURCE_METADATA_KEY.to_string(),
            format!(
                "uwnr-gan training, step {}, epoch {}",
                state.step, state.epoch
            ),
        );
        save_generator(&model.generator, &dir.join(GENERATOR_FILE), &meta)
    }
}

#[cfg(test)]
mod tests;
