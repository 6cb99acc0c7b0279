//! Training samples: the data order of each epoch and the random crop, flip, rotation and
//! colour cast of each sample, all pure functions of `(seed, epoch, position)` so that a run
//! gives the same batches whatever the thread timing and a resumed run continues exactly.
//!
//! As in the released `UWS_Dataset_Retinex.augData`: a random crop (the same window of the
//! clean image, its depth and the underwater image), a horizontal flip with probability 1/2,
//! then a rotation by 0/90/180/270 degrees counter-clockwise (torchvision's `rotate`), and the
//! light-field map computed from the augmented underwater crop at the crop's own size
//! (`MutiScaleLuminanceEstimation` on the crop). The optional colour cast (not in the paper)
//! multiplies each channel of the underwater crop by a gain and applies a gamma before the
//! light field is computed, so the map always describes the target the network must produce.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use uwnr_core::Image;
use uwnr_model::AnchorKind;
use uwnr_model::Variant;
use uwnr_model::style::{anchor, estimate_water_for};
use uwnr_run::plan::{Geometry, plan_crop};
pub use uwnr_run::plan::{epoch_order, source_of};

use crate::config::{AugmentConfig, ColorCast};
use crate::data::PairData;
use crate::error::{Result, TrainError};

/// Channels of the paper variant's network input: clean RGB, depth, light field.
pub const INPUT_CHANNELS: usize = 7;
/// Values per sample of the water the anchored variant's output stage uses: veil RGB, beta RGB.
pub const WATER_VALUES: usize = 6;
/// Channels of the target.
pub const TARGET_CHANNELS: usize = 3;
/// A colour cast: a gain per channel, then a gamma.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cast {
    /// R, G, B gains.
    pub gains: [f32; 3],
    /// Exponent applied after the gains (`v^gamma`).
    pub gamma: f32,
}

/// Everything random about one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplePlan {
    /// Index of the pair in the training set.
    pub pair: usize,
    /// Left column of the crop.
    pub x0: usize,
    /// Top row of the crop.
    pub y0: usize,
    /// Horizontal flip.
    pub flip: bool,
    /// Counter-clockwise quarter turns (0..4), after the flip.
    pub quarter_turns: u8,
    /// Colour cast of the underwater crop.
    pub cast: Option<Cast>,
}

/// The plan of sample `position` of epoch `epoch`, for `pair` of size `width x height`: the
/// crop, flip and turn of [`plan_crop`], then the colour cast drawn from the same generator.
#[must_use]
pub fn plan_sample(
    seed: u64,
    epoch: usize,
    position: usize,
    pair: (usize, usize, usize),
    crop: usize,
    aug: &AugmentConfig,
) -> SamplePlan {
    let geometry = Geometry {
        flip: aug.flip,
        rotate: aug.rotate,
    };
    let (p, mut rng) = plan_crop(seed, epoch, position, pair, crop, geometry);
    let cast = draw_cast(&mut rng, aug.color_cast.as_ref());
    SamplePlan {
        pair: p.pair,
        x0: p.x0,
        y0: p.y0,
        flip: p.flip,
        quarter_turns: p.quarter_turns,
        cast,
    }
}

fn draw_cast(rng: &mut ChaCha8Rng, cfg: Option<&ColorCast>) -> Option<Cast> {
    let cfg = cfg?;
    let apply = rng.random::<f32>() < cfg.probability;
    let mut gains = [1.0_f32; 3];
    for g in &mut gains {
        *g = uniform(rng, cfg.gain.0, cfg.gain.1);
    }
    // Log-uniform, so that gamma and 1/gamma are equally likely for symmetric ranges.
    let gamma = uniform(rng, cfg.gamma.0.ln(), cfg.gamma.1.ln()).exp();
    apply.then_some(Cast { gains, gamma })
}

fn uniform(rng: &mut ChaCha8Rng, lo: f32, hi: f32) -> f32 {
    if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    }
}

/// One training sample: the network input and the target `[3, crop, crop]`, planar.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// The paper's variant: clean RGB, depth, light field `[7, crop, crop]`; the anchored
    /// variant: clean RGB, light field, anchor `[9, crop, crop]`.
    pub input: Vec<f32>,
    /// The (possibly colour-cast) underwater crop.
    pub target: Vec<f32>,
    /// The depth crop `[1, crop, crop]` (the anchored variant's output stage; empty for the
    /// paper's, whose input holds it).
    pub depth: Vec<f32>,
    /// The target's water: veil RGB then beta RGB (anchored variant; zeros for the paper's).
    pub water: [f32; WATER_VALUES],
}

