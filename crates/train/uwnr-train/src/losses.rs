//! The training losses of UWNR (Ye et al., CVPR-W 2022, Sec. 3.4), differentiable in burn:
//!
//! - reconstruction: `L1(out, x_u)` (mean absolute error);
//! - perceptual: `sum_j 0.2 * L1(phi_j(out), phi_j(x_u))` over the VGG19 feature cut points of
//!   the released `loss/perceptual.py` ([`crate::vgg`]), or, without VGG19 weights, the
//!   stand-in `1 - SSIM` ([`ssim_loss`]);
//! - underwater dark channel: `L1(UDC(out), UDC(x_u))` with
//!   `UDC(x)(p) = min_{q in N(p)} min_{c in {g, b}} x_c(q)` over a 15x15 window
//!   ([`dark_channel`]; released `DCLoss_Two(15)`: a `MaxPool3d((2, 15, 15))` of the negated G
//!   and B planes, padding 7 that never wins, so the window is clipped at the borders);
//! - light-field consistency: `L1(LF(out), LF(x_u))` ([`light_field_map`]), or, as released,
//!   a plain L1 (the released `Retinex_loss1` blurs with radius `r = 0`).

use burn::tensor::module::{avg_pool2d, conv2d, max_pool2d};
use burn::tensor::ops::{AvgPoolOptions, ConvOptions, MaxPoolOptions};
use burn::tensor::{Device, Tensor, TensorData};

use crate::config::{LightFieldLoss, LossWeights, PerceptualFallback, TrainConfig};
use crate::vgg::{CUT_WEIGHT, Vgg19Features};

/// Gaussian sigmas of the light-field map (paper Eq. 2 and the released code).
pub const LF_SIGMAS: [f64; 3] = [15.0, 60.0, 90.0];
/// The released map blurs an image shrunk to 0.3 of its size (`cv2.resize(img, None, fx=0.3,
/// fy=0.3)` in `MutiScaleLuminanceEstimation`): the sigmas are in units of that grid.
pub const LF_RELEASED_SCALE: f64 = 0.3;
/// The loss shrinks by average pooling with this factor, the integer closest to 1 / 0.3, and
/// scales the sigmas by `(1 / LF_POOL) / LF_RELEASED_SCALE` to keep the released geometry.
pub const LF_POOL: usize = 3;
/// Truncation of the Gaussian kernels, in sigmas (OpenCV's rule for 8-bit images:
/// `ksize = round(sigma * 3 * 2 + 1) | 1`).
pub const LF_TRUNCATE_SIGMAS: f64 = uwnr_model::style::BLUR_TRUNCATE_SIGMAS;
/// Floor of the blurred values before the log: one 8-bit code. The output of the tanh can be
/// negative; the map's log needs positive values.
pub const LF_LOG_FLOOR: f64 = 1.0 / 255.0;
/// Added to the range in the min-max normalisation (a flat map normalises to 0, not NaN).
pub const NORMALISE_EPS: f64 = 1e-6;
/// SSIM window: 11x11 Gaussian with sigma 1.5 (Wang et al. 2004).
pub const SSIM_WINDOW: usize = 11;
/// SSIM window sigma.
pub const SSIM_SIGMA: f64 = 1.5;
/// SSIM `C1 = (K1 L)^2` with `K1 = 0.01`, data range `L = 1`.
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// SSIM `C2 = (K2 L)^2` with `K2 = 0.03`.
pub const SSIM_C2: f64 = 0.03 * 0.03;

/// Mean absolute difference.
///
/// # Shapes
/// - `a`, `b`: the same shape; output: `[1]`
pub fn l1<const D: usize>(a: Tensor<D>, b: Tensor<D>) -> Tensor<1> {
    (a - b).abs().mean()
}

