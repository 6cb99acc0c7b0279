//! Real waters: the per-channel affine relation `I_c = a_c J_c + b_c` between the clean and the
//! underwater side of real pairs, fitted by least squares, banked, and predicted from an
//! underwater photo alone by ridge regression on its colour statistics.
//!
//! Why affine per channel: it is the image-formation model `I = J t + B (1 - t)` at one
//! distance (`a = t`, `b = B (1 - t)`) with the camera's gain folded into `a`, and it is what
//! real pairs are. Fitted to each pair at 256 px, it reproduces the underwater side at 33.2 dB
//! on `uieb-train`, 35.5 on `uieb-val`, 35.5 on LSUI's training part and 34.8 on `lsui-test`
//! (PSNR of the fit against the real underwater image), so nearly all of what separates a real
//! pair is a global per-channel gain and offset, with no spatial layout. A Reinhard transfer
//! instead matches the *reference's* statistics, so the reference's scene (its green algae,
//! its open blue water) replaces the clean photo's colours; the affine water keeps the photo's
//! own colours and moves them as the reference's water would.
//!
//! The reference's water is predicted from the reference alone ([`Regressor`]): 15 statistics
//! per image ([`water_features`]: per-channel mean, standard deviation and the 2nd, 50th and
//! 98th percentiles) mapped linearly to the six parameters, ridge-regularised ([`RIDGE_LAMBDA`])
//! on standardised statistics. Trained on `uieb-train` and LSUI's training part (160 pairs) and
//! applied to pairs it never saw, the predicted water reproduces their underwater side at 28.7
//! dB (`uieb-val`) and 29.3 dB (`lsui-test`), and the rendered pairs sit as far apart as the
//! real ones: PSNR(render, clean) 17.2 dB against the real 16.6 on `uieb-val`, 15.5 against 15.1
//! on `lsui-test` (prototype measurements at 256 px; `uwnr water fit` prints the Rust ones).
//! Adding EUVP's pairs to the training lowered both (24.6 and 25.7 dB): their clean side was
//! made by one enhancement model, not chosen among many as UIEB's and LSUI's were.

use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::resize::{fit_within, resize_bilinear};

use crate::error::{ModelError, Result};

mod balance;
mod predict;

pub use balance::{
    BALANCE_RANGE, BANK_CLEAN_CHROMATICITY, BANK_UNDERWATER_CHROMATICITY, BANK_WATER_SHARE,
    CleanBalance, chromaticity, mean_colour,
};

#[cfg(test)]
use predict::percentile;
pub use predict::{
    BankEntry, FEATURE_PERCENTILES, N_FEATURES, RIDGE_LAMBDA, Regressor, WaterBank, bank_entry,
    bundled_bank, water_features,
};

/// Longest side, in pixels, at which waters are fitted and statistics measured (images are
/// shrunk to it, never enlarged): the statistics are global, so the scale barely moves them, and
/// 256 px keeps a reference's preparation cheap.
pub const WATER_SIDE: usize = 256;
/// Range of a predicted or drawn gain `a` (a real pair's fitted gains lie in it).
pub const GAIN_RANGE: (f32, f32) = (0.05, 1.2);
/// Range of a predicted or drawn offset `b`.
pub const OFFSET_RANGE: (f32, f32) = (-0.1, 0.6);

/// One water: `I_c = gain_c J_c + offset_c`, RGB in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Affine {
    /// Per-channel gain `a` (transmission times the camera's gain).
    pub gain: [f32; 3],
    /// Per-channel offset `b` (backscatter).
    pub offset: [f32; 3],
}

impl Affine {
    /// The water with its parameters clamped to [`GAIN_RANGE`] and [`OFFSET_RANGE`]; a
    /// non-finite parameter becomes the identity's.
    #[must_use]
    pub fn clamped(self) -> Self {
        let fix = |v: f32, (lo, hi): (f32, f32), id: f32| {
            if v.is_finite() { v.clamp(lo, hi) } else { id }
        };
        Self {
            gain: self.gain.map(|a| fix(a, GAIN_RANGE, 1.0)),
            offset: self.offset.map(|b| fix(b, OFFSET_RANGE, 0.0)),
        }
    }

    /// `clean` under this water, clamped to [0, 1].
    pub fn apply(&self, clean: &Image) -> Result<Image> {
        if clean.channels() != 3 {
            return Err(ModelError::InvalidOptions(format!(
                "a water applies to RGB images, got {} channel(s)",
                clean.channels()
            )));
        }
        let mut out = clean.clone();
        for c in 0..3 {
            let (a, b) = (self.gain[c], self.offset[c]);
            for v in out.plane_mut(c) {
                *v = (a * *v + b).clamp(0.0, 1.0);
            }
        }
        Ok(out)
    }

