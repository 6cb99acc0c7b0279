//! The render's depth stage (module doc of [`crate::style`] for the model): what a depth map's
//! values stand for ([`DepthScale`]) and how far they are trusted ([`DepthResponse`]), and the
//! finish of the anchored variant: the network's smooth gain and offset fields on the anchor,
//! `N = A (1 + G) + O`, then every pixel moved towards the veil as its depth attenuates it,
//! `I = B + (N - B) t(d) / t(d_ref)`.

use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::blur::blur_plane;
use crate::error::{ModelError, Result};
use crate::style::{
    DEFAULT_SCENE_SCALE_M, MAX_GAIN, PRIOR_TRUST, REFERENCE_DEPTH, REFERENCE_DISTANCE_M,
    SMOOTH_SIGMA, Water,
};
use crate::variant::ANCHORED_OUT_CHANNELS;

/// What a depth map's values stand for (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum DepthScale {
    /// Normalised per image: 1 spans `scene_m` metres, and the image's mean is the reference's
    /// distance.
    Relative {
        /// Metres between 0 and 1.
        scene_m: f32,
    },
    /// uwnr's absolute [0, 1]: [`REFERENCE_DEPTH`] is the reference's distance (constant maps,
    /// maps as stored).
    Absolute,
    /// Metres: 1 stands for `max_m` metres; the reference's subject is
    /// [`REFERENCE_DISTANCE_M`] away.
    Metric {
        /// Metres that 1 stands for.
        max_m: f32,
    },
}

impl DepthScale {
    /// Normalised-depth units per map unit: `beta · unit_gain` acts on the map's values.
    fn unit_gain(self) -> f32 {
        match self {
            Self::Absolute => 1.0,
            Self::Relative { scene_m: s } | Self::Metric { max_m: s } => {
                s * REFERENCE_DEPTH / REFERENCE_DISTANCE_M
            }
        }
    }

    /// The reference's distance in map units; `None` for a relative map (the image's mean).
    fn reference_depth(self) -> Option<f32> {
        match self {
            Self::Relative { .. } => None,
            Self::Absolute => Some(REFERENCE_DEPTH),
            Self::Metric { max_m } => Some(REFERENCE_DISTANCE_M / max_m),
        }
    }
}

/// How the anchored variant's output responds to a depth map: what its values stand for, and
/// how much its differences within the image are trusted (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DepthResponse {
    /// What the map's values stand for.
    pub scale: DepthScale,
    /// Trust in the map's differences within the image, in [0, 1] or a little above.
    pub trust: f32,
}

impl Default for DepthResponse {
    /// The built-in prior: relative, [`DEFAULT_SCENE_SCALE_M`], trusted [`PRIOR_TRUST`].
    fn default() -> Self {
        Self {
            scale: DepthScale::Relative {
                scene_m: DEFAULT_SCENE_SCALE_M,
            },
            trust: PRIOR_TRUST,
        }
    }
}

impl DepthResponse {
    /// The response to `depth`: a metric map keeps its metres, a relative one spans `scene_m`,
    /// an absolute one stands as it is; the built-in prior is trusted `prior_trust`, anything
    /// else fully.
    #[must_use]
    pub fn for_depth(depth: &uwnr_depth::Depth, scene_m: f32, prior_trust: f32) -> Self {
        let scale = match (depth.metric_max, depth.relative) {
            (Some(max_m), _) => DepthScale::Metric { max_m },
            (None, true) => DepthScale::Relative { scene_m },
            (None, false) => DepthScale::Absolute,
        };
        Self {
            scale,
            trust: if depth.prior { prior_trust } else { 1.0 },
        }
    }

    /// An absolute map trusted fully (constant maps: a scene that far away).
    #[must_use]
    pub fn absolute() -> Self {
        Self {
            scale: DepthScale::Absolute,
            trust: 1.0,
        }
    }

    /// Checks the numbers: a positive finite scale, a finite trust in [0, 4].
    pub fn validate(&self) -> Result<()> {
        let scale_ok = match self.scale {
            DepthScale::Relative { scene_m: s } | DepthScale::Metric { max_m: s } => {
                s.is_finite() && s > 0.0
            }
            DepthScale::Absolute => true,
        };
        if !scale_ok {
            return Err(ModelError::InvalidOptions(format!(
                "depth scale {:?} must be a positive number of metres",
                self.scale
            )));
        }
        if !(self.trust.is_finite() && (0.0..=MAX_TRUST).contains(&self.trust)) {
            return Err(ModelError::InvalidOptions(format!(
                "depth trust {} must be within [0, {MAX_TRUST}]",
                self.trust
            )));
        }
        Ok(())
    }
}

impl DepthResponse {
    /// Checked, in the normalised units of [`finish_with`]: the reference's depth (`None`: the
    /// image's mean), the within-image strength and the gain of the image's mean's offset.
    fn units(&self) -> Result<(Option<f32>, f32, f32)> {
        self.validate()?;
        let gain = self.scale.unit_gain();
        Ok((self.scale.reference_depth(), self.trust * gain, gain))
    }
}

