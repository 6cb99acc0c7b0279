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
//! - **RGB**: the stored values; with `match_std: false` this is the per-channel mean shift
//!   `x' = x − μ_src + μ_ref`, the simplest statistical baseline.
//!
//! The result is clipped to [0, 1]. A source channel with (almost) no spread is only shifted.

use crate::record::{BaselineRecord, ReinhardRecord};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
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
    /// The stored RGB values themselves (with `match_std: false`, the plain per-channel mean
    /// shift that serves as the simplest baseline).
    Rgb,
}

impl ColourSpace {
    fn forward(self, rgb: [f64; 3]) -> [f64; 3] {
        match self {
            Self::LAlphaBeta => rgb_to_lalphabeta_px(rgb, LALPHABETA_FLOOR),
            Self::Lab => rgb_to_lab_px(rgb),
            Self::Rgb => rgb,
        }
    }

    fn inverse(self, v: [f64; 3]) -> [f64; 3] {
        match self {
            Self::LAlphaBeta => lalphabeta_to_rgb_px(v),
            Self::Lab => lab_to_rgb_px(v),
            Self::Rgb => v,
        }
    }
}

/// Parameters of the colour transfer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReinhardParams {
    /// The space the statistics are matched in.
    pub space: ColourSpace,
    /// Scale each channel to the reference's standard deviation (Reinhard); `false` only shifts
    /// the means.
    pub match_std: bool,
}

impl Default for ReinhardParams {
    fn default() -> Self {
        Self {
            space: ColourSpace::default(),
            match_std: true,
        }
    }
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

/// Per-channel mean and population standard deviation of an image in a colour space.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChannelStats {
    /// Mean of each channel.
    pub mean: [f64; 3],
    /// Population standard deviation of each channel.
    pub std: [f64; 3],
}

/// Per-channel mean and population standard deviation of the pixels.
fn stats(px: &[[f64; 3]]) -> ChannelStats {
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
    ChannelStats {
        mean,
        std: var.map(|v| (v / n).sqrt()),
    }
}

/// `x' = (x − μ_src)·(σ_ref/σ_src) + μ_ref` per channel, with `(μ_ref, σ_ref) = target`; with
/// `match_std` false the gain is 1 (a mean shift).
fn match_statistics(src: Vec<[f64; 3]>, target: ChannelStats, match_std: bool) -> Vec<[f64; 3]> {
    let ChannelStats {
        mean: mu_s,
        std: sd_s,
    } = stats(&src);
    let ChannelStats {
        mean: mu_t,
        std: sd_t,
    } = target;
    let gain: [f64; 3] = std::array::from_fn(|c| {
        if match_std && sd_s[c] > MIN_STD {
            sd_t[c] / sd_s[c]
        } else {
            1.0
        }
    });
    src.into_par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|p| std::array::from_fn(|c| (p[c] - mu_s[c]) * gain[c] + mu_t[c]))
        .collect()
}

/// The transfer, returning the reference's statistics as well.
fn transfer_with_stats(
    clean: &Image,
    reference: &Image,
    space: ColourSpace,
    match_std: bool,
) -> Result<(Image, ChannelStats)> {
    check_image(clean, "clean image", 3)?;
    check_image(reference, "reference", 3)?;
    let target = stats(&convert(reference, space));
    let matched = match_statistics(convert(clean, space), target, match_std);
    Ok((to_image(clean, matched, space)?, target))
}

/// The statistics of `reference` in `space` that [`transfer`] matches.
pub fn reference_stats(reference: &Image, space: ColourSpace) -> Result<ChannelStats> {
    check_image(reference, "reference", 3)?;
    Ok(stats(&convert(reference, space)))
}

/// [`transfer`] to statistics computed before ([`reference_stats`]): the same result as
/// transferring to the image they came from.
pub fn transfer_to_stats(clean: &Image, target: ChannelStats, space: ColourSpace) -> Result<Image> {
    check_image(clean, "clean image", 3)?;
    let matched = match_statistics(convert(clean, space), target, true);
    to_image(clean, matched, space)
}