    /// The veiling light `B = b / (1 - a)` the water implies, per channel, in [0, 1]; `fallback`
    /// where the gain leaves too little of `1 - a` to divide by (no attenuation to speak of).
    #[must_use]
    pub fn veil(&self, fallback: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|c| {
            let t = self.gain[c];
            if t < MAX_VEIL_GAIN {
                (self.offset[c] / (1.0 - t)).clamp(0.0, 1.0)
            } else {
                fallback[c]
            }
        })
    }

    /// The six parameters as one vector: gains, then offsets.
    #[must_use]
    pub fn to_vec(&self) -> [f64; 6] {
        std::array::from_fn(|i| {
            f64::from(if i < 3 {
                self.gain[i]
            } else {
                self.offset[i - 3]
            })
        })
    }

    /// The water of a vector of [`Affine::to_vec`]'s layout.
    #[must_use]
    pub fn from_vec(v: [f64; 6]) -> Self {
        Self {
            gain: std::array::from_fn(|c| v[c] as f32),
            offset: std::array::from_fn(|c| v[c + 3] as f32),
        }
    }
}

/// Largest strength factor [`calibrate`] gives a water: up to this much farther along the line
/// from the clean image to its render than the reference's own water goes.
pub const MAX_STRENGTH_SCALE: f32 = 1.5;

impl Affine {
    /// The water `s` of the way from the identity to this one: `gain 1 + s (a - 1)`, offset
    /// `s b`, clamped. Every pixel's change is scaled by `s`, so (before clipping) the squared
    /// error against the clean image scales by `s²`: PSNR falls by `20 log10 s`. A shorter or
    /// longer path through the same water, in effect.
    #[must_use]
    pub fn scaled(&self, s: f32) -> Self {
        Self {
            gain: self.gain.map(|a| 1.0 + s * (a - 1.0)),
            offset: self.offset.map(|b| s * b),
        }
        .clamped()
    }
}

/// `water` scaled ([`Affine::scaled`]) so that PSNR(water on `clean`, `clean`) is `target_db`,
/// measured at [`WATER_SIDE`]; the factor stays within [0, [`MAX_STRENGTH_SCALE`]] (a weak
/// water cannot be made more than that much stronger). Returns the water and its factor.
pub fn calibrate(water: &Affine, clean: &Image, target_db: f32) -> Result<(Affine, f32)> {
    let small = fit_within(clean, WATER_SIDE)?;
    let strength = |s: f32| -> Result<f32> { pair_psnr(&water.scaled(s).apply(&small)?, &small) };
    // PSNR(s) = PSNR(1) - 20 log10 s until clipping bends it: a few fixed-point steps of the
    // closed form settle it.
    let mut s = 1.0f32;
    for _ in 0..CALIBRATION_STEPS {
        let now = strength(s)?;
        if !now.is_finite() {
            break;
        }
        s = rescaled(s, now, target_db);
    }
    Ok((water.scaled(s), s))
}

/// The scale that moves a pair rendered at scale `s` with strength `now_db` to `target_db`, by
/// the closed form of [`Affine::scaled`] (PSNR falls by `20 log10 s` until clipping bends it),
/// within [0, [`MAX_STRENGTH_SCALE`]].
#[must_use]
pub fn rescaled(s: f32, now_db: f32, target_db: f32) -> f32 {
    (s * 10f32.powf((now_db - target_db) / 20.0)).clamp(0.0, MAX_STRENGTH_SCALE)
}

/// Fixed-point steps of [`calibrate`].
const CALIBRATION_STEPS: usize = 4;

/// Above this gain a channel is taken to be unattenuated: [`Affine::veil`] falls back.
pub const MAX_VEIL_GAIN: f32 = 0.95;

/// The water of one real pair: per channel, the least-squares `a, b` of `under ≈ a clean + b`,
/// both images brought to the underwater image's size at [`WATER_SIDE`].
pub fn fit_pair(clean: &Image, under: &Image) -> Result<Affine> {
    if clean.channels() != 3 || under.channels() != 3 {
        return Err(ModelError::InvalidOptions(
            "a water is fitted to RGB images".into(),
        ));
    }
    let u = fit_within(under, WATER_SIDE)?;
    let (w, h) = u.size();
    let c_img = resize_bilinear(clean, w, h)?;
    let mut gain = [1.0f32; 3];
    let mut offset = [0.0f32; 3];
    for c in 0..3 {
        let (x, y) = (c_img.plane(c), u.plane(c));
        let n = x.len() as f64;
        let mx = x.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let my = y.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let (mut sxy, mut sxx) = (0.0f64, 0.0f64);
        for (&a, &b) in x.iter().zip(y) {
            let dx = f64::from(a) - mx;
            sxy += dx * (f64::from(b) - my);
            sxx += dx * dx;
        }
        let a = if sxx > 1e-12 { sxy / sxx } else { 0.0 };
        gain[c] = a as f32;
        offset[c] = (my - a * mx) as f32;
    }
    Ok(Affine { gain, offset })
}

