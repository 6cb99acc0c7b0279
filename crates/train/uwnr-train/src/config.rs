//! `TrainConfig`: everything a training run depends on, serialised into the run folder as
//! `config.json`. `Default` is the paper's recipe as the released `train_ddp.py` runs it
//! (UWNR, Ye et al., CVPR-W 2022, Sec. 4.1): random 256x256 crops with horizontal flips and
//! rotations by multiples of 90 degrees, batch 16, AdamW (lr 2e-4, betas 0.9/0.999, weight
//! decay 1e-6), 200 epochs with the learning rate constant for the first half and decaying
//! linearly to 0 over the second, and the loss `0.6 L1 + 0.5 perceptual + 0.5 dark channel +
//! 0.5 light-field consistency`.

use std::path::Path;

use serde::{Deserialize, Deserializer, Serialize};
use uwnr_depth::DepthSource;
use uwnr_gan_train::{DiscriminatorConfig, GanLoss};
use uwnr_model::config::SIZE_MULTIPLE;
use uwnr_model::{GeneratorConfig, Variant};
use uwnr_run::RunSettings;

use crate::error::{Result, TrainError};

/// Released `option.py` / paper: AdamW learning rate.
pub const PAPER_LR: f64 = 2e-4;
/// `torch.optim.AdamW(..., betas=[0.9, 0.999])` in `train_ddp.py`.
pub const PAPER_BETAS: (f32, f32) = (0.9, 0.999);
/// `weight_decay=0.000001` in `train_ddp.py`.
pub const PAPER_WEIGHT_DECAY: f32 = 1e-6;
/// PyTorch's AdamW default `eps` (the released script does not change it).
pub const TORCH_ADAMW_EPS: f32 = 1e-8;
/// Paper: 200 epochs.
pub const PAPER_EPOCHS: usize = 200;
/// Paper: batch size 16.
pub const PAPER_BATCH: usize = 16;
/// Paper: random 256x256 crops.
pub const PAPER_CROP: usize = 256;
/// `init_seeds(41 + rank)` in `train_ddp.py` (rank 0).
pub const PAPER_SEED: u64 = 41;
/// Released loss weights: `0.6 * L1`.
pub const PAPER_W_RECONSTRUCTION: f64 = 0.6;
/// `0.5 * PerceptualLoss`.
pub const PAPER_W_PERCEPTUAL: f64 = 0.5;
/// `0.5 * DCLoss_Two(15)`.
pub const PAPER_W_DARK_CHANNEL: f64 = 0.5;
/// `0.5 * Retinex_loss1` (the light-field consistency term).
pub const PAPER_W_LIGHT_FIELD: f64 = 0.5;
/// `DCLoss_Two(15)`: the dark channel's local window.
pub const PAPER_DARK_CHANNEL_WINDOW: usize = 15;
/// Colour-cast gains measured useful in the calibration runs (TRAINING-NOTES): each channel of
/// the underwater target multiplied by a gain drawn from [0.5, 1.6].
pub const COLOR_CAST_GAIN: (f32, f32) = (0.5, 1.6);
/// Gamma range of the colour-cast augmentation (`v^gamma`, drawn per sample).
pub const COLOR_CAST_GAMMA: (f32, f32) = (0.8, 1.25);

/// The light-field consistency loss variant.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightFieldLoss {
    /// The paper's definition (Sec. 3.4): L1 between the light-field maps of the output and
    /// the target, each the mean of Gaussian blurs with sigma 15, 60, 90, in the log domain,
    /// min-max normalised (see [`crate::losses::light_field_map`]).
    #[default]
    Paper,
    /// The released code's behaviour: its blur radius is 0 (`r = 0` in
    /// `loss/retinex_loss.py`), so the term reduces to a plain L1 between output and target.
    Released,
}

/// What replaces the VGG19 perceptual term when no VGG19 weights are given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PerceptualFallback {
    /// `1 - SSIM` with an 11x11 Gaussian window (sigma 1.5), a structure term that needs no
    /// pretrained weights (see [`crate::losses::ssim_loss`]).
    #[default]
    Ssim,
    /// Drop the term.
    None,
}

