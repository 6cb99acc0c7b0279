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

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::resize::{fit_within, resize_bilinear};

use crate::error::{ModelError, Result};

/// Longest side, in pixels, at which waters are fitted and statistics measured (images are
/// shrunk to it, never enlarged): the statistics are global, so the scale barely moves them, and
/// 256 px keeps a reference's preparation cheap.
pub const WATER_SIDE: usize = 256;
/// The percentiles of each channel among the statistics.
pub const FEATURE_PERCENTILES: [f64; 3] = [0.02, 0.5, 0.98];
/// Statistics per image: per channel the mean, the standard deviation and the
/// [`FEATURE_PERCENTILES`].
pub const N_FEATURES: usize = 15;
/// Ridge penalty on the standardised statistics (chosen among 0.1, 1 and 3: the three were within
/// 0.2 dB of each other on held-out pairs).
pub const RIDGE_LAMBDA: f64 = 1.0;
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

/// Statistics of an image for [`Regressor`]: per channel the mean, the standard deviation and
/// the [`FEATURE_PERCENTILES`] (linear interpolation between ranks, as NumPy's default), in
/// that order, measured at [`WATER_SIDE`].
pub fn water_features(img: &Image) -> Result<[f32; N_FEATURES]> {
    if img.channels() != 3 {
        return Err(ModelError::InvalidOptions(format!(
            "water statistics need an RGB image, got {} channel(s)",
            img.channels()
        )));
    }
    let small = fit_within(img, WATER_SIDE)?;
    let mut f = [0.0f32; N_FEATURES];
    for c in 0..3 {
        let p = small.plane(c);
        let n = p.len().max(1) as f64;
        let mean = p.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let var = p
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n;
        let mut sorted = p.to_vec();
        sorted.sort_by(f32::total_cmp);
        f[c] = mean as f32;
        f[3 + c] = var.sqrt() as f32;
        for (k, q) in FEATURE_PERCENTILES.iter().enumerate() {
            f[6 + 3 * k + c] = percentile(&sorted, *q);
        }
    }
    Ok(f)
}

/// The `q` quantile of sorted values, linearly interpolated between ranks.
fn percentile(sorted: &[f32], q: f64) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let (lo, frac) = (pos.floor() as usize, pos - pos.floor());
    let hi = (lo + 1).min(sorted.len() - 1);
    (f64::from(sorted[lo]) * (1.0 - frac) + f64::from(sorted[hi]) * frac) as f32
}

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

/// A real pair's water, with the statistics of its underwater side.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BankEntry {
    /// Where the pair came from (`SET/NAME`).
    pub name: String,
    /// [`water_features`] of the underwater image.
    pub features: [f32; N_FEATURES],
    /// The fitted water (unclamped).
    pub water: Affine,
    /// PSNR(underwater, clean) of the real pair at [`WATER_SIDE`], dB.
    pub strength: f32,
}

/// Statistics -> water, linear on standardised statistics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Regressor {
    /// Mean of each statistic over the training pairs.
    pub mean: [f32; N_FEATURES],
    /// Standard deviation of each statistic over the training pairs.
    pub scale: [f32; N_FEATURES],
    /// `(N_FEATURES + 1) x 6`: a row per standardised statistic, then the intercept.
    pub weights: Vec<[f32; 6]>,
    /// The ridge penalty it was fitted with.
    pub lambda: f64,
}

impl Regressor {
    /// Ridge regression of the entries' waters on their statistics.
    pub fn fit(entries: &[BankEntry], lambda: f64) -> Result<Self> {
        if entries.len() < 2 {
            return Err(ModelError::InvalidOptions(format!(
                "a water regressor needs at least 2 pairs, got {}",
                entries.len()
            )));
        }
        let n = entries.len() as f64;
        let mut mean = [0.0f64; N_FEATURES];
        for e in entries {
            for (m, &f) in mean.iter_mut().zip(&e.features) {
                *m += f64::from(f) / n;
            }
        }
        let mut scale = [0.0f64; N_FEATURES];
        for e in entries {
            for ((s, &f), m) in scale.iter_mut().zip(&e.features).zip(&mean) {
                *s += (f64::from(f) - m).powi(2) / n;
            }
        }
        let scale = scale.map(|v| v.sqrt() + 1e-6);
        const K: usize = N_FEATURES + 1;
        // Normal equations (Z^T Z + lambda I) W = Z^T Y, the intercept column penalised too
        // (as the prototype that chose lambda did).
        let mut a = vec![[0.0f64; K]; K];
        let mut rhs = vec![[0.0f64; 6]; K];
        for e in entries {
            let mut z = [1.0f64; K];
            for i in 0..N_FEATURES {
                z[i] = (f64::from(e.features[i]) - mean[i]) / scale[i];
            }
            let y = e.water.to_vec();
            for i in 0..K {
                for j in 0..K {
                    a[i][j] += z[i] * z[j];
                }
                for (r, yv) in rhs[i].iter_mut().zip(&y) {
                    *r += z[i] * yv;
                }
            }
        }
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += lambda;
        }
        let w = solve(a, rhs)?;
        Ok(Self {
            mean: mean.map(|v| v as f32),
            scale: scale.map(|v| v as f32),
            weights: w.iter().map(|r| r.map(|v| v as f32)).collect(),
            lambda,
        })
    }

    /// The water predicted for an underwater image of statistics `features`, clamped.
    #[must_use]
    pub fn predict(&self, features: &[f32; N_FEATURES]) -> Affine {
        let mut out = [0.0f64; 6];
        for (i, row) in self.weights.iter().enumerate() {
            let z = if i < N_FEATURES {
                (f64::from(features[i]) - f64::from(self.mean[i])) / f64::from(self.scale[i])
            } else {
                1.0
            };
            for (o, &w) in out.iter_mut().zip(row) {
                *o += z * f64::from(w);
            }
        }
        Affine::from_vec(out).clamped()
    }

    /// Checks the shape of a regressor read from a file.
    pub fn validate(&self) -> Result<()> {
        if self.weights.len() != N_FEATURES + 1
            || self.weights.iter().flatten().any(|v| !v.is_finite())
            || self.scale.iter().any(|&s| !(s.is_finite() && s > 0.0))
        {
            return Err(ModelError::InvalidOptions(format!(
                "a water regressor has {} rows of 6 finite weights and positive scales",
                N_FEATURES + 1
            )));
        }
        Ok(())
    }
}

