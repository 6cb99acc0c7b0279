//! Pieces shared by the baselines: sampling ranges, the seeded generator, input checks and the
//! per-pixel image formation `I_c = J_c·t_c + B_c·(1 − t_c)` with its generalisations.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::error::{BaselineError, Result};

/// Pixels per parallel work item: large enough that rayon's overhead stays negligible.
const PAR_CHUNK: usize = 16 * 1024;

/// A closed-open interval `(min, max]` a parameter is drawn from uniformly, as UWCNN's
/// `max - (max - min) * rand` draws it. `min == max` fixes the value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Range {
    /// Lower end (excluded unless equal to `max`).
    pub min: f64,
    /// Upper end (included).
    pub max: f64,
}

impl Range {
    /// The range `(min, max]`.
    #[must_use]
    pub const fn new(min: f64, max: f64) -> Self {
        Self { min, max }
    }

    /// The fixed value `v`.
    #[must_use]
    pub const fn fixed(v: f64) -> Self {
        Self { min: v, max: v }
    }

    /// Draws `max - (max - min) * u` with `u` uniform in `[0, 1)`: a value in `(min, max]`.
    pub fn sample(&self, rng: &mut ChaCha8Rng) -> f64 {
        let u: f64 = rng.random();
        self.max - (self.max - self.min) * u
    }

    /// Checks that both ends are finite and `lowest <= min <= max <= highest`.
    pub(crate) fn validate(&self, name: &'static str, lowest: f64, highest: f64) -> Result<()> {
        let ok = self.min.is_finite() && self.max.is_finite();
        if !ok || self.min > self.max || self.min < lowest || self.max > highest {
            return Err(BaselineError::InvalidParam {
                name,
                value: format!(
                    "({}, {}] (allowed within [{lowest}, {highest}])",
                    self.min, self.max
                ),
                reason: "must be finite with min <= max, inside the allowed interval",
            });
        }
        Ok(())
    }
}

/// The generator every baseline draws from: ChaCha8 seeded from `seed`, so a seed gives the same
/// image on every platform and thread count.
pub(crate) fn rng_from_seed(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Fails unless `img` has `channels` channels and at least one pixel.
pub(crate) fn check_image(img: &Image, what: &'static str, channels: usize) -> Result<()> {
    if img.channels() != channels {
        return Err(BaselineError::Channels {
            what,
            expected: channels,
            got: img.channels(),
        });
    }
    if img.width() == 0 || img.height() == 0 {
        return Err(BaselineError::Empty {
            what,
            width: img.width(),
            height: img.height(),
        });
    }
    Ok(())
}

/// Checks the clean image (RGB) and its depth (grey, same size, finite) and returns the depth
/// values clamped to [0, 1], the range uwnr's relative depth is defined on.
pub(crate) fn checked_depth(clean: &Image, depth: &Image) -> Result<Vec<f32>> {
    check_image(clean, "clean image", 3)?;
    check_image(depth, "depth", 1)?;
    if depth.size() != clean.size() {
        return Err(BaselineError::DepthSize {
            expected: clean.size(),
            got: depth.size(),
        });
    }
    let bad = depth.data().iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(BaselineError::NonFiniteDepth { count: bad });
    }
    Ok(depth.data().iter().map(|v| v.clamp(0.0, 1.0)).collect())
}

/// Fails unless `v` is finite and within `[lo, hi]`.
pub(crate) fn check_in(
    name: &'static str,
    v: f64,
    lo: f64,
    hi: f64,
    reason: &'static str,
) -> Result<()> {
    if !(v.is_finite() && v >= lo && v <= hi) {
        return Err(BaselineError::InvalidParam {
            name,
            value: v.to_string(),
            reason,
        });
    }
    Ok(())
}