/// How images smaller than the crop are brought up to it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SmallImagePolicy {
    /// Upscale the pair (bilinear, aspect ratio kept) until the short side equals the crop.
    #[default]
    Upscale,
    /// Pad by reflection to the crop size.
    Pad,
}

/// Weights of the loss terms.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LossWeights {
    /// L1 reconstruction.
    pub reconstruction: f64,
    /// VGG19 perceptual term (or its stand-in, see [`PerceptualFallback`]).
    pub perceptual: f64,
    /// Underwater dark channel.
    pub dark_channel: f64,
    /// Light-field consistency.
    pub light_field: f64,
}

impl Default for LossWeights {
    fn default() -> Self {
        Self {
            reconstruction: PAPER_W_RECONSTRUCTION,
            perceptual: PAPER_W_PERCEPTUAL,
            dark_channel: PAPER_W_DARK_CHANNEL,
            light_field: PAPER_W_LIGHT_FIELD,
        }
    }
}

/// Random colour cast of the underwater target: per-channel gains and a gamma, after which the
/// light-field map is recomputed from the altered target, so that the clean image cannot
/// predict the target's colour and the network must read it from the light field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColorCast {
    /// Probability that a sample is cast.
    pub probability: f32,
    /// Per-channel gain range `[min, max]`, drawn uniformly and independently per channel.
    pub gain: (f32, f32),
    /// Gamma range `[min, max]` (one gamma per sample, drawn log-uniformly).
    pub gamma: (f32, f32),
}

impl Default for ColorCast {
    fn default() -> Self {
        Self {
            probability: 1.0,
            gain: COLOR_CAST_GAIN,
            gamma: COLOR_CAST_GAMMA,
        }
    }
}

/// Data augmentation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AugmentConfig {
    /// Random horizontal flip (released `augData`).
    pub flip: bool,
    /// Random rotation by 0, 90, 180 or 270 degrees (released `augData`).
    pub rotate: bool,
    /// Colour cast of the underwater target (not in the paper; off by default).
    #[serde(default)]
    pub color_cast: Option<ColorCast>,
}

impl Default for AugmentConfig {
    fn default() -> Self {
        Self {
            flip: true,
            rotate: true,
            color_cast: None,
        }
    }
}

/// Adversarial training of the anchored variant's correction ([`crate::adversarial`]): the
/// generator's objective is `weight · L_G(D(render)) + content · L1(render, uncorrected)` plus
/// the paired terms of [`LossWeights`] (set them to 0 when the "underwater" side of each pair
/// is a reference of another scene), and the discriminator learns the real photos (each
/// pair's underwater side) from the renders.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AdversarialConfig {
    /// Weight of the generator's adversarial term.
    pub weight: f64,
    /// Weight of the content term: L1 between the render and the same render without
    /// correction (the anchor through the depth stage), which keeps the water and its strength.
    pub content: f64,
    /// The discriminator sees renders and real photos average-pooled by this factor: the
    /// correction is a smooth gain and offset, so the discriminator judges what it can change
    /// (colour and light over the frame) rather than texture it cannot.
    pub downsample: usize,
    /// The adversarial loss.
    pub loss: GanLoss,
    /// The PatchGAN discriminator.
    pub discriminator: DiscriminatorConfig,
    /// The stages a render goes through after the model (the water's effects and the camera),
    /// applied to what the discriminator sees; absent, it sees the model's render alone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stages: Option<RenderStages>,
}

/// What a dataset's render goes through after the model, for the discriminator's eyes
/// ([`crate::adversarial`]): the real photos it is compared with passed through water's
/// effects and a camera, and without them a discriminator tells renders from photos by what the
/// correction cannot change. Straight-through: the generator's gradient passes the stages as if
/// they were not there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RenderStages {
    /// The water's effects (uwnr's default when absent).
    pub effects: uwnr_model::WaterEffects,
    /// The camera (`typical` when absent).
    pub camera: uwnr_render::Camera,
    /// Shorter side (px) of the frames the training crops come from, which sizes the particles,
    /// the point spreads and the lens blur as in a render of the whole frame.
    pub frame: usize,
}

