//! The differentiable underwater image-formation layer of the GAN baseline:
//! `I = k · V(r) · S_w( J · t + B · (1 − t) )` with `t = exp(−β · d)`, on burn tensors, so the
//! discriminator's gradient flows back into the predicted parameters. Rendering uses the same
//! layer on images, without burn (`uwnr_gan::imaging`); the tests compare the two.
//!
//! # The stages
//!
//! 1. **Attenuation** (WaterGAN stage 1, UWGAN's `g_atten`): per-channel transmission
//!    `t_c = exp(−β_c · d)` with `d` in metres (`d = depth · range_m`, see
//!    [`ImagingConfig::range_m`]) and `β_c ≥ 0` per metre; the direct signal is `J · t`.
//! 2. **Backscatter / veiling light** (the paper's Eq. 1, `I = J t + B (1 − t)`): a veiling
//!    light `B_c ∈ [0, 1]` per image and channel, weighted by `1 − t_c`, so it grows with
//!    distance.
//! 3. **Optics blur** (optional, [`ImagingConfig::blur`]): `S_w(x) = (1 − w) x + w · G(x)` with
//!    `G` a normalised 3x3 binomial blur and `w ∈ [0, 1]` predicted.
//! 4. **Camera** (WaterGAN stage 3): radial vignetting
//!    `V(r) = 1 + a r² + b r⁴ + c r⁶` (r = 0 at the centre, 1 at the corners) and a global gain `k`.
//!
//! # What is reproduced and what is simplified
//!
//! Reproduced from WaterGAN (Li et al. 2017, RA-L 2018) and UWGAN (Wang et al. 2019, whose
//! released generator `wc_generator` starts from WaterGAN's code):
//! - the generator's structure as a chain of physical stages (attenuation, scattering, camera)
//!   whose parameters are learnt adversarially from unpaired real underwater images, conditioned
//!   on an in-air image, its depth and a noise code `z`;
//! - per-channel exponential attenuation with depth, `exp(−η_c d)`, and the depth-dependent
//!   veiling term `(1 − exp(−η d))` of UWGAN's "improved" model;
//! - the camera stage of the WaterGAN paper: a radial vignetting polynomial in `r²`, `r⁴`, `r⁶`
//!   (coefficients a, b, c) and a scale `k`, as summaries of the paper describe it (the paper's
//!   own equation could not be checked from here; the form is the standard even polynomial of
//!   the vignetting literature); the scale is also UWGAN's `g_tol`, initialised to 0.9
//!   ([`GAIN_INIT`]);
//! - UWGAN's initial attenuation coefficients ([`UWGAN_BETA_INIT`]).
//!
//! Simplified or changed (the baseline is "in the manner of", not a reproduction):
//! - **Parameters are predicted per image by a small network** (see [`crate::model`]) instead
//!   of being global learnt variables (UWGAN's `g_eta_r/g/b`, `g_amp`, `g_tol`): one trained
//!   generator renders many waters, chosen by `z`.
//! - **Backscatter is `B (1 − t)` with one veiling light per image and channel.** WaterGAN and
//!   UWGAN instead project `z` with a dense layer to a full-resolution map, multiply it by
//!   depth and convolve it (5x5) per channel; that dense layer has `|z| · H · W` weights, which
//!   ties the network to one image size (48x64 in WaterGAN, 256x256 in UWGAN). UWGAN's extra
//!   haze term, `255 A (1 − e^(−0.75 d)) e^(−η d)` with a fixed 0.75, is not reproduced:
//!   `B (1 − t)` is the only veiling term.
//! - **Constraints are built into the parameterisation** (bounded sigmoids, [`WaterParams::from_raw`])
//!   instead of WaterGAN/UWGAN's penalty terms (`−min(η, 0) · 10⁴` added to the generator
//!   loss). The vignetting coefficients are kept in `[−VIGNETTE_MAX, 0]`, so `V` falls off
//!   monotonically from 1 at the centre and stays above `1 − 3 · VIGNETTE_MAX` at the corners;
//!   WaterGAN's released code replaces the polynomial by a fixed 2-D Gaussian profile scaled by
//!   a learnt amplitude, which we do not follow.
//! - **Depth is uwnr's relative depth** ([0, 1], larger = farther, see `uwnr-depth`) scaled to
//!   metres by one constant, where UWGAN reads NYU's metric depth directly.
//! - **Vignetting is centred on the image (or training crop) it is applied to**; WaterGAN trains
//!   on whole frames.
//! - **The blur is ours** (neither paper has one): a stand-in for forward scattering and
//!   defocus, off by default.
//!
//! With `J, B ∈ [0, 1]`, `t ∈ (0, 1]`, `V ∈ (0, 1]` and `k ∈ [GAIN_MIN, GAIN_MAX] ⊂ (0, 1]`, the
//! render stays in [0, 1] with no clamp, so no gradient is cut.

