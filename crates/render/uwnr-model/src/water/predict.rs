//! A water predicted from an underwater photo alone: the photo's colour statistics
//! ([`water_features`]), a ridge regression from them to the affine water ([`Regressor`]), and
//! the bank of real pairs it is fitted on ([`WaterBank`], `uwnr water fit`).

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::resize::{fit_within, resize_bilinear};

use super::{Affine, WATER_SIDE, fit_pair, pair_psnr};
use crate::error::{ModelError, Result};

/// The percentiles of each channel among the statistics.
pub const FEATURE_PERCENTILES: [f64; 3] = [0.02, 0.5, 0.98];
/// Statistics per image: per channel the mean, the standard deviation and the
/// [`FEATURE_PERCENTILES`].
pub const N_FEATURES: usize = 15;
/// Ridge penalty on the standardised statistics (chosen among 0.1, 1 and 3: the three were within
/// 0.2 dB of each other on held-out pairs).
pub const RIDGE_LAMBDA: f64 = 1.0;

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
pub(super) fn percentile(sorted: &[f32], q: f64) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let (lo, frac) = (pos.floor() as usize, pos - pos.floor());
    let hi = (lo + 1).min(sorted.len() - 1);
    (f64::from(sorted[lo]) * (1.0 - frac) + f64::from(sorted[hi]) * frac) as f32
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
        WaterBank::from_json(include_str!("../../../../../assets/model/water-bank.json"))
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