impl Default for RenderStages {
    fn default() -> Self {
        Self {
            effects: uwnr_model::WaterEffects::DEFAULT,
            camera: uwnr_render::Camera::TYPICAL,
            frame: 256,
        }
    }
}

impl Default for AdversarialConfig {
    /// The setting of `tools/train_realism.json` (`docs/RESULTS.md`, "The correction trained for
    /// realism"): at a weight of 0.1 against the content's 1.0 the correction never left zero.
    fn default() -> Self {
        Self {
            weight: 1.0,
            content: 1.0,
            downsample: 2,
            loss: GanLoss::LeastSquares,
            discriminator: DiscriminatorConfig {
                width: 32,
                layers: 2,
            },
            stages: None,
        }
    }
}

impl AdversarialConfig {
    /// Checks the fields against the run's `cfg`: an anchored model with a correction, finite
    /// non-negative weights, and a pooled crop the discriminator can read.
    pub fn validate(&self, cfg: &TrainConfig) -> Result<()> {
        let bad =
            |field: &'static str, reason: String| Err(TrainError::InvalidConfig { field, reason });
        if cfg.model.variant != Variant::Anchored || !cfg.model.runs_network() {
            return bad(
                "adversarial",
                "trains the anchored variant's correction: needs model.variant \"anchored\" \
                 with a network correction"
                    .into(),
            );
        }
        for (field, v) in [
            ("adversarial.weight", self.weight),
            ("adversarial.content", self.content),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, format!("{v} must be finite and >= 0"));
            }
        }
        if self.downsample == 0 || !cfg.crop.is_multiple_of(self.downsample) {
            return bad(
                "adversarial.downsample",
                format!(
                    "{} must be at least 1 and divide the crop {}",
                    self.downsample, cfg.crop
                ),
            );
        }
        if let Err(e) = self.discriminator.validate() {
            return bad("adversarial.discriminator", e.to_string());
        }
        if let Some(st) = &self.stages {
            if st.frame == 0 {
                return bad("adversarial.stages.frame", "must be at least 1".into());
            }
            if let Err(e) = st.effects.validate() {
                return bad("adversarial.stages.effects", e.to_string());
            }
            if let Err(e) = st.camera.validate() {
                return bad("adversarial.stages.camera", e.to_string());
            }
            if !st.camera.clean.is_none() {
                return bad(
                    "adversarial.stages.camera",
                    "clean acts on a dataset's stored clean side; training stores none".into(),
                );
            }
        }
        let seen = cfg.crop / self.downsample;
        if seen < self.discriminator.min_input() {
            return bad(
                "adversarial.downsample",
                format!(
                    "the discriminator sees {seen} px (crop {} / {}), below its smallest input {}",
                    cfg.crop,
                    self.downsample,
                    self.discriminator.min_input()
                ),
            );
        }
        Ok(())
    }
}

/// A training run's configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// The generator's widths.
    pub model: GeneratorConfig,
    /// Passes over the training pairs.
    pub epochs: usize,
    /// Samples per optimisation step.
    pub batch_size: usize,
    /// Side of the square random crops (a multiple of 16).
    pub crop: usize,
    /// AdamW learning rate.
    pub lr: f64,
    /// AdamW `(beta_1, beta_2)`.
    pub betas: (f32, f32),
    /// AdamW decoupled weight decay.
    pub weight_decay: f32,
    /// AdamW epsilon.
    pub epsilon: f32,
    /// Epoch (0-based) after which the learning rate decays linearly to 0 at the last step;
    /// `None` = half of `epochs`.
    pub decay_start_epoch: Option<usize>,
    /// Loss weights.
    pub loss: LossWeights,
    /// Light-field loss variant.
    pub light_field_loss: LightFieldLoss,
    /// What stands in for the perceptual term without VGG19 weights.
    pub perceptual_fallback: PerceptualFallback,
    /// Window of the underwater dark channel.
    pub dark_channel_window: usize,
    /// Augmentation.
    pub augment: AugmentConfig,
    /// Images smaller than the crop.
    pub small_images: SmallImagePolicy,
    /// Where depth maps come from when a data folder has no `depth/` folder.
    pub depth: DepthSource,
    /// Use at most this many pairs of each data folder (the first ones in name order);
    /// `None` = all.
    pub max_pairs_per_dir: Option<usize>,
    /// Train the anchored variant's correction against real underwater photos with a
    /// discriminator ([`crate::adversarial`]); `None` (the default) is the paper's paired
    /// training.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adversarial: Option<AdversarialConfig>,
    /// Seed (of the weight initialisation, the data order and the augmentation), logging,
    /// validation, checkpoint and prefetch cadence; their keys sit at the top level of the
    /// JSON.
    #[serde(flatten, deserialize_with = "run_settings")]
    pub run: RunSettings,
}