use burn::tensor::activation::sigmoid;
use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;
use burn::tensor::{Device, Tensor, TensorData};
pub use uwnr_gan::config::{
    BACKLIGHT_INIT, BETA_MAX, BINOMIAL, BLUR_INIT, DEFAULT_RANGE_M, GAIN_INIT, GAIN_MAX, GAIN_MIN,
    ImagingConfig, RAW_PARAMS, RGB, UWGAN_BETA_INIT, VIGNETTE_INIT, VIGNETTE_MAX, initial_raw,
};

use crate::error::{GanError, Result};

/// The image-formation parameters of a batch, one set per image, already in their physical
/// ranges.
#[derive(Clone, Debug)]
pub struct WaterParams {
    /// Attenuation per metre, R, G, B, in `[0, BETA_MAX]`: `[b, 3]`.
    pub beta: Tensor<2>,
    /// Veiling light, R, G, B, in `[0, 1]`: `[b, 3]`.
    pub backlight: Tensor<2>,
    /// Vignetting coefficients `(a, b, c)` of `r², r⁴, r⁶`, each in `[−VIGNETTE_MAX, 0]`: `[b, 3]`.
    pub vignette: Tensor<2>,
    /// Camera gain `k` in `[GAIN_MIN, GAIN_MAX]`: `[b, 1]`.
    pub gain: Tensor<2>,
    /// Blur weight `w` in `[0, 1]`: `[b, 1]`.
    pub blur: Tensor<2>,
}

impl WaterParams {
    /// Maps the head's raw outputs to the parameters' ranges with sigmoids:
    /// `β = BETA_MAX σ(x₀..₃)`, `B = σ(x₃..₆)`, `(a, b, c) = −VIGNETTE_MAX σ(x₆..₉)`,
    /// `k = GAIN_MIN + (GAIN_MAX − GAIN_MIN) σ(x₉)`, `w = σ(x₁₀)`.
    ///
    /// # Shapes
    /// - `raw`: `[b, RAW_PARAMS]`
    pub fn from_raw(raw: Tensor<2>) -> Self {
        let [b, _] = raw.dims();
        let s = sigmoid(raw);
        Self {
            beta: s.clone().slice([0..b, 0..3]) * BETA_MAX,
            backlight: s.clone().slice([0..b, 3..6]),
            vignette: s.clone().slice([0..b, 6..9]) * (-VIGNETTE_MAX),
            gain: s.clone().slice([0..b, 9..10]) * (GAIN_MAX - GAIN_MIN) + GAIN_MIN,
            blur: s.slice([0..b, 10..11]),
        }
    }

