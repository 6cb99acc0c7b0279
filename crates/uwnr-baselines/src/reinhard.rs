//! Colour transfer of Reinhard, Ashikhmin, Gooch, Shirley 2001 ("Color transfer between images",
//! IEEE CG&A 21(5)): in a decorrelated colour space, each channel of the source is shifted and
//! scaled to the mean and standard deviation of the target,
//!
//! `x' = (x − μ_src)·(σ_ref/σ_src) + μ_ref`,
//!
//! here with the clean image as source and the underwater reference as target. Depth is unused and
//! nothing is random.
//!
//! Spaces ([`ColourSpace`]):
//! - **lαβ** (default, the paper's): Ruderman et al.'s space, RGB → LMS → log10 → decorrelating
//!   rotation ([`uwnr_core::color::rgb_to_lalphabeta_px`]), applied to the stored (gamma-encoded)
//!   RGB values as the paper does with its images. LMS values are floored at 1/255 before the
//!   logarithm, so a black pixel counts as the darkest non-zero 8-bit level instead of −∞.
//! - **Lab**: CIE L\*a\*b\* (D65) as scikit-image computes it ([`uwnr_core::color::rgb_to_lab_px`]),
//!   the space most open implementations use through OpenCV's `COLOR_BGR2LAB` (which differs from
//!   CIELAB only by its 8-bit scaling, which mean/std matching is invariant to, and its
//!   quantisation).
//!
//! The result is clipped to [0, 1]. A source channel with (almost) no spread is only shifted.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::json;
use uwnr_core::Image;
use uwnr_core::color::{lab_to_rgb_px, lalphabeta_to_rgb_px, rgb_to_lab_px, rgb_to_lalphabeta_px};

use crate::common::{check_image, round6_3};
use crate::error::{BaselineError, Result};
use crate::{RenderInput, Rendered};

/// Floor of the LMS values before log10: one 8-bit code value.
pub const LALPHABETA_FLOOR: f64 = 1.0 / 255.0;
/// Below this standard deviation a source channel is treated as constant (only shifted).
const MIN_STD: f64 = 1e-9;
/// Pixels per parallel work item.
const PAR_CHUNK: usize = 4096;

/// The colour space the statistics are matched in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ColourSpace {
    /// Ruderman's lαβ, as in the paper (default).
    #[default]
    #[serde(rename = "lalphabeta")]
    LAlphaBeta,
    /// CIE L\*a\*b\* (D65), as OpenCV-based implementations do it.
    Lab,
}

impl ColourSpace {
    fn forward(self, rgb: [f64; 3]) -> [f64; 3] {
        match self {
            Self::LAlphaBeta => rgb_to_lalphabeta_px(rgb, LALPHABETA_FLOOR),
            Self::Lab => rgb_to_lab_px(rgb),
        }
    }

    fn inverse(self, v: [f64; 3]) -> [f64; 3] {
        match self {
            Self::LAlphaBeta => lalphabeta_to_rgb_px(v),
            Self::Lab => lab_to_rgb_px(v),
        }
    }
}

/// Parameters of the colour transfer.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReinhardParams {
    /// The space the statistics are matched in.
    pub space: ColourSpace,
}

/// Pixels of `img` converted to `space`, interleaved.
fn convert(img: &Image, space: ColourSpace) -> Vec<[f64; 3]> {
    let (r, g, b) = (img.plane(0), img.plane(1), img.plane(2));
    (0..r.len())
        .into_par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|i| space.forward([f64::from(r[i]), f64::from(g[i]), f64::from(b[i])]))
        .collect()
}

/// Per-channel mean and population standard deviation.
fn stats(px: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let n = px.len() as f64;
    let mut mean = [0.0; 3];
    for p in px {
        for c in 0..3 {
            mean[c] += p[c];
        }
    }
    mean = mean.map(|m| m / n);
    let mut var = [0.0; 3];
    for p in px {
        for c in 0..3 {
            var[c] += (p[c] - mean[c]).powi(2);
        }
    }
    (mean, var.map(|v| (v / n).sqrt()))
}

/// Transfers the colour statistics of `reference` onto `clean` in `space`.
pub fn transfer(clean: &Image, reference: &Image, space: ColourSpace) -> Result<Image> {
    check_image(clean, "clean image", 3)?;
    check_image(reference, "reference", 3)?;
    let src = convert(clean, space);
    let (mu_s, sd_s) = stats(&src);
    let (mu_t, sd_t) = stats(&convert(reference, space));
    let gain: [f64; 3] = std::array::from_fn(|c| if sd_s[c] > MIN_STD { sd_t[c] / sd_s[c] } else { 1.0 });
    let rgb: Vec<[f64; 3]> = src
        .into_par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|p| space.inverse(std::array::from_fn(|c| (p[c] - mu_s[c]) * gain[c] + mu_t[c])))
        .collect();
    let (w, h) = clean.size();
    let n = w * h;
    let mut data = vec![0.0f32; 3 * n];
    for (i, p) in rgb.iter().enumerate() {
        for c in 0..3 {
            data[c * n + i] = p[c].clamp(0.0, 1.0) as f32;
        }
    }
    Ok(Image::from_planar(w, h, 3, data)?)
}

/// Renders `input.clean` with the colours of `input.reference` (required).
pub(crate) fn render(params: &ReinhardParams, input: &RenderInput) -> Result<Rendered> {
    let reference = input.reference.ok_or(BaselineError::MissingReference { method: "reinhard" })?;
    let image = transfer(input.clean, reference, params.space)?;
    let (mu_t, sd_t) = stats(&convert(reference, params.space));
    let params_json = json!({
        "method": "reinhard",
        "space": params.space,
        "reference_mean": round6_3(mu_t),
        "reference_std": round6_3(sd_t),
    });
    Ok(Rendered {
        image,
        params: params_json,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: usize, h: usize, tint: [f32; 3]) -> Image {
        let n = w * h;
        let data: Vec<f32> = (0..3)
            .flat_map(|c| (0..n).map(move |i| (0.1 + 0.8 * i as f32 / n as f32) * tint[c]))
            .collect();
        Image::from_planar(w, h, 3, data).unwrap()
    }

    #[test]
    fn output_has_the_reference_statistics() {
        let clean = gradient(16, 16, [1.0, 0.9, 0.7]);
        let reference = gradient(8, 8, [0.2, 0.6, 0.9]);
        for space in [ColourSpace::LAlphaBeta, ColourSpace::Lab] {
            let out = transfer(&clean, &reference, space).unwrap();
            let (mo, so) = stats(&convert(&out, space));
            let (mr, sr) = stats(&convert(&reference, space));
            for c in 0..3 {
                let tol_m = 1e-3 * (1.0 + mr[c].abs());
                assert!((mo[c] - mr[c]).abs() < tol_m, "{space:?} mean {mo:?} vs {mr:?}");
                assert!((so[c] - sr[c]).abs() < 1e-3 * (1.0 + sr[c]), "{space:?} std {so:?} vs {sr:?}");
            }
        }
    }

    #[test]
    fn self_transfer_is_identity() {
        let img = gradient(8, 8, [0.9, 0.5, 0.3]);
        for space in [ColourSpace::LAlphaBeta, ColourSpace::Lab] {
            let out = transfer(&img, &img, space).unwrap();
            for (a, b) in out.data().iter().zip(img.data()) {
                assert!((a - b).abs() < 2e-3, "{space:?}: {a} vs {b}");
            }
        }
    }
}
