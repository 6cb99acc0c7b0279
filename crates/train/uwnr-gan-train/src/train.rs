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
    fn discriminator(self, real: Tensor<4>, fake: Tensor<4>) -> Tensor<1> {
        match self {
            Self::NonSaturating => softplus(real.neg()).mean() + softplus(fake).mean(),
            Self::LeastSquares => {
                ((real - 1.0).powi_scalar(2).mean() + fake.powi_scalar(2).mean()) * 0.5
            }
        }
    }

    /// The generator's loss on the discriminator's logits for its renders.
    fn generator(self, fake: Tensor<4>) -> Tensor<1> {
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
mod tests {
    use super::*;
    use crate::model::{DiscriminatorConfig, GeneratorConfig, sample_z};
    use crate::weights::load_generator;
    use uwnr_run::folder::read_config_unchanged;

    /// A config small enough for a few steps on 32x32 images in a debug test.
    fn tiny() -> GanTrainConfig {
        GanTrainConfig {
            model: GanConfig {
                generator: GeneratorConfig {
                    z_dim: 8,
                    widths: vec![8, 16],
                    hidden: 16,
                    encoder_size: 16,
                    ..GeneratorConfig::default()
                },
                discriminator: DiscriminatorConfig {
                    width: 8,
                    layers: 3,
                },
            },
            epochs: 2,
            batch_size: 2,
            crop: 32,
            lr: 2e-3,
            val_images: 2,
            run: RunSettings {
                val_sheet_pairs: 2,
                log_every_steps: 1,
                checkpoint_every_secs: 0,
                ..GanTrainConfig::default().run
            },
            ..GanTrainConfig::default()
        }
    }

    /// Writes `n` synthetic 32x32 images: clean ones are grey-level ramps with a bright square,
    /// references are blue-green with a vertical falloff.
    fn write_images(dir: &Path, n: usize, underwater: bool) {
        std::fs::create_dir_all(dir).unwrap();
        for k in 0..n {
            let (w, h) = (32, 32);
            let mut data = vec![0.0_f32; 3 * w * h];
            for y in 0..h {
                for x in 0..w {
                    let i = y * w + x;
                    let v = if underwater {
                        [
                            0.1,
                            0.5 - 0.2 * y as f32 / 32.0,
                            0.7 - 0.1 * k as f32 / n as f32,
                        ]
                    } else {
                        let ramp = (x + y + 4 * k) as f32 / 80.0;
                        let sq = if (8..16).contains(&x) && (8..16).contains(&y) {
                            0.3
                        } else {
                            0.0
                        };
                        [ramp + sq, 0.5 * ramp + sq, 0.3 + sq]
                    };
                    for c in 0..3 {
                        data[c * w * h + i] = v[c].clamp(0.0, 1.0);
                    }
                }
            }
            let img = Image::from_planar(w, h, 3, data).unwrap();
            uwnr_core::io::save_rgb(&dir.join(format!("{k:02}.png")), &img).unwrap();
        }
    }

    #[test]
    fn gradients_reach_the_parameter_head_and_stay_on_their_side() {
        let d = Device::flex().autodiff();
        let cfg = tiny();
        let gan = cfg.model.init(&d).unwrap();
        let clean = Tensor::<4>::ones([2, 3, 32, 32], &d) * 0.6;
        let ramp: Vec<f32> = (0..2 * 32 * 32).map(|i| (i % 32) as f32 / 31.0).collect();
        let depth = Tensor::<4>::from_data(TensorData::new(ramp, [2, 1, 32, 32]), &d);
        let z = sample_z(3, 2, 8, &d);
        let (fake, _) = gan
            .generator
            .forward(clean.clone(), depth.clone(), z.clone())
            .unwrap();
        // Generator loss: gradients reach the head's weights and bias.
        let g_loss = GanLoss::NonSaturating.generator(gan.discriminator.forward(fake));
        let grads = g_loss.backward();
        for (name, g) in [
            (
                "head.weight",
                gan.generator
                    .head
                    .weight
                    .val()
                    .grad(&grads)
                    .map(|g| g.abs().sum()),
            ),
            (
                "head.bias",
                gan.generator
                    .head
                    .bias
                    .as_ref()
                    .and_then(|b| b.val().grad(&grads))
                    .map(|g| g.abs().sum()),
            ),
            (
                "encoder.0.weight",
                gan.generator.encoder[0]
                    .weight
                    .val()
                    .grad(&grads)
                    .map(|g| g.abs().sum()),
            ),
        ] {
            let g = g.unwrap_or_else(|| panic!("no gradient for {name}"));
            let v = to_vec(g).unwrap()[0];
            assert!(v > 0.0 && v.is_finite(), "{name}: |grad| sum {v}");
        }
        // Discriminator loss on a detached render: nothing for the generator.
        let (fake, _) = gan.generator.forward(clean, depth, z).unwrap();
        let real = Tensor::<4>::ones([2, 3, 32, 32], &d) * 0.3;
        let d_loss = GanLoss::LeastSquares.discriminator(
            gan.discriminator.forward(real),
            gan.discriminator.forward(fake.detach()),
        );
        let mut grads = d_loss.backward();
        assert!(GradientsParams::from_module(&mut grads, &gan.generator).is_empty());
        assert!(!GradientsParams::from_module(&mut grads, &gan.discriminator).is_empty());
    }

    #[test]
    fn losses_match_hand_values() {
        let d = Device::flex();
        let t = |v: f32| Tensor::<4>::ones([1, 1, 1, 1], &d) * v;
        let v = |x: Tensor<1>| f64::from(to_vec(x).unwrap()[0]);
        // softplus(0) = ln 2; softplus(-2) = ln(1 + e^-2) = 0.126928.
        assert!(
            (v(GanLoss::NonSaturating.discriminator(t(0.0), t(0.0))) - 2.0 * 2f64.ln()).abs()
                < 1e-6
        );
        assert!((v(GanLoss::NonSaturating.generator(t(2.0))) - 0.126_928).abs() < 1e-5);
        // Large logits do not overflow: softplus(100) = 100.
        assert!((v(GanLoss::NonSaturating.generator(t(-100.0))) - 100.0).abs() < 1e-3);
        // LSGAN: 0.5 * ((0.5 - 1)^2 + 0.5^2) = 0.25; (0.5 - 1)^2 = 0.25.
        assert!((v(GanLoss::LeastSquares.discriminator(t(0.5), t(0.5))) - 0.25).abs() < 1e-6);
        assert!((v(GanLoss::LeastSquares.generator(t(0.5))) - 0.25).abs() < 1e-6);
    }

    #[test]
    fn a_tiny_run_trains_both_players_validates_and_exports() {
        let dir = tempfile::tempdir().unwrap();
        let clean = dir.path().join("inair");
        let refs = dir.path().join("refs");
        write_images(&clean, 4, false);
        write_images(&refs.join("underwater"), 3, true);
        let run = dir.path().join("run");
        let opts = TrainOptions::new(vec![clean], run.clone(), Device::flex());
        let cfg = tiny();
        let mut messages = Vec::new();
        let s = train(&cfg, &opts, &[refs], &AtomicBool::new(false), &mut |e| {
            if let Event::Message(m) = e {
                messages.push(m.to_string());
            }
        })
        .unwrap();
        assert!(s.finished);
        assert_eq!(s.step, 4, "2 epochs of 4 images in batches of 2");
        let first = &s.losses[0].1;
        let last = &s.losses[3].1;
        assert!(first.iter().chain(last).all(|v| v.is_finite()));
        assert_ne!(first[0], last[0], "discriminator loss unchanged");
        assert_ne!(first[1], last[1], "generator loss unchanged");
        assert!((last[2] - last[0] - last[1]).abs() < 1e-9);
        assert!(
            messages.iter().any(|m| m.contains("built-in prior")),
            "{messages:?}"
        );
        // Validation ran (contact sheets, val.csv) and a best checkpoint exists.
        let val = std::fs::read_to_string(run.join("val.csv")).unwrap();
        assert_eq!(val.lines().count(), 3, "{val}");
        assert!(run.join("val").read_dir().unwrap().count() >= 2);
        assert!(s.best.is_some_and(|(p, _)| p.is_finite()));
        // The exported generator loads and renders.
        let g = load_generator(&s.last_weights, &Device::flex()).unwrap();
        assert_eq!(g.config, cfg.model.generator);
        assert!(s.best_weights.is_some());
    }

    #[test]
    fn a_run_is_deterministic_per_seed() {
        let dir = tempfile::tempdir().unwrap();
        let clean = dir.path().join("inair");
        let refs = dir.path().join("refs");
        write_images(&clean, 2, false);
        write_images(&refs, 2, true);
        let cfg = GanTrainConfig {
            epochs: 1,
            val_images: 0,
            ..tiny()
        };
        let losses = |name: &str| {
            let opts =
                TrainOptions::new(vec![clean.clone()], dir.path().join(name), Device::flex());
            train(
                &cfg,
                &opts,
                std::slice::from_ref(&refs),
                &AtomicBool::new(false),
                &mut |_| {},
            )
            .unwrap()
            .losses
        };
        assert_eq!(losses("a"), losses("b"));
    }

    /// The config files of `tests/fixtures/`, as the code before `RunSettings` (commit 966515d)
    /// wrote them (the defaults; a run with every run-level field changed), read back to configs
    /// that write the same JSON. The defaults of now are those of then, so a new config is
    /// written with the same keys and values as before.
    #[test]
    fn config_files_of_earlier_versions_read_back_unchanged() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
        let read = |name: &str| read_config_unchanged::<GanTrainConfig>(&dir.join(name));
        assert_eq!(
            read("config-default.json").unwrap(),
            GanTrainConfig::default()
        );
        let custom = read("config-custom.json").unwrap();
        assert_eq!((custom.run.seed, custom.val_images), (3, 2));
        let partial: GanTrainConfig = serde_json::from_str(r#"{"epochs": 3}"#).unwrap();
        assert_eq!(
            partial.run,
            GanTrainConfig::default().run,
            "the GAN's own defaults"
        );
        assert!(serde_json::from_str::<GanTrainConfig>(r#"{"max_pairs_per_dir": 2}"#).is_err());
    }

    #[test]
    fn invalid_fields_are_named() {
        let d = GanTrainConfig::default;
        for (c, field) in [
            (GanTrainConfig { epochs: 0, ..d() }, "epochs"),
            (GanTrainConfig { crop: 16, ..d() }, "crop"),
            (GanTrainConfig { lr: 0.0, ..d() }, "lr"),
            (GanTrainConfig { g_steps: 0, ..d() }, "g_steps"),
            (
                GanTrainConfig {
                    run: RunSettings {
                        prefetch_batches: 0,
                        ..d().run
                    },
                    ..d()
                },
                "prefetch_batches",
            ),
            (
                GanTrainConfig {
                    total_steps: Some(0),
                    ..d()
                },
                "total_steps",
            ),
        ] {
            match c.validate() {
                Err(GanError::InvalidTrainConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("expected InvalidTrainConfig for {field}, got {other:?}"),
            }
        }
        GanTrainConfig::default().validate().unwrap();
        let back: GanTrainConfig = serde_json::from_str(&tiny().to_json().unwrap()).unwrap();
        assert_eq!(back, tiny());
    }
}