/// The run settings of a config file, over UWNR's defaults.
fn run_settings<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<RunSettings, D::Error> {
    RunSettings::deserialize_over(TrainConfig::default().run, d)
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            model: GeneratorConfig::default(),
            epochs: PAPER_EPOCHS,
            batch_size: PAPER_BATCH,
            crop: PAPER_CROP,
            lr: PAPER_LR,
            betas: PAPER_BETAS,
            weight_decay: PAPER_WEIGHT_DECAY,
            epsilon: TORCH_ADAMW_EPS,
            decay_start_epoch: None,
            loss: LossWeights::default(),
            light_field_loss: LightFieldLoss::default(),
            perceptual_fallback: PerceptualFallback::default(),
            dark_channel_window: PAPER_DARK_CHANNEL_WINDOW,
            augment: AugmentConfig::default(),
            small_images: SmallImagePolicy::default(),
            depth: DepthSource::Builtin,
            max_pairs_per_dir: None,
            adversarial: None,
            run: RunSettings::defaults(PAPER_SEED, 10),
        }
    }
}

impl TrainConfig {
    /// Checks every field that could make a run fail late.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |field: &'static str, reason: String| Err(TrainError::InvalidConfig { field, reason });
        self.model
            .validate()
            .map_err(|e| TrainError::InvalidConfig {
                field: "model",
                reason: e.to_string(),
            })?;
        if self.epochs == 0 {
            return bad("epochs", "must be at least 1".into());
        }
        if self.batch_size == 0 {
            return bad("batch_size", "must be at least 1".into());
        }
        if self.crop == 0 || !self.crop.is_multiple_of(SIZE_MULTIPLE) {
            return bad(
                "crop",
                format!(
                    "{} must be a positive multiple of {SIZE_MULTIPLE}",
                    self.crop
                ),
            );
        }
        if !(self.lr.is_finite() && self.lr > 0.0) {
            return bad("lr", format!("{} must be positive", self.lr));
        }
        for (field, b) in [("betas.0", self.betas.0), ("betas.1", self.betas.1)] {
            if !(0.0..1.0).contains(&b) {
                return bad(field, format!("{b} must be in [0, 1)"));
            }
        }
        if let Some(d) = self.decay_start_epoch
            && d >= self.epochs
        {
            return bad(
                "decay_start_epoch",
                format!("{d} must be below epochs = {}", self.epochs),
            );
        }
        if self.dark_channel_window == 0 || self.dark_channel_window.is_multiple_of(2) {
            return bad(
                "dark_channel_window",
                format!("{} must be odd", self.dark_channel_window),
            );
        }
        let w = self.loss;
        for (field, v) in [
            ("loss.reconstruction", w.reconstruction),
            ("loss.perceptual", w.perceptual),
            ("loss.dark_channel", w.dark_channel),
            ("loss.light_field", w.light_field),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, format!("{v} must be finite and >= 0"));
            }
        }
        if let Some(c) = self.augment.color_cast {
            if !(0.0..=1.0).contains(&c.probability) {
                return bad(
                    "augment.color_cast.probability",
                    format!("{} must be in [0, 1]", c.probability),
                );
            }
            if !(c.gain.0 > 0.0 && c.gain.0 <= c.gain.1) {
                return bad(
                    "augment.color_cast.gain",
                    format!("{:?} must be 0 < min <= max", c.gain),
                );
            }
            if !(c.gamma.0 > 0.0 && c.gamma.0 <= c.gamma.1) {
                return bad(
                    "augment.color_cast.gamma",
                    format!("{:?} must be 0 < min <= max", c.gamma),
                );
            }
        }
        if let Some(a) = &self.adversarial {
            a.validate(self)?;
        }
        self.run.validate()?;
        Ok(())
    }

    /// The epoch (0-based) from which the learning rate decays.
    #[must_use]
    pub fn decay_start(&self) -> usize {
        self.decay_start_epoch.unwrap_or(self.epochs / 2)
    }

    /// Learning rate at optimisation step `step` (0-based) of a run of `steps_per_epoch`
    /// steps per epoch: `lr` up to the start of epoch [`Self::decay_start`], then falling
    /// linearly to 0 at the end of the last epoch. (The released `LambdaLR` does this per
    /// epoch, `1 - max(0, e - 100) / 100`; per step it reaches 0 exactly and has no jumps.)
    #[must_use]
    pub fn lr_at(&self, step: usize, steps_per_epoch: usize) -> f64 {
        let total = self.epochs * steps_per_epoch;
        let start = self.decay_start() * steps_per_epoch;
        if step < start || total <= start {
            return self.lr;
        }
        let left = total.saturating_sub(step) as f64;
        self.lr * left / (total - start) as f64
    }

    /// Reads a config from JSON. Fields not given keep their defaults; unknown fields are an
    /// error.
    pub fn from_json_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| TrainError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| TrainError::Config {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// Pretty JSON of the config.
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self).map_err(|e| TrainError::InvalidConfig {
            field: "config",
            reason: e.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use uwnr_run::folder::read_config_unchanged;

    #[test]
    fn default_is_the_paper_recipe() {
        let c = TrainConfig::default();
        c.validate().unwrap();
        assert_eq!((c.epochs, c.batch_size, c.crop), (200, 16, 256));
        assert_eq!(c.decay_start(), 100);
        assert_eq!(c.model.base_width, 64);
        assert!(c.augment.flip && c.augment.rotate && c.augment.color_cast.is_none());
    }

    #[test]
    fn lr_is_constant_then_linear_to_zero() {
        let c = TrainConfig {
            epochs: 4,
            lr: 1.0,
            ..TrainConfig::default()
        };
        // 10 steps per epoch: constant for epochs 0-1 (steps 0..20), then 20 steps to 0.
        assert_eq!(c.lr_at(0, 10), 1.0);
        assert_eq!(c.lr_at(19, 10), 1.0);
        assert_eq!(c.lr_at(20, 10), 1.0);
        assert!((c.lr_at(30, 10) - 0.5).abs() < 1e-12);
        assert!((c.lr_at(39, 10) - 0.05).abs() < 1e-12);
        assert_eq!(c.lr_at(40, 10), 0.0);
    }

    #[test]
    fn json_round_trip_and_partial_files() {
        let c = TrainConfig {
            light_field_loss: LightFieldLoss::Released,
            augment: AugmentConfig {
                color_cast: Some(ColorCast::default()),
                ..AugmentConfig::default()
            },
            ..TrainConfig::default()
        };
        let back: TrainConfig = serde_json::from_str(&c.to_json().unwrap()).unwrap();
        assert_eq!(back, c);
        let partial: TrainConfig =
            serde_json::from_str(r#"{"epochs": 3, "light_field_loss": "released"}"#).unwrap();
        assert_eq!(partial.epochs, 3);
        assert_eq!(partial.light_field_loss, LightFieldLoss::Released);
        assert_eq!(partial.batch_size, PAPER_BATCH);
        assert!(serde_json::from_str::<TrainConfig>(r#"{"epoch": 3}"#).is_err());
    }

    /// The config files of `tests/fixtures/`, as the code before `RunSettings` (commit 966515d)
    /// wrote them (the defaults; a run with every run-level field changed), read back to configs
    /// that write the same JSON. The defaults of now are those of then, so a new config is
    /// written with the same keys and values as before.
    #[test]
    fn config_files_of_earlier_versions_read_back_unchanged() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
        let read = |name: &str| read_config_unchanged::<TrainConfig>(&dir.join(name)).unwrap();
        assert_eq!(read("config-default.json"), TrainConfig::default());
        let custom = read("config-custom.json");
        assert_eq!((custom.run.seed, custom.run.log_every_steps), (5, 7));
        let partial: TrainConfig = serde_json::from_str(r#"{"epochs": 3}"#).unwrap();
        assert_eq!(
            partial.run,
            TrainConfig::default().run,
            "UWNR's own defaults"
        );
        assert!(serde_json::from_str::<TrainConfig>(r#"{"total_steps": 9}"#).is_err());
    }

    #[test]
    fn invalid_fields_are_named() {
        for (c, field) in [
            (
                TrainConfig {
                    crop: 100,
                    ..TrainConfig::default()
                },
                "crop",
            ),
            (
                TrainConfig {
                    dark_channel_window: 14,
                    ..TrainConfig::default()
                },
                "dark_channel_window",
            ),
            (
                TrainConfig {
                    batch_size: 0,
                    ..TrainConfig::default()
                },
                "batch_size",
            ),
        ] {
            match c.validate() {
                Err(TrainError::InvalidConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("expected InvalidConfig for {field}, got {other:?}"),
            }
        }
    }

    #[test]
    fn an_adversarial_run_needs_an_anchored_correction_and_a_readable_pool() {
        let anchored = GeneratorConfig::anchored(8);
        let ok = TrainConfig {
            model: anchored,
            crop: 64,
            adversarial: Some(AdversarialConfig::default()),
            ..TrainConfig::default()
        };
        ok.validate().unwrap();
        let back: TrainConfig = serde_json::from_str(&ok.to_json().unwrap()).unwrap();
        assert_eq!(back, ok);
        // A config without the field writes none (earlier files read back unchanged).
        assert!(
            !TrainConfig::default()
                .to_json()
                .unwrap()
                .contains("adversarial")
        );
        let field_of = |c: TrainConfig| match c.validate() {
            Err(TrainError::InvalidConfig { field, .. }) => field,
            other => panic!("expected InvalidConfig, got {other:?}"),
        };
        let paper = TrainConfig {
            model: GeneratorConfig::with_base_width(8),
            ..ok.clone()
        };
        assert_eq!(field_of(paper), "adversarial");
        let no_network = TrainConfig {
            model: GeneratorConfig {
                correction: uwnr_model::Correction::None,
                ..anchored
            },
            ..ok.clone()
        };
        assert_eq!(field_of(no_network), "adversarial");
        let with = |a: AdversarialConfig| TrainConfig {
            adversarial: Some(a),
            ..ok.clone()
        };
        let d = AdversarialConfig::default();
        // 64 / 3 is not whole; 64 / 16 = 4 px is below the 2-layer discriminator's 12.
        for (a, field) in [
            (
                AdversarialConfig { downsample: 3, ..d },
                "adversarial.downsample",
            ),
            (
                AdversarialConfig {
                    downsample: 16,
                    ..d
                },
                "adversarial.downsample",
            ),
            (
                AdversarialConfig { weight: -1.0, ..d },
                "adversarial.weight",
            ),
            (
                AdversarialConfig {
                    content: f64::NAN,
                    ..d
                },
                "adversarial.content",
            ),
            (
                // No clean side is stored in training for the clean blur to act on.
                AdversarialConfig {
                    stages: Some(RenderStages {
                        camera: uwnr_render::Camera {
                            clean: uwnr_render::CleanCamera::Lens,
                            ..uwnr_render::Camera::TYPICAL
                        },
                        ..RenderStages::default()
                    }),
                    ..d
                },
                "adversarial.stages.camera",
            ),
        ] {
            assert_eq!(field_of(with(a)), field);
        }
    }
}