/// PSNR in dB of two images of one size (data range 1), the strength measure of a pair.
pub fn pair_psnr(a: &Image, b: &Image) -> Result<f32> {
    if a.size() != b.size() || a.channels() != b.channels() {
        return Err(ModelError::InvalidOptions(format!(
            "PSNR of images of different shapes: {:?} and {:?}",
            a.size(),
            b.size()
        )));
    }
    let n = a.data().len().max(1) as f64;
    let mse = a
        .data()
        .iter()
        .zip(b.data())
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum::<f64>()
        / n;
    Ok((10.0 * (1.0 / mse.max(1e-12)).log10()) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Image {
        let data: Vec<f32> = (0..3)
            .flat_map(|c| {
                (0..w * h).map(move |i| ((i % w) as f32 / w as f32 * (0.6 + 0.1 * c as f32)) + 0.1)
            })
            .collect();
        Image::from_planar(w, h, 3, data).unwrap()
    }

    #[test]
    fn a_pair_made_by_a_water_gives_that_water_back() {
        let clean = ramp(64, 48);
        let water = Affine {
            gain: [0.4, 0.7, 0.6],
            offset: [0.05, 0.2, 0.25],
        };
        let under = water.apply(&clean).unwrap();
        let fit = fit_pair(&clean, &under).unwrap();
        for c in 0..3 {
            assert!((fit.gain[c] - water.gain[c]).abs() < 1e-4, "{fit:?}");
            assert!((fit.offset[c] - water.offset[c]).abs() < 1e-4, "{fit:?}");
        }
        // B = b / (1 - a).
        let veil = water.veil([0.0; 3]);
        assert!((veil[0] - 0.05 / 0.6).abs() < 1e-6);
    }

    #[test]
    fn the_regressor_recovers_a_linear_law_and_clamps() {
        // Waters that depend linearly on the statistics are predicted back.
        let entries: Vec<BankEntry> = (0..40)
            .map(|i| {
                let clean = ramp(32, 32);
                let g = 0.3 + 0.01 * i as f32;
                let water = Affine {
                    gain: [g, 0.8 - g / 2.0, 0.5],
                    offset: [0.1, 0.05 + g / 4.0, 0.3 - g / 3.0],
                };
                let under = water.apply(&clean).unwrap();
                bank_entry(format!("t/{i}"), &clean, &under).unwrap()
            })
            .collect();
        let reg = Regressor::fit(&entries, 1e-6).unwrap();
        for e in &entries {
            let p = reg.predict(&e.features);
            for c in 0..3 {
                assert!(
                    (p.gain[c] - e.water.gain[c]).abs() < 2e-3,
                    "{p:?} {:?}",
                    e.water
                );
            }
        }
        let wild = Affine {
            gain: [9.0, f32::NAN, -1.0],
            offset: [2.0, -3.0, 0.1],
        }
        .clamped();
        assert_eq!(wild.gain, [GAIN_RANGE.1, 1.0, GAIN_RANGE.0]);
        assert_eq!(wild.offset, [OFFSET_RANGE.1, OFFSET_RANGE.0, 0.1]);
        assert!(Regressor::fit(&entries[..1], 1.0).is_err());
    }

    #[test]
    fn calibration_reaches_the_target_strength() {
        let clean = ramp(64, 48);
        let water = Affine {
            gain: [0.4, 0.7, 0.6],
            offset: [0.05, 0.2, 0.25],
        };
        let own = pair_psnr(&water.apply(&clean).unwrap(), &clean).unwrap();
        for target in [own + 3.0, own, own - 2.0] {
            let (w, s) = calibrate(&water, &clean, target).unwrap();
            let got = pair_psnr(&w.apply(&clean).unwrap(), &clean).unwrap();
            assert!((got - target).abs() < 0.05, "{target} {got} {s}");
        }
        // The identity water cannot be made stronger; a far target is capped.
        let (_, s) = calibrate(&water, &clean, own - 40.0).unwrap();
        assert_eq!(s, MAX_STRENGTH_SCALE);
        let one = water.scaled(1.0).to_vec();
        assert!(
            one.iter()
                .zip(water.to_vec())
                .all(|(a, b)| (a - b).abs() < 1e-6)
        );
        assert_eq!(water.scaled(0.0).gain, [1.0; 3]);
    }

    #[test]
    fn percentiles_interpolate_like_numpy() {
        let v = [0.0f32, 1.0, 2.0, 3.0, 4.0];
        assert_eq!(percentile(&v, 0.5), 2.0);
        assert!((percentile(&v, 0.02) - 0.08).abs() < 1e-6);
        assert!((percentile(&v, 0.98) - 3.92).abs() < 1e-6);
    }
}
