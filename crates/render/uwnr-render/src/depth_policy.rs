//! How a render job reads depth ([`DepthPolicy`]): maps found beside the clean images (`X/rgb/`
//! with `X/depth/`, as RGB-D sets are laid out, in a dataset run), the scene scale drawn per
//! item, and how far the built-in prior is trusted. `uwnr render`, the page and Python use
//! [`DepthPolicy::render`]; a dataset the default.
//!
//! A dataset has no target to be faithful to: what counts is that its renders vary as real
//! underwater scenes do. So, unlike `uwnr render`, a run
//! - reads the measured depth of every clean image that has it, and trusts it fully;
//! - draws each pair's scene scale (the metres a relative map's [0, 1] spans) uniformly from a
//!   range, from the pair's seed, and records it;
//! - trusts the built-in prior [`DATASET_PRIOR_TRUST`] by default (module doc of
//!   `uwnr_model::style` for what trust means; `uwnr render` uses `PRIOR_TRUST`, the value that
//!   keeps self-reconstruction fidelity, where a target exists).

use serde::{Deserialize, Serialize};
use uwnr_depth::DepthUnit;
use uwnr_model::{DepthResponse, DepthScale};

use uwnr_core::seed::mix;

use crate::error::{RenderError, Result};

/// Default range of the scene scale, metres: from a close-up (a diver's arm's length to a
/// metre or two behind) to a reef or a room seen across (NYU-v2's measured maps span 3.5-6 m,
/// Redwood's about 1.7 m, KITTI's street scenes tens of metres).
pub const DATASET_SCENE_SCALE_M: (f32, f32) = (1.5, 8.0);

/// Default trust in the built-in prior's depth differences in a dataset: full, as a measured
/// map. The prior is a ground-plane ramp (farther towards the top) refined by local contrast;
/// on the 12 RGB-D photos of the development data it ranks measured depth with a Spearman
/// correlation of 0.625 (`uwnr-depth`'s `rgbd_eval` test), so a render that gets hazier towards
/// the top of a photo is right more often than not, and a dataset has no target whose haze it
/// could contradict. `--prior-trust` sets it (0 turns the within-image response of the prior
/// off, as `uwnr render` nearly does).
pub const DATASET_PRIOR_TRUST: f32 = 1.0;

/// How a dataset run treats depth; recorded in the dataset settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DepthPolicy {
    /// Read `X/depth/` beside `X/rgb/` for the clean images that have a map there (when the
    /// depth source is the built-in prior: an explicit `--depth` or `--depth-model` wins).
    pub beside: bool,
    /// What the values of those maps mean (relative maps are min-max normalised per image).
    pub unit: DepthUnit,
    /// Range `(min, max)` of the scene scale in metres, drawn uniformly per pair.
    pub scene_scale_m: (f32, f32),
    /// Trust in the built-in prior's differences within an image.
    pub prior_trust: f32,
}

impl Default for DepthPolicy {
    fn default() -> Self {
        Self {
            beside: true,
            unit: DepthUnit::Relative,
            scene_scale_m: DATASET_SCENE_SCALE_M,
            prior_trust: DATASET_PRIOR_TRUST,
        }
    }
}

/// Largest scene scale, metres. Over it even the clearest ocean water, Jerlov type I, which keeps
/// 98.2 % of blue light a metre, keeps 1e-8 of the scene: every method's render is its veiling
/// light alone.
pub const MAX_SCENE_SCALE_M: f32 = 1000.0;

/// Salt of the scene-scale draw, so that it is independent of the methods' own draws from the
/// pair's seed.
const SCALE_SALT: u64 = 0x5CE7_E5CA_1E00_0001;