/// Largest trust accepted (beyond 1 the map's differences act more than its distances say).
pub const MAX_TRUST: f32 = 4.0;

/// Depth factor `min(exp(-beta (local (d - m) + gain (m - m_ref))), MAX_GAIN)` for a pixel at
/// map depth `d` of an image whose mean map depth is `m`, rendered in the water of a reference
/// whose subject is at map depth `m_ref`; `beta` per unit of normalised depth, `gain` normalised
/// units per map unit, `local` the trusted share of that within the image.
fn depth_factor(beta: f32, d: f32, m: f32, m_ref: f32, local: f32, gain: f32) -> f32 {
    (-beta * (local * (d - m) + gain * (m - m_ref)))
        .exp()
        .min(MAX_GAIN)
}

/// Mean of a depth plane.
fn mean_depth(d: &[f32]) -> f32 {
    (d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len().max(1) as f64) as f32
}

/// The anchored variant's output stage on one image (module doc): `raw` is the network's
/// 6-plane output, `anchor` the colour transfer, `depth` the 1-plane depth map, all one size;
/// `response` says what the map's values stand for and how far its differences are trusted.
/// `raw` and `anchor` are taken and reused (the output is written over the anchor), so a large
/// photo holds no extra copies.
pub fn finish(
    raw: Image,
    anchor: Image,
    depth: &Image,
    water: &Water,
    response: &DepthResponse,
) -> Result<Image> {
    let (reference_depth, local, gain) = response.units()?;
    finish_with(raw, anchor, depth, water, reference_depth, local, gain)
}

/// [`finish`] in normalised units: the reference at `reference_depth` (`None`: the image's
/// mean), the within-image strength `local`, and `gain` scaling the image's mean's offset from
/// the reference (1 for an absolute map).
pub fn finish_with(
    raw: Image,
    anchor: Image,
    depth: &Image,
    water: &Water,
    reference_depth: Option<f32>,
    local: f32,
    gain: f32,
) -> Result<Image> {
    let (w, h) = anchor.size();
    if raw.size() != (w, h) {
        return Err(ModelError::ImageSize {
            what: "anchored network output",
            expected: (w, h),
            got: raw.size(),
        });
    }
    let mut fields = raw;
    for c in 0..ANCHORED_OUT_CHANNELS {
        blur_plane(fields.plane_mut(c), w, h, SMOOTH_SIGMA);
    }
    depth_stage(
        Some(&fields),
        anchor,
        depth,
        water,
        reference_depth,
        local,
        gain,
    )
}

/// [`finish`] with the correction at zero: the anchor through the depth stage alone (a network
/// whose output convolution is all zeros corrects nothing, so it is not run).
pub fn finish_uncorrected(
    anchor: Image,
    depth: &Image,
    water: &Water,
    response: &DepthResponse,
) -> Result<Image> {
    let (reference_depth, local, gain) = response.units()?;
    depth_stage(None, anchor, depth, water, reference_depth, local, gain)
}