/// The underwater dark channel: the minimum over the G and B channels, then over a
/// `window x window` neighbourhood clipped at the image borders.
///
/// # Shapes
/// - `x`: `[b, 3, h, w]`; output: `[b, 1, h, w]`
pub fn dark_channel(x: Tensor<4>, window: usize) -> Tensor<4> {
    let gb_min = x.narrow(1, 1, 2).min_dim(1); // [b, 1, h, w]
    let pad = window / 2;
    let opts = MaxPoolOptions::new([window, window])
        .with_stride([1, 1])
        .with_padding([pad, pad]);
    // min over a window = -max(-x); max pooling pads with -inf, so borders clip the window.
    max_pool2d(gb_min.neg(), opts).neg()
}

/// `L1(dark_channel(out), dark_channel(target))`.
pub fn dark_channel_loss(out: Tensor<4>, target: Tensor<4>, window: usize) -> Tensor<1> {
    l1(dark_channel(out, window), dark_channel(target, window))
}

pub use crate::burn_style::gaussian_blur;
pub use uwnr_model::blur::gaussian_kernel;

/// The paper's light-field map of a batch (Eq. 2-3 and the loss's `LF`), with the released
/// map's geometry: the image is shrunk by [`LF_POOL`] (average pooling), blurred with
/// `sigma in LF_SIGMAS` scaled to that grid, the three blurs averaged, floored at
/// [`LF_LOG_FLOOR`], taken to the log and min-max normalised per sample over all channels.
///
/// # Shapes
/// - `x`: `[b, 3, h, w]` with `h, w >= LF_POOL`; output: `[b, 3, h / 3, w / 3]`
pub fn light_field_map(x: Tensor<4>) -> Tensor<4> {
    let small = avg_pool2d(x, AvgPoolOptions::new([LF_POOL, LF_POOL])); // [b, 3, h/3, w/3]
    let to_grid = (1.0 / LF_POOL as f64) / LF_RELEASED_SCALE;
    let mut sum: Option<Tensor<4>> = None;
    for sigma in LF_SIGMAS {
        let b = gaussian_blur(small.clone(), sigma * to_grid);
        sum = Some(match sum {
            Some(s) => s + b,
            None => b,
        });
    }
    let Some(sum) = sum else {
        return small;
    };
    let logged = (sum / LF_SIGMAS.len() as f64).clamp_min(LF_LOG_FLOOR).log(); // [b, 3, h', w']
    normalise_per_sample(logged)
}

/// Min-max normalisation of each sample over all its channels and pixels.
fn normalise_per_sample(x: Tensor<4>) -> Tensor<4> {
    let [b, c, h, w] = x.dims();
    let flat = x.reshape([b, c * h * w]);
    let lo = flat.clone().min_dim(1); // [b, 1]
    let hi = flat.clone().max_dim(1); // [b, 1]
    let out = (flat - lo.clone()) / (hi - lo + NORMALISE_EPS);
    out.reshape([b, c, h, w])
}

/// The light-field consistency loss in the chosen variant.
pub fn light_field_loss(out: Tensor<4>, target: Tensor<4>, variant: LightFieldLoss) -> Tensor<1> {
    match variant {
        LightFieldLoss::Paper => l1(light_field_map(out), light_field_map(target.detach())),
        LightFieldLoss::Released => l1(out, target),
    }
}

/// Mean SSIM (Wang et al. 2004) of two batches with values in [0, 1]: per channel, an 11x11
/// Gaussian window (sigma 1.5), only where the window lies inside the image ("valid").
///
/// # Shapes
/// - `x`, `y`: `[b, c, h, w]` with `h, w >= 11`; output: `[1]`
pub fn ssim(x: Tensor<4>, y: Tensor<4>) -> Tensor<1> {
    let [_, c, _, _] = x.dims();
    let device = x.device();
    let k = gaussian_kernel(SSIM_SIGMA, SSIM_WINDOW / 2);
    let win = |t: Tensor<4>| window_filter(t, &k, c, &device);
    let mx = win(x.clone());
    let my = win(y.clone());
    let sxx = win(x.clone() * x.clone()) - mx.clone() * mx.clone();
    let syy = win(y.clone() * y.clone()) - my.clone() * my.clone();
    let sxy = win(x * y) - mx.clone() * my.clone();
    let num = (mx.clone() * my.clone() * 2.0 + SSIM_C1) * (sxy * 2.0 + SSIM_C2);
    let den = (mx.clone() * mx + my.clone() * my + SSIM_C1) * (sxx + syy + SSIM_C2);
    (num / den).mean()
}