/// Renders `I_c(x) = gain_c·J_c(x)·exp(−att_c·d(x)) + B_c·(1 − exp(−bs_c·d(x)))`, clamped to
/// [0, 1], in parallel over pixels.
///
/// `att_c` and `bs_c` are attenuation coefficients per unit of `d` (the depth map's own unit):
/// with `att == bs` and `gain == 1` this is the classic model `J·t + B·(1 − t)`; separate `bs`
/// is Akkaynak & Treibitz's revised model; `gain = B` is UWCNN's released code, where the scene is
/// lit by the light left at the background depth.
pub(crate) fn form_image(
    clean: &Image,
    depth: &[f32],
    gain: [f64; 3],
    att: [f64; 3],
    bs: [f64; 3],
    background: [f64; 3],
) -> Result<Image> {
    let (w, h) = clean.size();
    let n = w * h;
    let mut out = vec![0.0f32; 3 * n];
    for (c, plane_out) in out.chunks_exact_mut(n).enumerate() {
        let plane_in = clean.plane(c);
        let (g, a, s, b) = (
            gain[c] as f32,
            att[c] as f32,
            bs[c] as f32,
            background[c] as f32,
        );
        plane_out
            .par_chunks_mut(PAR_CHUNK)
            .zip(plane_in.par_chunks(PAR_CHUNK))
            .zip(depth.par_chunks(PAR_CHUNK))
            .for_each(|((o, j), d)| {
                for ((o, &j), &d) in o.iter_mut().zip(j).zip(d) {
                    let direct = (-a * d).exp();
                    let veil = 1.0 - (-s * d).exp();
                    *o = (g * j * direct + b * veil).clamp(0.0, 1.0);
                }
            });
    }
    Ok(Image::from_planar(w, h, 3, out)?)
}

/// Median of the values (the lower middle element for an even count); `None` when empty or when
/// a value is NaN.
pub(crate) fn median(values: &[f32]) -> Option<f32> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    let mut v = values.to_vec();
    let k = (v.len() - 1) / 2;
    let (_, m, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    Some(*m)
}

/// Rounds to 6 significant decimals for the manifest (keeps the JSON readable and stable).
pub(crate) fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// [`round6`] on each component.
pub(crate) fn round6_3(v: [f64; 3]) -> [f64; 3] {
    v.map(round6)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_samples_stay_in_half_open_interval_and_fixed_is_fixed() {
        let mut rng = rng_from_seed(3);
        let r = Range::new(0.5, 15.0);
        for _ in 0..1000 {
            let v = r.sample(&mut rng);
            assert!(v > 0.5 && v <= 15.0, "{v}");
        }
        assert_eq!(Range::fixed(2.5).sample(&mut rng), 2.5);
        assert!(r.validate("r", 0.0, f64::MAX).is_ok());
        assert!(Range::new(2.0, 1.0).validate("r", 0.0, f64::MAX).is_err());
        assert!(Range::new(-1.0, 1.0).validate("r", 0.0, f64::MAX).is_err());
        assert!(Range::new(0.0, 10.0).validate("r", 0.0, 9.0).is_err());
        assert!(
            Range::new(f64::NAN, 1.0)
                .validate("r", 0.0, f64::MAX)
                .is_err()
        );
    }

    #[test]
    fn median_takes_the_lower_middle() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.0));
        assert_eq!(median(&[]), None);
    }

    #[test]
    fn form_image_matches_the_formula_by_hand() {
        let clean = Image::from_planar(2, 1, 3, vec![0.5, 0.5, 0.2, 0.2, 1.0, 0.0]).unwrap();
        let depth = [0.0f32, 1.0];
        let ln2 = std::f64::consts::LN_2;
        let out = form_image(
            &clean,
            &depth,
            [1.0; 3],
            [ln2; 3],
            [ln2; 3],
            [0.8, 0.6, 0.4],
        )
        .unwrap();
        // d = 0: the clean pixel; d = 1: t = 0.5, I = 0.5·J + 0.5·B.
        let want = [0.5, 0.25 + 0.4, 0.2, 0.1 + 0.3, 1.0, 0.2];
        for (g, w) in out.data().iter().zip(want) {
            assert!((g - w).abs() < 1e-6, "{:?}", out.data());
        }
    }
}
