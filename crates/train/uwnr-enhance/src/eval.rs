//! Scoring an enhancer on a paired test folder, as the paper's downstream experiment does
//! (its Table 1): each underwater image is enhanced, and the output is scored against its
//! clean partner with PSNR and SSIM and on its own with UIQM and UCIQE ([`uwnr_metrics`]:
//! scikit-image conventions for PSNR/SSIM, FUnIE-GAN's UIQM, the common UCIQE script).
//!
//! Outputs are rounded to 8 bits before scoring, so the scores equal those of the written PNG
//! files (`uwnr eval --pred DIR --target DIR` on `save_to` gives the same numbers). Without a
//! network the underwater input itself is scored: the "no enhancement" row of the table.
//!
//! Unpaired names are listed in [`EvalReport::skipped`]; a pair that cannot be decoded or whose
//! images differ in size is an error, so a score always covers the whole test set.

use std::collections::HashSet;
use std::path::Path;

use burn::tensor::Device;
use serde::Serialize;
use uwnr_core::io::{DecodeLimits, save_rgb};
use uwnr_core::resize::{fit_within_dims, resize_bilinear};
use uwnr_metrics::{DEFAULT_DATA_RANGE, psnr, ssim, uciqe, uiqm};
use uwnr_run::RunError;
use uwnr_run::pairs::{SizeMismatch, decode_pair, discover_pairs};

use crate::error::{EnhanceError, Result};
use crate::model::ShallowUwnet;

/// Scores of one test pair.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageScore {
    /// File name of the pair.
    pub name: String,
    /// PSNR (dB) of the output against the clean image.
    pub psnr: f64,
    /// SSIM of the output against the clean image.
    pub ssim: f64,
    /// UIQM of the output.
    pub uiqm: f64,
    /// UCIQE of the output.
    pub uciqe: f64,
    /// The pair's size when it was downscaled for `max_side` (it was scored smaller).
    pub downscaled_from: Option<(usize, usize)>,
}

/// Scores of a test folder.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EvalReport {
    /// One row per pair, in file-name order.
    pub per_image: Vec<ImageScore>,
    /// Mean PSNR (dB).
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean UIQM.
    pub uiqm: f64,
    /// Mean UCIQE.
    pub uciqe: f64,
    /// Files left out because they have no partner (`path: reason`).
    pub skipped: Vec<String>,
}

/// Scores `net` on the paired folder `dir` (`underwater/` + `clean/`, or `raw-890/` +
/// `reference-890/`).
///
/// `net` `None` = "no enhancement": the underwater input itself is scored. `save_to` writes each
/// output there as `STEM.png` (atomically). With `max_side` `Some(n)`, pairs whose longer side
/// exceeds `n` are downscaled (aspect kept, antialiased) before enhancing and scoring, and
/// [`ImageScore::downscaled_from`] records it.
pub fn evaluate_dir(
    net: Option<&ShallowUwnet>,
    dir: &Path,
    device: &Device,
    save_to: Option<&Path>,
    max_side: Option<usize>,
    limits: &DecodeLimits,
) -> Result<EvalReport> {
    if max_side == Some(0) {
        return Err(EnhanceError::InvalidConfig(
            "max_side must be at least 1".into(),
        ));
    }
    let found = discover_pairs(dir, None)?;
    if let Some(out) = save_to {
        std::fs::create_dir_all(out).map_err(|source| RunError::Io {
            path: out.to_path_buf(),
            source,
        })?;
    }
    let mut taken = HashSet::new();
    let mut per_image = Vec::with_capacity(found.pairs.len());
    for p in &found.pairs {
        let pair = decode_pair(p, limits, SizeMismatch::Refuse)?;
        let (input, target) = (pair.underwater, pair.clean);
        let (input, target, downscaled_from) = match max_side {
            Some(n) if input.width().max(input.height()) > n => {
                let (w, h) = fit_within_dims(input.size(), n);
                (
                    resize_bilinear(&input, w, h)?,
                    resize_bilinear(&target, w, h)?,
                    Some(input.size()),
                )
            }
            _ => (input, target, None),
        };
        let out = match net {
            Some(net) => crate::infer::enhance(net, &input, device)?,
            None => input,
        };
        let out = out.quantised();
        let score = |e: uwnr_metrics::MetricsError| EnhanceError::BadPair {
            path: p.underwater.clone(),
            reason: format!("scoring: {e}"),
        };
        per_image.push(ImageScore {
            name: p.name.clone(),
            psnr: psnr(&out, &target, DEFAULT_DATA_RANGE).map_err(score)?,
            ssim: ssim(&out, &target, DEFAULT_DATA_RANGE).map_err(score)?,
            uiqm: uiqm(&out).map_err(score)?,
            uciqe: uciqe(&out).map_err(score)?,
            downscaled_from,
        });
        if let Some(dir) = save_to {
            let name = output_name(&p.name, &mut taken);
            save_rgb(&dir.join(name), &out)?;
        }
    }
    let n = per_image.len().max(1) as f64;
    let mean = |f: fn(&ImageScore) -> f64| per_image.iter().map(f).sum::<f64>() / n;
    Ok(EvalReport {
        psnr: mean(|s| s.psnr),
        ssim: mean(|s| s.ssim),
        uiqm: mean(|s| s.uiqm),
        uciqe: mean(|s| s.uciqe),
        skipped: found
            .skipped
            .iter()
            .map(|s| format!("{}: {}", s.path.display(), s.reason))
            .collect(),
        per_image,
    })
}

/// `STEM.png`, or `STEM-2.png`, ... when that name is taken.
fn output_name(file: &str, taken: &mut HashSet<String>) -> String {
    let stem = Path::new(file)
        .file_stem()
        .map_or_else(|| "image".to_string(), |s| s.to_string_lossy().into_owned());
    let name = (1..)
        .map(|k| {
            if k == 1 {
                format!("{stem}.png")
            } else {
                format!("{stem}-{k}.png")
            }
        })
        .find(|c| !taken.contains(c))
        .unwrap_or_default();
    taken.insert(name.clone());
    name
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_names_are_unique() {
        let mut taken = HashSet::new();
        assert_eq!(output_name("a.jpg", &mut taken), "a.png");
        assert_eq!(output_name("a.png", &mut taken), "a-2.png");
        assert_eq!(output_name("b.tif", &mut taken), "b.png");
    }
}