    /// Parameters given directly (for tests and hand-set renders), each `[b, n]` on `device`.
    ///
    /// # Shapes
    /// - every argument is one row per image: `beta`, `backlight`, `vignette` have 3 values,
    ///   `gain` and `blur` 1
    pub fn from_values(
        beta: &[[f32; 3]],
        backlight: &[[f32; 3]],
        vignette: &[[f32; 3]],
        gain: &[f32],
        blur: &[f32],
        device: &Device,
    ) -> Result<Self> {
        let b = beta.len();
        for (what, n) in [
            ("backlight rows", backlight.len()),
            ("vignette rows", vignette.len()),
            ("gain rows", gain.len()),
            ("blur rows", blur.len()),
        ] {
            if n != b {
                return Err(GanError::ShapeMismatch {
                    what,
                    expected: vec![b],
                    got: vec![n],
                });
            }
        }
        let rows3 = |v: &[[f32; 3]]| {
            Tensor::<2>::from_data(
                TensorData::new(v.iter().flatten().copied().collect::<Vec<f32>>(), [b, 3]),
                device,
            )
        };
        let rows1 = |v: &[f32]| Tensor::<2>::from_data(TensorData::new(v.to_vec(), [b, 1]), device);
        Ok(Self {
            beta: rows3(beta),
            backlight: rows3(backlight),
            vignette: rows3(vignette),
            gain: rows1(gain),
            blur: rows1(blur),
        })
    }
}

/// `[b, n]` per-image values as `[b, n, 1, 1]`, to broadcast over pixels.
fn per_pixel(v: Tensor<2>) -> Tensor<4> {
    let [b, n] = v.dims();
    v.reshape([b, n, 1, 1])
}

/// Transmission `t_c = exp(−β_c · d)`.
///
/// # Shapes
/// - `depth_m`: `[b, 1, h, w]`, metres; `beta`: `[b, 3]`, per metre; output `[b, 3, h, w]`
#[must_use]
pub fn transmission(depth_m: Tensor<4>, beta: Tensor<2>) -> Tensor<4> {
    (per_pixel(beta) * depth_m).neg().exp() // [b, 3, h, w]
}

/// The water stage, `J t + B (1 − t)`.
///
/// # Shapes
/// - `clean`, `t`: `[b, 3, h, w]`; `backlight`: `[b, 3]`; output `[b, 3, h, w]`
#[must_use]
pub fn water(clean: Tensor<4>, t: Tensor<4>, backlight: Tensor<2>) -> Tensor<4> {
    let veil = t.clone().neg() + 1.0; // 1 - t
    clean * t + veil * per_pixel(backlight)
}

/// Squared normalised radius `r²` of every pixel of an `h x w` image: 0 at the centre (between
/// pixels for even sizes), 1 at the corner pixels' centres. A single pixel has `r = 0`.
///
/// # Shapes
/// - output `[1, 1, h, w]`
#[must_use]
pub fn radius_squared(h: usize, w: usize, device: &Device) -> Tensor<4> {
    let (cy, cx) = ((h as f64 - 1.0) / 2.0, (w as f64 - 1.0) / 2.0);
    let norm = cx * cx + cy * cy;
    let values: Vec<f32> = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                if norm > 0.0 {
                    ((dx * dx + dy * dy) / norm) as f32
                } else {
                    0.0
                }
            })
        })
        .collect();
    Tensor::<4>::from_data(TensorData::new(values, [1, 1, h, w]), device)
}

/// WaterGAN's vignetting profile `V(r) = 1 + a r² + b r⁴ + c r⁶`.
///
/// # Shapes
/// - `coeffs`: `[b, 3]` (a, b, c); output `[b, 1, h, w]`
#[must_use]
pub fn vignette_profile(coeffs: Tensor<2>, h: usize, w: usize) -> Tensor<4> {
    let [b, _] = coeffs.dims();
    let r2 = radius_squared(h, w, &coeffs.device()); // [1, 1, h, w]
    let r4 = r2.clone() * r2.clone();
    let r6 = r4.clone() * r2.clone();
    let c = |i: usize| coeffs.clone().slice([0..b, i..i + 1]).reshape([b, 1, 1, 1]);
    r2 * c(0) + r4 * c(1) + r6 * c(2) + 1.0 // [b, 1, h, w]
}