/// Gaussian elimination with partial pivoting for a small dense system with six right-hand
/// sides.
fn solve<const K: usize>(mut a: Vec<[f64; K]>, mut b: Vec<[f64; 6]>) -> Result<Vec<[f64; 6]>> {
    for col in 0..K {
        let pivot = (col..K)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap_or(col);
        if a[pivot][col].abs() < 1e-12 {
            return Err(ModelError::InvalidOptions(
                "the water regression is singular".into(),
            ));
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..K {
            let f = a[row][col] / a[col][col];
            if f == 0.0 {
                continue;
            }
            let (pr, pb) = (a[col], b[col]);
            for k in col..K {
                a[row][k] -= f * pr[k];
            }
            for k in 0..6 {
                b[row][k] -= f * pb[k];
            }
        }
    }
    let mut x = vec![[0.0f64; 6]; K];
    for row in (0..K).rev() {
        for k in 0..6 {
            let s: f64 = (row + 1..K).map(|j| a[row][j] * x[j][k]).sum();
            x[row][k] = (b[row][k] - s) / a[row][row];
        }
    }
    Ok(x)
}

/// The waters of a set of real pairs and the regressor fitted to them: what `uwnr water fit`
/// writes and what the bundled renderer predicts the reference's water with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WaterBank {
    /// The pair folders it was fitted on, as given.
    pub sources: Vec<String>,
    /// One entry per pair.
    pub entries: Vec<BankEntry>,
    /// Statistics -> water.
    pub regressor: Regressor,
}

impl WaterBank {
    /// Fits the bank of `entries` (regressor with [`RIDGE_LAMBDA`]).
    pub fn fit(sources: Vec<String>, entries: Vec<BankEntry>) -> Result<Self> {
        let regressor = Regressor::fit(&entries, RIDGE_LAMBDA)?;
        Ok(Self {
            sources,
            entries,
            regressor,
        })
    }

    /// Reads a bank from JSON, checked.
    pub fn from_json(text: &str) -> Result<Self> {
        let bank: Self = serde_json::from_str(text)
            .map_err(|e| ModelError::InvalidOptions(format!("water bank: {e}")))?;
        bank.regressor.validate()?;
        Ok(bank)
    }

    /// The water predicted for the underwater photo `reference`.
    pub fn predict(&self, reference: &Image) -> Result<Affine> {
        Ok(self.regressor.predict(&water_features(reference)?))
    }
}

/// The bank the bundled renderer uses (`assets/model/water-bank.json`, made by
/// `uwnr water fit`; the command is in that folder's README).
pub fn bundled_bank() -> Result<&'static WaterBank> {
    static BANK: OnceLock<std::result::Result<WaterBank, String>> = OnceLock::new();
    BANK.get_or_init(|| {
        WaterBank::from_json(include_str!("../../../../assets/model/water-bank.json"))
            .map_err(|e| e.to_string())
    })
    .as_ref()
    .map_err(|e| ModelError::InvalidOptions(format!("the bundled water bank: {e}")))
}

/// The entry of one real pair.
pub fn bank_entry(name: String, clean: &Image, under: &Image) -> Result<BankEntry> {
    // Both sides brought to the fitting size once; the fit and the statistics then find them
    // at that size (a same-size resize is an exact copy), so the values are those of the
    // originals.
    let u = fit_within(under, WATER_SIDE)?;
    let (w, h) = u.size();
    let c = resize_bilinear(clean, w, h)?;
    Ok(BankEntry {
        name,
        features: water_features(&u)?,
        water: fit_pair(&c, &u)?,
        strength: pair_psnr(&u, &c)?,
    })
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