/// Separable "valid" filtering of every channel with the 1-D kernel `k`.
fn window_filter(x: Tensor<4>, k: &[f64], c: usize, device: &Device) -> Tensor<4> {
    let data: Vec<f32> = (0..c).flat_map(|_| k.iter().map(|&v| v as f32)).collect();
    let n = k.len();
    let kx = Tensor::<4>::from_data(TensorData::new(data.clone(), [c, 1, 1, n]), device);
    let ky = Tensor::<4>::from_data(TensorData::new(data, [c, 1, n, 1]), device);
    let h = conv2d(x, kx, None, ConvOptions::new([1, 1], [0, 0], [1, 1], c));
    conv2d(h, ky, None, ConvOptions::new([1, 1], [0, 0], [1, 1], c))
}

/// `1 - SSIM(out, target)`: the structure term that stands in for the VGG19 perceptual loss
/// when no VGG19 weights are available. The output is clamped to [0, 1] first, the range SSIM's
/// constants assume.
pub fn ssim_loss(out: Tensor<4>, target: Tensor<4>) -> Tensor<1> {
    ssim(out.clamp(0.0, 1.0), target).neg() + 1.0
}

impl Vgg19Features {
    /// The VGG19 perceptual loss of the released `loss/perceptual.py`: `sum over cuts of
    /// 0.2 * L1(cut(out), cut(target))` over [`Vgg19Features::cuts`], the target's features
    /// detached. (Here with the other losses, so that [`crate::vgg`] needs nothing from them.)
    pub fn perceptual_loss(&self, out: Tensor<4>, target: Tensor<4>) -> Tensor<1> {
        let a = self.cuts(out);
        let b = self.cuts(target.detach());
        let mut total: Option<Tensor<1>> = None;
        for (fa, fb) in a.into_iter().zip(b) {
            let term = l1(fa, fb.detach()) * CUT_WEIGHT;
            total = Some(match total {
                Some(t) => t + term,
                None => term,
            });
        }
        total.unwrap_or_else(|| Tensor::zeros([1], &Device::default()))
    }
}

/// The perceptual term's implementation.
#[derive(Debug)]
pub enum Perceptual {
    /// VGG19 features (the paper's term).
    Vgg(Box<Vgg19Features>),
    /// `1 - SSIM` stand-in.
    Ssim,
    /// No perceptual term.
    Off,
}

impl Perceptual {
    /// A short name for logs.
    #[must_use]
    pub fn describe(&self) -> &'static str {
        match self {
            Self::Vgg(_) => "VGG19 perceptual (features[:1,:3,:5,:9,:13], 0.2 each, L1)",
            Self::Ssim => {
                "1 - SSIM (11x11 Gaussian window), standing in for the VGG19 perceptual term"
            }
            Self::Off => "none",
        }
    }
}

/// Loss term values of one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LossValues {
    /// Unweighted L1 reconstruction.
    pub reconstruction: f64,
    /// Unweighted perceptual term (or its stand-in).
    pub perceptual: f64,
    /// Unweighted dark-channel term.
    pub dark_channel: f64,
    /// Unweighted light-field term.
    pub light_field: f64,
    /// Weighted sum (what is minimised).
    pub total: f64,
}

impl LossValues {
    /// The values as an array in CSV column order.
    #[must_use]
    pub fn as_array(&self) -> [f64; 5] {
        [
            self.reconstruction,
            self.perceptual,
            self.dark_channel,
            self.light_field,
            self.total,
        ]
    }

