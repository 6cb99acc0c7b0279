//! The UWGAN-style generator's settings, shared by rendering (this crate) and training
//! (`uwnr-gan-train`): its architecture ([`GeneratorConfig`]), the imaging layer's fixed
//! settings ([`ImagingConfig`]), the parameters' ranges and initial values, and the water code.

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::error::{GanError, Result};

/// Slope of every LeakyReLU (DCGAN's and pix2pix's 0.2).
pub const LEAKY_SLOPE: f64 = 0.2;
/// Standard deviation of the N(0, σ) weight init (DCGAN, used by WaterGAN, UWGAN and pix2pix).
pub const INIT_STD: f64 = 0.02;
/// Length of the water code `z` in WaterGAN and UWGAN (`z_dim=100`).
pub const PAPER_Z_DIM: usize = 100;
/// Input channels of the generator's encoder: RGB + depth.
pub const ENCODER_IN: usize = RGB + 1;

/// Channels of an RGB image.
pub const RGB: usize = 3;
/// Number of raw values the generator's head predicts per image: β (3), B (3), vignetting
/// (a, b, c), gain k, blur weight w.
pub const RAW_PARAMS: usize = 11;
/// Largest attenuation coefficient, per metre. Jerlov's most turbid coastal type 9C keeps 29%
/// of blue light per metre (UWCNN's table, see `UWNR-NOTES.md`): `−ln 0.29 = 1.24` m⁻¹; the bound
/// leaves room above it.
pub const BETA_MAX: f32 = 1.5;
/// UWGAN's initial attenuation coefficients `(η_r, η_g, η_b)` per metre (`uwgan_model.py`,
/// `g_eta_r/g/b`, normal initialisers with these means).
pub const UWGAN_BETA_INIT: [f32; 3] = [0.35, 0.015, 0.036];
/// Largest magnitude of each vignetting coefficient: `V ≥ 1 − 3 · 0.3 = 0.1` at the corners.
pub const VIGNETTE_MAX: f32 = 0.3;
/// Initial vignetting coefficient (each of a, b, c): a faint fall-off, 4% at the corners.
pub const VIGNETTE_INIT: f32 = -0.013;
/// Smallest camera gain.
pub const GAIN_MIN: f32 = 0.5;
/// Largest camera gain (1: the stages only darken, so the render stays in [0, 1]).
pub const GAIN_MAX: f32 = 1.0;
/// Initial camera gain: UWGAN's `g_tol`, initialised to 0.9.
pub const GAIN_INIT: f32 = 0.9;
/// Initial veiling light per channel (mid grey: no colour preferred before training).
pub const BACKLIGHT_INIT: f32 = 0.5;
/// Initial blur weight (a light blur, 5%).
pub const BLUR_INIT: f32 = 0.05;
/// Depth range in metres that uwnr's relative depth 1 stands for: NYU Depth v2's Kinect range,
/// about 10 m, the metric depth UWGAN trains on.
pub const DEFAULT_RANGE_M: f64 = 10.0;
/// The 1-D binomial kernel of the optics blur (its outer product, over 16, is the 3x3 kernel).
pub const BINOMIAL: [f32; 3] = [1.0, 2.0, 1.0];

/// The fixed settings of the imaging layer (part of the generator's config).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImagingConfig {
    /// Metres that relative depth 1 stands for (`d = depth · range_m`).
    pub range_m: f64,
    /// Apply the optics blur stage.
    pub blur: bool,
}

impl Default for ImagingConfig {
    fn default() -> Self {
        Self {
            range_m: DEFAULT_RANGE_M,
            blur: false,
        }
    }
}

impl ImagingConfig {
    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        if !(self.range_m.is_finite() && self.range_m > 0.0) {
            return Err(GanError::InvalidConfig {
                field: "imaging.range_m",
                reason: format!("{} must be positive", self.range_m),
            });
        }
        Ok(())
    }
}

/// The parameter generator's architecture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeneratorConfig {
    /// Length of the water code `z`.
    pub z_dim: usize,
    /// Channels of the stride-2 conv3x3 encoder layers.
    pub widths: Vec<usize>,
    /// Units of the hidden layer between the pooled feature (+ `z`) and the head.
    pub hidden: usize,
    /// Side the clean image and depth are area-averaged to before the encoder.
    pub encoder_size: usize,
    /// The imaging layer's fixed settings.
    pub imaging: ImagingConfig,
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        Self {
            z_dim: PAPER_Z_DIM,
            widths: vec![16, 32, 64],
            hidden: 64,
            encoder_size: 64,
            imaging: ImagingConfig::default(),
        }
    }
}

impl GeneratorConfig {
    /// Checks the config can build a network.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |field: &'static str, reason: String| Err(GanError::InvalidConfig { field, reason });
        if self.widths.is_empty() || self.widths.contains(&0) {
            return bad(
                "generator.widths",
                format!("{:?}: at least one layer, none empty", self.widths),
            );
        }
        if self.hidden == 0 {
            return bad("generator.hidden", "must be at least 1".into());
        }
        if self.encoder_size < 1 << self.widths.len() {
            return bad(
                "generator.encoder_size",
                format!(
                    "{} is too small for {} stride-2 layers (at least {})",
                    self.encoder_size,
                    self.widths.len(),
                    1 << self.widths.len()
                ),
            );
        }
        self.imaging.validate()
    }

    /// Number of parameters: the encoder's `9·c_in·c_out + c_out` per layer, the hidden layer's
    /// `(c_last + z_dim + 1)·hidden`, the head's `(hidden + 1)·RAW_PARAMS` (35,003 for the default).
    #[must_use]
    pub fn param_count(&self) -> usize {
        let mut n = 0;
        let mut cin = ENCODER_IN;
        for &c in &self.widths {
            n += 9 * cin * c + c;
            cin = c;
        }
        n + (cin + self.z_dim + 1) * self.hidden + (self.hidden + 1) * RAW_PARAMS
    }
}

/// The head's raw bias that [`crate::WaterValues::from_raw`] maps to the initial parameters
/// ([`UWGAN_BETA_INIT`], [`BACKLIGHT_INIT`], [`VIGNETTE_INIT`], [`GAIN_INIT`], [`BLUR_INIT`]).
#[must_use]
pub fn initial_raw() -> [f32; RAW_PARAMS] {
    let logit = |p: f32| (p / (1.0 - p)).ln();
    let beta = UWGAN_BETA_INIT.map(|b| logit(b / BETA_MAX));
    let backlight = logit(BACKLIGHT_INIT);
    let vignette = logit(VIGNETTE_INIT / -VIGNETTE_MAX);
    let gain = logit((GAIN_INIT - GAIN_MIN) / (GAIN_MAX - GAIN_MIN));
    [
        beta[0],
        beta[1],
        beta[2],
        backlight,
        backlight,
        backlight,
        vignette,
        vignette,
        vignette,
        gain,
        logit(BLUR_INIT),
    ]
}

/// `n` values uniform in [−1, 1].
pub fn draw_z<R: Rng>(rng: &mut R, n: usize) -> Vec<f32> {
    (0..n).map(|_| rng.random_range(-1.0_f32..=1.0)).collect()
}