/// Cuts, flips, rotates and casts the sample of `plan` from `pair`, then computes the light
/// field of the underwater crop with `light_field` (the released procedure at the crop's size),
/// and for the anchored variant the crop's water and the clean crop's anchor (`model`: the
/// variant, whether the anchor retains the target's detail, and what the anchor starts from).
pub fn make_sample(
    pair: &PairData,
    plan: &SamplePlan,
    crop: usize,
    model: (Variant, bool, AnchorKind),
    light_field: impl Fn(&Image) -> Result<Image>,
) -> Result<Sample> {
    let (variant, detail_retention, anchor_kind) = model;
    let (w, h) = (pair.width(), pair.height());
    if w < crop || h < crop || plan.x0 + crop > w || plan.y0 + crop > h {
        return Err(TrainError::BadImage {
            path: pair.name.clone().into(),
            reason: format!(
                "crop {crop}x{crop}+{}+{} leaves the {}x{} pair",
                plan.x0, plan.y0, w, h
            ),
        });
    }
    let n = crop * crop;
    let mut clean = vec![0.0_f32; 3 * n];
    let mut under = vec![0.0_f32; 3 * n];
    let mut depth = vec![0.0_f32; n];
    for oy in 0..crop {
        for ox in 0..crop {
            // Output pixel (ox, oy) shows the augmented-crop pixel: undo the rotation, then the flip.
            let (cx, cy) = source_of(ox, oy, crop, plan.flip, plan.quarter_turns);
            let src = (plan.y0 + cy) * w + plan.x0 + cx;
            let dst = oy * crop + ox;
            for c in 0..3 {
                clean[c * n + dst] = pair.clean.value(c, src);
                under[c * n + dst] = pair.underwater.value(c, src);
            }
            depth[dst] = f32::from(pair.depth[src]) / 65_535.0;
        }
    }
    debug_assert!(h >= crop);
    if let Some(cast) = plan.cast {
        apply_cast(&mut under, n, &cast);
    }
    let under_img = Image::from_planar(crop, crop, 3, under)?;
    let lf = light_field(&under_img)?;
    if lf.size() != (crop, crop) || lf.channels() != 3 {
        return Err(TrainError::BadImage {
            path: pair.name.clone().into(),
            reason: format!(
                "light field is {}x{}x{}, expected {crop}x{crop}x3",
                lf.width(),
                lf.height(),
                lf.channels()
            ),
        });
    }
    let (cin, _) = variant.channels();
    let mut input = Vec::with_capacity(cin * n);
    match variant {
        Variant::Paper => {
            input.extend_from_slice(&clean);
            input.extend_from_slice(&depth);
            input.extend_from_slice(lf.data());
            Ok(Sample {
                input,
                target: under_img.into_data(),
                depth: Vec::new(),
                water: [0.0; WATER_VALUES],
            })
        }
        Variant::Anchored => {
            let bad = |e: uwnr_model::ModelError| TrainError::BadImage {
                path: pair.name.clone().into(),
                reason: e.to_string(),
            };
            let water =
                estimate_water_for(&under_img, anchor_kind, detail_retention).map_err(bad)?;
            let clean_img = Image::from_planar(crop, crop, 3, clean)?;
            let a = anchor(&clean_img, &water, &lf, |im| {
                light_field(im).map_err(|e| uwnr_model::ModelError::InvalidOptions(e.to_string()))
            })
            .map_err(bad)?;
            input.extend_from_slice(clean_img.data());
            input.extend_from_slice(lf.data());
            input.extend_from_slice(a.data());
            let mut w = [0.0; WATER_VALUES];
            w[..3].copy_from_slice(&water.veil);
            w[3..].copy_from_slice(&water.beta);
            Ok(Sample {
                input,
                target: under_img.into_data(),
                depth,
                water: w,
            })
        }
    }
}

/// `v <- clamp(v * gain_c, 0, 1)^gamma` on planar RGB with `n` pixels a plane.
pub fn apply_cast(rgb: &mut [f32], n: usize, cast: &Cast) {
    for (c, plane) in rgb.chunks_exact_mut(n).enumerate().take(3) {
        let g = cast.gains[c];
        for v in plane {
            *v = (*v * g).clamp(0.0, 1.0).powf(cast.gamma);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_stay_inside_and_follow_the_switches() {
        let aug = AugmentConfig {
            flip: false,
            rotate: false,
            color_cast: None,
        };
        for pos in 0..100 {
            let p = plan_sample(3, 2, pos, (0, 40, 33), 32, &aug);
            assert!(p.x0 <= 8 && p.y0 <= 1);
            assert!(!p.flip && p.quarter_turns == 0 && p.cast.is_none());
        }
        let aug = AugmentConfig {
            color_cast: Some(ColorCast::default()),
            ..AugmentConfig::default()
        };
        let plans: Vec<SamplePlan> = (0..200)
            .map(|i| plan_sample(3, 2, i, (0, 64, 64), 32, &aug))
            .collect();
        assert!(plans.iter().any(|p| p.flip) && plans.iter().any(|p| !p.flip));
        assert!((0..4).all(|t| plans.iter().any(|p| p.quarter_turns == t)));
        for p in &plans {
            let c = p.cast.unwrap();
            assert!(c.gains.iter().all(|g| (0.5..1.6).contains(g)));
            assert!((0.8..1.25).contains(&c.gamma));
        }
        assert_eq!(plans[7], plan_sample(3, 2, 7, (0, 64, 64), 32, &aug));
    }
}