fn to_image(clean: &Image, matched: Vec<[f64; 3]>, space: ColourSpace) -> Result<Image> {
    let rgb: Vec<[f64; 3]> = matched
        .into_par_iter()
        .with_min_len(PAR_CHUNK)
        .map(|p| space.inverse(p))
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

/// Transfers the colour statistics of `reference` onto `clean` in `space`.
pub fn transfer(clean: &Image, reference: &Image, space: ColourSpace) -> Result<Image> {
    Ok(transfer_with_stats(clean, reference, space, true)?.0)
}

/// Renders `input.clean` with the colours of `input.reference` (required).
pub(crate) fn render(params: &ReinhardParams, input: &RenderInput) -> Result<Rendered> {
    let reference = input
        .reference
        .ok_or(BaselineError::MissingReference { method: "reinhard" })?;
    let (image, target) =
        transfer_with_stats(input.clean, reference, params.space, params.match_std)?;
    let params = BaselineRecord::Reinhard(ReinhardRecord {
        space: params.space,
        match_std: params.match_std,
        reference_mean: round6_3(target.mean),
        reference_std: round6_3(target.std),
    });
    Ok(Rendered { image, params })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb_mean_shift_moves_each_channel_by_the_mean_difference() {
        let clean = Image::from_planar(2, 1, 3, vec![0.2, 0.4, 0.5, 0.5, 0.1, 0.3]).unwrap();
        let reference = Image::from_planar(1, 1, 3, vec![0.6, 0.3, 0.4]).unwrap();
        let (out, _) = transfer_with_stats(&clean, &reference, ColourSpace::Rgb, false).unwrap();
        // Means 0.3, 0.5, 0.2 -> 0.6, 0.3, 0.4: shifts +0.3, -0.2, +0.2.
        let want = [0.5, 0.7, 0.3, 0.3, 0.3, 0.5];
        for (got, want) in out.data().iter().zip(want) {
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
        }
    }

    /// Round-trip error of a space: the paper's lαβ matrices (RGB→LMS and LMS→RGB, published to
    /// four decimals) are inverse only to about 0.7% (LMS→RGB·RGB→LMS has 0.0072 off the
    /// diagonal); CIELAB round-trips exactly.
    fn round_trip_tol(space: ColourSpace) -> f64 {
        match space {
            ColourSpace::LAlphaBeta => 8e-3,
            ColourSpace::Lab | ColourSpace::Rgb => 1e-4,
        }
    }

    fn gradient(w: usize, h: usize, tint: [f32; 3]) -> Image {
        let n = w * h;
        let data: Vec<f32> = (0..3)
            .flat_map(|c| (0..n).map(move |i| (0.1 + 0.8 * i as f32 / n as f32) * tint[c]))
            .collect();
        Image::from_planar(w, h, 3, data).unwrap()
    }

    #[test]
    fn matched_values_have_the_reference_statistics() {
        let clean = gradient(16, 16, [1.0, 0.9, 0.7]);
        let reference = gradient(8, 8, [0.2, 0.6, 0.9]);
        for space in [ColourSpace::LAlphaBeta, ColourSpace::Lab] {
            let target = stats(&convert(&reference, space));
            let got = stats(&match_statistics(convert(&clean, space), target, true));
            for c in 0..3 {
                let (dm, ds) = (got.mean[c] - target.mean[c], got.std[c] - target.std[c]);
                assert!(
                    dm.abs() < 1e-9 && ds.abs() < 1e-9,
                    "{space:?} {got:?} vs {target:?}"
                );
            }
        }
        // A constant source channel is only shifted.
        let flat = vec![[1.0, 2.0, 3.0]; 4];
        let target = ChannelStats {
            mean: [0.5; 3],
            std: [7.0; 3],
        };
        let out = match_statistics(flat, target, true);
        assert!(out.iter().all(|p| *p == [0.5; 3]), "{out:?}");
    }

    #[test]
    fn transfer_to_saved_stats_equals_transfer() {
        let clean = gradient(16, 12, [1.0, 0.9, 0.7]);
        let reference = gradient(8, 8, [0.2, 0.6, 0.9]);
        for space in [ColourSpace::LAlphaBeta, ColourSpace::Lab] {
            let st = reference_stats(&reference, space).unwrap();
            let a = transfer_to_stats(&clean, st, space).unwrap();
            let b = transfer(&clean, &reference, space).unwrap();
            assert_eq!(a, b, "{space:?}");
        }
    }

    #[test]
    fn self_transfer_is_identity() {
        let img = gradient(8, 8, [0.9, 0.5, 0.3]);
        for space in [ColourSpace::LAlphaBeta, ColourSpace::Lab] {
            let out = transfer(&img, &img, space).unwrap();
            for (a, b) in out.data().iter().zip(img.data()) {
                let tol = round_trip_tol(space) as f32;
                assert!((a - b).abs() < tol, "{space:?}: {a} vs {b}");
            }
        }
    }
}