/// The optics blur `S_w(x) = (1 − w) x + w G(x)`: `G` is the 3x3 binomial kernel
/// (`[1 2 1]ᵀ[1 2 1] / 16`) applied per channel and renormalised at the border by the kernel
/// weight inside the image (a normalised convolution), so a flat image stays flat.
///
/// # Shapes
/// - `image`: `[b, c, h, w]`; `weight`: `[b, 1]`; output `[b, c, h, w]`
#[must_use]
pub fn blur(image: Tensor<4>, weight: Tensor<2>) -> Tensor<4> {
    let [_, c, h, w] = image.dims();
    let device = image.device();
    let k: Vec<f32> = BINOMIAL
        .iter()
        .flat_map(|a| BINOMIAL.iter().map(move |b| a * b / 16.0))
        .collect();
    let kernel = |channels: usize| {
        let data: Vec<f32> = (0..channels).flat_map(|_| k.iter().copied()).collect();
        Tensor::<4>::from_data(TensorData::new(data, [channels, 1, 3, 3]), &device)
    };
    let opts = |groups: usize| ConvOptions::new([1, 1], [1, 1], [1, 1], groups);
    let blurred = conv2d(image.clone(), kernel(c), None, opts(c)); // [b, c, h, w]
    let ones = Tensor::<4>::ones([1, 1, h, w], &device);
    let support = conv2d(ones, kernel(1), None, opts(1)); // [1, 1, h, w]
    let g = blurred / support;
    let wt = per_pixel(weight); // [b, 1, 1, 1]
    image * (wt.clone().neg() + 1.0) + g * wt
}