    /// The values from a slice in CSV column order (as [`Self::as_array`] gives them); missing
    /// values are NaN.
    #[must_use]
    pub fn from_slice(v: &[f64]) -> Self {
        let g = |i: usize| v.get(i).copied().unwrap_or(f64::NAN);
        Self {
            reconstruction: g(0),
            perceptual: g(1),
            dark_channel: g(2),
            light_field: g(3),
            total: g(4),
        }
    }

    /// Whether every value is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.as_array().iter().all(|v| v.is_finite())
    }
}

/// The weighted training objective.
#[derive(Debug)]
pub struct Criterion {
    /// Term weights.
    pub weights: LossWeights,
    /// Light-field variant.
    pub light_field: LightFieldLoss,
    /// Dark-channel window.
    pub window: usize,
    /// Perceptual term.
    pub perceptual: Perceptual,
}

/// The loss of one batch: the tensor to differentiate and the terms, detached.
pub struct LossOutput {
    /// Weighted total, `[1]`.
    pub total: Tensor<1>,
    /// `[5]`: reconstruction, perceptual, dark channel, light field, total (unweighted terms).
    pub terms: Tensor<1>,
}

impl Criterion {
    /// The objective of `cfg`; `vgg` is used for the perceptual term when given, otherwise
    /// `cfg.perceptual_fallback`.
    #[must_use]
    pub fn new(cfg: &TrainConfig, vgg: Option<Vgg19Features>) -> Self {
        let perceptual = match (vgg, cfg.perceptual_fallback) {
            (Some(v), _) => Perceptual::Vgg(Box::new(v)),
            (None, PerceptualFallback::Ssim) => Perceptual::Ssim,
            (None, PerceptualFallback::None) => Perceptual::Off,
        };
        Self {
            weights: cfg.loss,
            light_field: cfg.light_field_loss,
            window: cfg.dark_channel_window,
            perceptual,
        }
    }

    /// The loss of `out` against `target`; terms with weight 0 are not computed (reported 0).
    ///
    /// # Shapes
    /// - `out`, `target`: `[b, 3, h, w]`
    pub fn forward(&self, out: Tensor<4>, target: Tensor<4>) -> LossOutput {
        let device = out.device();
        let zero = || Tensor::<1>::zeros([1], &device);
        let w = self.weights;
        let rec = l1(out.clone(), target.clone());
        let per = match (&self.perceptual, w.perceptual > 0.0) {
            (Perceptual::Vgg(v), true) => v.perceptual_loss(out.clone(), target.clone()),
            (Perceptual::Ssim, true) => ssim_loss(out.clone(), target.clone()),
            _ => zero(),
        };
        let dc = if w.dark_channel > 0.0 {
            dark_channel_loss(out.clone(), target.clone(), self.window)
        } else {
            zero()
        };
        let lf = if w.light_field > 0.0 {
            light_field_loss(out, target, self.light_field)
        } else {
            zero()
        };
        let total = rec.clone() * w.reconstruction
            + per.clone() * w.perceptual
            + dc.clone() * w.dark_channel
            + lf.clone() * w.light_field;
        let terms = Tensor::cat(
            vec![
                rec.detach(),
                per.detach(),
                dc.detach(),
                lf.detach(),
                total.clone().detach(),
            ],
            0,
        );
        LossOutput { total, terms }
    }
}

/// Reads the `[5]` term tensor of [`LossOutput`].
pub fn read_terms(terms: Tensor<1>) -> crate::error::Result<LossValues> {
    let v = terms.into_data().try_to_vec::<f32>().map_err(|e| {
        crate::error::TrainError::Model(uwnr_model::ModelError::Backend(format!(
            "reading loss values: {e:?}"
        )))
    })?;
    let g = |i: usize| v.get(i).copied().map_or(f64::NAN, f64::from);
    Ok(LossValues {
        reconstruction: g(0),
        perceptual: g(1),
        dark_channel: g(2),
        light_field: g(3),
        total: g(4),
    })
}