impl DepthPolicy {
    /// `uwnr render`'s defaults: the scene scale and the trust in the prior that the bundled
    /// model renders with (`uwnr_model::style`), no maps looked for beside the images.
    #[must_use]
    pub fn render() -> Self {
        let s = uwnr_model::style::DEFAULT_SCENE_SCALE_M;
        Self {
            beside: false,
            unit: DepthUnit::Relative,
            scene_scale_m: (s, s),
            prior_trust: uwnr_model::style::PRIOR_TRUST,
        }
    }

    /// Checks the numbers.
    pub fn validate(&self) -> Result<()> {
        let (lo, hi) = self.scene_scale_m;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi) {
            return Err(RenderError::Invalid(format!(
                "the scene scale range {lo},{hi} must be positive metres with MIN <= MAX"
            )));
        }
        if hi > MAX_SCENE_SCALE_M {
            return Err(RenderError::Invalid(format!(
                "the scene scale range {lo},{hi}: at most {MAX_SCENE_SCALE_M} metres (past it a \
                 render is its veiling light alone)"
            )));
        }
        DepthResponse {
            scale: DepthScale::Relative { scene_m: lo },
            trust: self.prior_trust,
        }
        .validate()
        .map_err(|e| RenderError::Invalid(e.to_string()))
    }

    /// The scene scale of the pair with `seed`: uniform in the range, to the millimetre (the
    /// manifest records it exactly), a pure function of the seed.
    #[must_use]
    pub fn scene_scale(&self, seed: u64) -> f32 {
        let (lo, hi) = self.scene_scale_m;
        if lo == hi {
            return lo;
        }
        // 53 random bits as a fraction in [0, 1).
        let u = (mix(seed ^ SCALE_SALT) >> 11) as f64 / (1u64 << 53) as f64;
        let metres = f64::from(lo) + u * f64::from(hi - lo);
        ((metres * 1e3).round() / 1e3).clamp(f64::from(lo), f64::from(hi)) as f32
    }

    /// How the pair with `seed` responds to `depth`.
    #[must_use]
    pub fn response(&self, depth: &uwnr_depth::Depth, seed: u64) -> DepthResponse {
        DepthResponse::for_depth(depth, self.scene_scale(seed), self.prior_trust)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_scale_past_any_water_is_refused() {
        for (lo, hi) in [(1.0, 1001.0), (1e30, 1e31), (1.0, f32::INFINITY)] {
            let p = DepthPolicy {
                scene_scale_m: (lo, hi),
                ..DepthPolicy::render()
            };
            assert!(p.validate().is_err(), "{lo},{hi}");
        }
        let p = DepthPolicy {
            scene_scale_m: (1.0, MAX_SCENE_SCALE_M),
            ..DepthPolicy::render()
        };
        assert!(p.validate().is_ok());
    }

    #[test]
    fn scene_scales_are_drawn_in_the_range_from_the_seed() {
        let p = DepthPolicy::default();
        let draws: Vec<f32> = (0..1000).map(|s| p.scene_scale(s)).collect();
        let (lo, hi) = p.scene_scale_m;
        assert!(draws.iter().all(|&s| (lo..=hi).contains(&s)));
        // Spread over the range, and the same for the same seed.
        let mean = draws.iter().sum::<f32>() / draws.len() as f32;
        assert!((mean - (lo + hi) / 2.0).abs() < 0.3, "{mean}");
        assert_eq!(p.scene_scale(7), p.scene_scale(7));
        assert_ne!(p.scene_scale(7), p.scene_scale(8));
        let fixed = DepthPolicy {
            scene_scale_m: (3.0, 3.0),
            ..p
        };
        assert_eq!(fixed.scene_scale(123), 3.0);
    }

    #[test]
    fn bad_policies_are_refused() {
        let p = DepthPolicy::default();
        for bad in [
            DepthPolicy {
                scene_scale_m: (0.0, 2.0),
                ..p
            },
            DepthPolicy {
                scene_scale_m: (3.0, 2.0),
                ..p
            },
            DepthPolicy {
                prior_trust: -1.0,
                ..p
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
        assert!(p.validate().is_ok());
    }
}