/// Renders the batch: `k · V(r) · S_w(J t + B (1 − t))`, `t = exp(−β · depth · range_m)`
/// (the blur only when `config.blur`).
///
/// # Shapes
/// - `clean`: `[b, 3, h, w]` in [0, 1]; `depth`: `[b, 1, h, w]` in [0, 1] (larger = farther);
///   output `[b, 3, h, w]` in [0, 1]
pub fn render(
    clean: Tensor<4>,
    depth: Tensor<4>,
    params: &WaterParams,
    config: &ImagingConfig,
) -> Result<Tensor<4>> {
    let [b, c, h, w] = clean.dims();
    if c != RGB {
        return Err(GanError::ShapeMismatch {
            what: "clean image channels",
            expected: vec![RGB],
            got: vec![c],
        });
    }
    if depth.dims() != [b, 1, h, w] {
        return Err(GanError::ShapeMismatch {
            what: "depth map shape",
            expected: vec![b, 1, h, w],
            got: depth.dims().to_vec(),
        });
    }
    let pb = params.beta.dims()[0];
    if pb != b {
        return Err(GanError::ShapeMismatch {
            what: "parameter rows",
            expected: vec![b],
            got: vec![pb],
        });
    }
    let t = transmission(depth * config.range_m, params.beta.clone()); // [b, 3, h, w]
    let mut out = water(clean, t, params.backlight.clone());
    if config.blur {
        out = blur(out, params.blur.clone());
    }
    let v = vignette_profile(params.vignette.clone(), h, w); // [b, 1, h, w]
    Ok(out * v * per_pixel(params.gain.clone()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::to_vec;

    fn dev() -> Device {
        Device::flex()
    }

    fn close(got: &[f32], want: &[f32], tol: f32) {
        assert_eq!(got.len(), want.len());
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() <= tol, "element {i}: got {g}, want {w}");
        }
    }

    fn params(beta: [f32; 3], b: [f32; 3], vig: [f32; 3], k: f32, w: f32) -> WaterParams {
        WaterParams::from_values(&[beta], &[b], &[vig], &[k], &[w], &dev()).unwrap()
    }

    #[test]
    fn attenuation_and_backscatter_match_hand_values() {
        // One pixel, J = (0.8, 0.6, 0.4), relative depth 0.2 -> 2 m; beta = (0.5, 0.1, 0) /m;
        // B = (0.1, 0.5, 0.7); no vignetting (r = 0 for one pixel anyway), k = 1.
        let d = dev();
        let clean =
            Tensor::<4>::from_data(TensorData::new(vec![0.8_f32, 0.6, 0.4], [1, 3, 1, 1]), &d);
        let depth = Tensor::<4>::from_data(TensorData::new(vec![0.2_f32], [1, 1, 1, 1]), &d);
        let p = params([0.5, 0.1, 0.0], [0.1, 0.5, 0.7], [0.0; 3], 1.0, 0.0);
        let out = to_vec(render(clean, depth, &p, &ImagingConfig::default()).unwrap()).unwrap();
        // t = exp(-1) = 0.367879, exp(-0.2) = 0.818731, 1.
        let t = [(-1.0_f32).exp(), (-0.2_f32).exp(), 1.0];
        let want: Vec<f32> = (0..3)
            .map(|c| [0.8, 0.6, 0.4][c] * t[c] + [0.1, 0.5, 0.7][c] * (1.0 - t[c]))
            .collect();
        close(&out, &want, 1e-6);
        // Written out: R = 0.8 * 0.367879 + 0.1 * 0.632121 = 0.357515.
        close(&out[..1], &[0.357_515], 1e-5);
        // The gain scales everything.
        let clean =
            Tensor::<4>::from_data(TensorData::new(vec![0.8_f32, 0.6, 0.4], [1, 3, 1, 1]), &d);
        let depth = Tensor::<4>::zeros([1, 1, 1, 1], &d);
        let p = params([0.5, 0.1, 0.0], [0.1, 0.5, 0.7], [0.0; 3], 0.5, 0.0);
        let out = to_vec(render(clean, depth, &p, &ImagingConfig::default()).unwrap()).unwrap();
        close(&out, &[0.4, 0.3, 0.2], 1e-6);
    }

    #[test]
    fn vignetting_is_one_at_the_centre_and_the_polynomial_at_the_corners() {
        // 3x3: centre r = 0, corners r = 1, edge midpoints r^2 = 1/2.
        let r2 = to_vec(radius_squared(3, 3, &dev())).unwrap();
        close(&r2, &[1.0, 0.5, 1.0, 0.5, 0.0, 0.5, 1.0, 0.5, 1.0], 1e-6);
        let coeffs =
            Tensor::<2>::from_data(TensorData::new(vec![-0.2_f32, -0.1, -0.05], [1, 3]), &dev());
        let v = to_vec(vignette_profile(coeffs, 3, 3)).unwrap();
        let edge = 1.0 - 0.2 * 0.5 - 0.1 * 0.25 - 0.05 * 0.125; // 0.86875
        let corner = 1.0 - 0.2 - 0.1 - 0.05; // 0.65
        close(
            &v,
            &[corner, edge, corner, edge, 1.0, edge, corner, edge, corner],
            1e-6,
        );
        // 2x2: every pixel is a corner.
        let r2 = to_vec(radius_squared(2, 2, &dev())).unwrap();
        close(&r2, &[1.0; 4], 1e-6);
        assert_eq!(to_vec(radius_squared(1, 1, &dev())).unwrap(), vec![0.0]);
    }

    #[test]
    fn blur_keeps_flat_images_and_spreads_a_point_binomially() {
        let d = dev();
        let flat = Tensor::<4>::ones([1, 3, 4, 5], &d) * 0.3;
        let w = Tensor::<2>::ones([1, 1], &d);
        close(&to_vec(blur(flat, w.clone())).unwrap(), &[0.3; 60], 1e-6);
        // A unit impulse at the centre of 3x3, full blur: the binomial kernel itself.
        let mut v = vec![0.0_f32; 9];
        v[4] = 1.0;
        let x = Tensor::<4>::from_data(TensorData::new(v, [1, 1, 3, 3]), &d);
        let got = to_vec(blur(x.clone(), w)).unwrap();
        // Centre 4/16; edge midpoints: 2/16 of the impulse over the kernel weight inside the
        // image (12/16 at an edge midpoint) = 1/6; corners: 1/16 over 9/16 = 1/9.
        let (e, c) = (2.0 / 12.0, 1.0 / 9.0);
        close(&got, &[c, e, c, e, 0.25, e, c, e, c], 1e-6);
        // Half weight blends half-way.
        let half = Tensor::<2>::ones([1, 1], &d) * 0.5;
        let got = to_vec(blur(x, half)).unwrap();
        close(&got[4..5], &[0.5 * 1.0 + 0.5 * 0.25], 1e-6);
    }

    #[test]
    fn raw_zero_maps_to_mid_ranges_and_initial_raw_to_the_initial_values() {
        let d = dev();
        let p = WaterParams::from_raw(Tensor::<2>::zeros([2, RAW_PARAMS], &d));
        close(&to_vec(p.beta).unwrap(), &[0.75; 6], 1e-6);
        close(&to_vec(p.backlight).unwrap(), &[0.5; 6], 1e-6);
        close(&to_vec(p.vignette).unwrap(), &[-0.15; 6], 1e-6);
        close(&to_vec(p.gain).unwrap(), &[0.75; 2], 1e-6);
        close(&to_vec(p.blur).unwrap(), &[0.5; 2], 1e-6);
        let raw =
            Tensor::<2>::from_data(TensorData::new(initial_raw().to_vec(), [1, RAW_PARAMS]), &d);
        let p = WaterParams::from_raw(raw);
        close(&to_vec(p.beta).unwrap(), &UWGAN_BETA_INIT, 1e-5);
        close(&to_vec(p.vignette).unwrap(), &[VIGNETTE_INIT; 3], 1e-6);
        close(&to_vec(p.gain).unwrap(), &[GAIN_INIT], 1e-6);
        close(&to_vec(p.blur).unwrap(), &[BLUR_INIT], 1e-6);
    }

    #[test]
    fn renders_stay_in_the_unit_range_at_the_parameter_extremes() {
        let d = dev();
        let clean = Tensor::<4>::ones([2, 3, 5, 6], &d);
        let depth = Tensor::<4>::ones([2, 1, 5, 6], &d);
        let cfg = ImagingConfig {
            blur: true,
            ..ImagingConfig::default()
        };
        for x in [-30.0_f32, 0.0, 30.0] {
            let p = WaterParams::from_raw(Tensor::<2>::ones([2, RAW_PARAMS], &d) * x);
            let out = to_vec(render(clean.clone(), depth.clone(), &p, &cfg).unwrap()).unwrap();
            assert!(
                out.iter().all(|v| (0.0..=1.0).contains(v) && v.is_finite()),
                "raw {x}"
            );
        }
    }

    #[test]
    fn mismatched_inputs_are_refused() {
        let d = dev();
        let p = params([0.1; 3], [0.5; 3], [0.0; 3], 1.0, 0.0);
        let cfg = ImagingConfig::default();
        let err = render(
            Tensor::zeros([1, 3, 4, 4], &d),
            Tensor::zeros([1, 1, 4, 5], &d),
            &p,
            &cfg,
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                GanError::ShapeMismatch {
                    what: "depth map shape",
                    ..
                }
            ),
            "{err}"
        );
        let err = render(
            Tensor::zeros([2, 3, 4, 4], &d),
            Tensor::zeros([2, 1, 4, 4], &d),
            &p,
            &cfg,
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                GanError::ShapeMismatch {
                    what: "parameter rows",
                    ..
                }
            ),
            "{err}"
        );
        assert!(
            WaterParams::from_values(&[[0.0; 3]], &[], &[[0.0; 3]], &[1.0], &[0.0], &d).is_err()
        );
    }
}