/// The output stage after the correction's blur: `N = A (1 + g') + o'` (`fields`: g' then o';
/// `None`: zero) through the depth factor towards the veil.
fn depth_stage(
    fields: Option<&Image>,
    anchor: Image,
    depth: &Image,
    water: &Water,
    reference_depth: Option<f32>,
    local: f32,
    gain: f32,
) -> Result<Image> {
    let (w, h) = anchor.size();
    if depth.size() != (w, h) {
        return Err(ModelError::ImageSize {
            what: "depth map",
            expected: (w, h),
            got: depth.size(),
        });
    }
    let d = depth.plane(0);
    let m = mean_depth(d);
    let reference_depth = reference_depth.unwrap_or(m);
    let mut out = anchor;
    for c in 0..3 {
        let (veil, beta) = (water.veil[c], water.beta[c]);
        let gain_offset = fields.map(|f| (f.plane(c), f.plane(c + 3)));
        for (i, v) in out.plane_mut(c).iter_mut().enumerate() {
            let n = match gain_offset {
                Some((g, o)) => *v * (1.0 + g[i]) + o[i],
                None => *v,
            };
            *v = veil + (n - veil) * depth_factor(beta, d[i], m, reference_depth, local, gain);
        }
    }
    out.clamp01();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::style::LOCAL_DEPTH_STRENGTH;
    use uwnr_baselines::reinhard::ChannelStats;

    #[test]
    fn depth_factor_is_one_at_the_reference_depth_and_falls() {
        let r = REFERENCE_DEPTH;
        let f = |beta, d| depth_factor(beta, d, d, r, LOCAL_DEPTH_STRENGTH, 1.0);
        assert!((f(2.0, r) - 1.0).abs() < 1e-6);
        assert!(f(2.0, 1.0) < f(2.0, 0.75));
        assert_eq!(f(20.0, 0.0), MAX_GAIN);
        // No attenuation: no response.
        assert_eq!(f(0.0, 1.0), 1.0);
        // Within an image, farther pixels are hazier, less so than a farther image.
        let local = |d| depth_factor(2.0, d, 0.5, r, LOCAL_DEPTH_STRENGTH, 1.0);
        assert!(local(0.8) < local(0.2));
        assert!(local(0.8) > f(2.0, 0.8));
    }

    #[test]
    fn the_prior_renders_as_the_bundled_model_was_trained() {
        let r = DepthResponse::default();
        let local = r.trust * r.scale.unit_gain();
        assert!((local - LOCAL_DEPTH_STRENGTH).abs() < 1e-7, "{local}");
    }

    /// A water whose channels attenuate at three rates.
    fn test_water() -> Water {
        Water {
            stats: ChannelStats {
                mean: [0.0; 3],
                std: [1.0; 3],
            },
            veil: [0.1, 0.5, 0.6],
            beta: [3.0, 1.0, 0.5],
            detail: None,
            affine: None,
        }
    }

    /// The anchored stage with the network's correction at zero on a striped clean image, the
    /// depth running from 0 at the top to 1 at the bottom; the mean distance to the veil and the
    /// contrast of each row band.
    fn bands(response: &DepthResponse) -> Vec<(f32, f32)> {
        let (w, h) = (8, 40);
        let water = test_water();
        let anchor: Vec<f32> = (0..3)
            .flat_map(|_| (0..w * h).map(|i| if i % 2 == 0 { 0.9 } else { 0.2 }))
            .collect();
        let anchor = Image::from_planar(w, h, 3, anchor).unwrap();
        let depth: Vec<f32> = (0..w * h)
            .map(|i| (i / w) as f32 / (h - 1) as f32)
            .collect();
        let depth = Image::from_planar(w, h, 1, depth).unwrap();
        let raw = Image::filled(w, h, 6, 0.0);
        let out = finish(raw, anchor, &depth, &water, response).unwrap();
        (0..h / 8)
            .map(|band| {
                let rows = band * 8..band * 8 + 8;
                let px: Vec<usize> = rows.flat_map(|y| (0..w).map(move |x| y * w + x)).collect();
                let dist = px
                    .iter()
                    .map(|&i| {
                        (0..3)
                            .map(|c| (out.plane(c)[i] - water.veil[c]).abs())
                            .sum::<f32>()
                    })
                    .sum::<f32>()
                    / px.len() as f32;
                let lum: Vec<f32> = px.iter().map(|&i| out.plane(1)[i]).collect();
                let (hi, lo) = lum
                    .iter()
                    .fold((0.0f32, 1.0f32), |(a, b), &v| (a.max(v), b.min(v)));
                (dist, hi - lo)
            })
            .collect()
    }

    #[test]
    fn farther_is_hazier_and_nearer_to_the_veil_with_a_trusted_map() {
        for response in [
            DepthResponse {
                scale: DepthScale::Metric { max_m: 6.0 },
                trust: 1.0,
            },
            DepthResponse {
                scale: DepthScale::Relative { scene_m: 4.0 },
                trust: 1.0,
            },
            DepthResponse::default(),
        ] {
            let b = bands(&response);
            for k in 1..b.len() {
                assert!(b[k].0 < b[k - 1].0, "{response:?}: {b:?}");
                assert!(b[k].1 <= b[k - 1].1, "{response:?}: {b:?}");
            }
        }
        // The trusted map acts far more than the prior.
        let spread = |r: &DepthResponse| {
            let b = bands(r);
            b[b.len() - 1].1 / b[0].1
        };
        let trusted = spread(&DepthResponse {
            scale: DepthScale::Relative { scene_m: 4.0 },
            trust: 1.0,
        });
        let prior = spread(&DepthResponse::default());
        assert!(trusted < 0.8 && prior > 0.9, "{trusted} {prior}");
    }

    #[test]
    fn a_metric_scene_at_the_reference_distance_is_left_as_rendered() {
        let water = test_water();
        let a = Image::filled(4, 4, 3, 0.8);
        let raw = Image::filled(4, 4, 6, 0.0);
        // A flat scene exactly REFERENCE_DISTANCE_M away: the factor is 1.
        let depth = Image::filled(4, 4, 1, 0.5);
        let response = DepthResponse {
            scale: DepthScale::Metric {
                max_m: 2.0 * REFERENCE_DISTANCE_M,
            },
            trust: 1.0,
        };
        let out = finish(raw.clone(), a.clone(), &depth, &water, &response).unwrap();
        assert!(out.data().iter().all(|&v| (v - 0.8).abs() < 1e-6));
        // Twice as far: t(2 z_ref) / t(z_ref) = exp(-beta_m z_ref) per channel.
        let far = Image::filled(4, 4, 1, 1.0);
        let out = finish(raw, a, &far, &water, &response).unwrap();
        let beta_m = water.beta_per_metre();
        for (c, b) in beta_m.iter().enumerate() {
            let f = (-b * REFERENCE_DISTANCE_M).exp();
            let want = water.veil[c] + (0.8 - water.veil[c]) * f;
            assert!((out.plane(c)[0] - want).abs() < 1e-5, "{c}");
        }
        // Bad numbers are refused.
        let bad = DepthResponse {
            scale: DepthScale::Relative { scene_m: -1.0 },
            trust: 1.0,
        };
        assert!(bad.validate().is_err());
    }
}
