//! UIQM, the underwater image quality measure of Panetta, Gao and Agaian 2016 ("Human-visual-
//! system-inspired underwater image quality measures", IEEE J. Oceanic Eng.):
//! `UIQM = 0.0282 UICM + 0.2953 UISM + 3.5753 UIConM`.
//!
//! Implementations in circulation disagree (block size, channel order, logAMEE vs a plain
//! entropy term, the blue weight). This one follows, operation for operation, the Python code
//! most underwater papers run: `Evaluation/uqim_utils.py` of xahidbuffon/FUnIE-GAN, with the
//! integer block counts `int(W / block)` that the Python 3 copies use:
//! - pixel values 0..255: the image is quantised to 8 bits first (`round(255 v)`), as those
//!   scripts read 8-bit files. This matters: the EME below tests block minima for exact zero,
//!   and a Sobel response of 1e-13 where integers would cancel exactly adds `log(max / 1e-13)`;
//! - UICM: `RG = R - G`, `YB = (R + G) / 2 - B`; `-0.0268 sqrt(mu_RG^2 + mu_YB^2) +
//!   0.1586 sqrt(s_RG + s_YB)` with the asymmetric alpha-trimmed mean (alpha_L = alpha_R = 0.1)
//!   exactly as coded there: sort, drop `ceil(0.1 K) + 1` values on the left and
//!   `floor(0.1 K)` on the right, divide by `K - ceil(0.1 K) - floor(0.1 K)`; s = mean squared
//!   deviation from that mean over *all* values;
//! - UISM: per channel, the Sobel magnitude (`scipy.ndimage.sobel`, reflect border) rescaled to
//!   a maximum of 255, times the channel; `EME = 2 / (k1 k2) sum ln(max / min)` over
//!   non-overlapping `block x block` tiles (the right/bottom remainder dropped; tiles whose
//!   min or max is 0 add 0); weights 0.299, 0.587 and 0.144 (sic, not 0.114, as coded);
//! - UIConM: over the same tiles, max and min across all three channels,
//!   `-1 / (k1 k2) sum (t) ln(t)` with `t = (max - min) / (max + min)` (0 when either is 0).
//!
//! Presets: [`UiqmConfig::funie_gan`] (10x10 tiles, RGB; the default) and
//! [`UiqmConfig::shallow_uwnet`] (8x8 tiles and the channels taken as B, G, R, as
//! mkartik/Shallow-UWnet's `uiqm_utils.py` receives them from `cv2.imread`; the UWNR paper's
//! downstream UIQM numbers come from that script). Both scripts resize to 256x256 before
//! measuring; this module measures the image it is given.
//!
//! One deliberate difference: for a channel with no edges at all the reference computes
//! `0 * 255 / 0 = NaN`; here its Sobel map stays 0, so its EME is 0 and UIQM stays finite.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::error::{MetricsError, Result, check_finite_image, check_rgb};
use crate::filter::{PlaneF64, sobel_magnitude};

/// UIQM weights c1, c2, c3 (Panetta et al. 2016).
pub const UIQM_WEIGHTS: [f64; 3] = [0.0282, 0.2953, 3.5753];
/// UICM weights on the trimmed-mean magnitude and the spread (Panetta et al. 2016).
pub const UICM_WEIGHTS: [f64; 2] = [-0.0268, 0.1586];
/// Trimming fractions alpha_L = alpha_R of the UICM mean.
pub const UICM_ALPHA: f64 = 0.1;
/// UISM channel weights as coded in FUnIE-GAN's `uqim_utils.py` (the paper's 0.114 reads 0.144).
pub const UISM_WEIGHTS: [f64; 3] = [0.299, 0.587, 0.144];
/// The 8-bit scale the reference scripts measure on.
pub const UIQM_PIXEL_SCALE: f64 = 255.0;
/// Tile sides of the two presets.
pub const FUNIE_GAN_BLOCK: usize = 10;
pub const SHALLOW_UWNET_BLOCK: usize = 8;

/// Order in which the three planes are fed to the formulas.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ChannelOrder {
    /// R, G, B (FUnIE-GAN reads files with PIL).
    #[default]
    Rgb,
    /// B, G, R (scripts that read with OpenCV without converting).
    Bgr,
}

/// Parameters of [`uiqm_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct UiqmConfig {
    /// Side of the EME / UIConM tiles.
    pub block: usize,
    /// Which plane plays "R", "G" and "B".
    pub channel_order: ChannelOrder,
    /// Quantise to the 8-bit grid first (what the reference scripts see when reading files).
    pub quantize_u8: bool,
}

impl UiqmConfig {
    /// FUnIE-GAN's `uqim_utils.py`: 10x10 tiles, RGB.
    #[must_use]
    pub fn funie_gan() -> Self {
        Self {
            block: FUNIE_GAN_BLOCK,
            channel_order: ChannelOrder::Rgb,
            quantize_u8: true,
        }
    }

    /// Shallow-UWnet's `uiqm_utils.py` on `cv2.imread` arrays: 8x8 tiles, BGR.
    #[must_use]
    pub fn shallow_uwnet() -> Self {
        Self {
            block: SHALLOW_UWNET_BLOCK,
            channel_order: ChannelOrder::Bgr,
            quantize_u8: true,
        }
    }
}

impl Default for UiqmConfig {
    fn default() -> Self {
        Self::funie_gan()
    }
}

/// UIQM and its three terms.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UiqmComponents {
    /// Colourfulness.
    pub uicm: f64,
    /// Sharpness.
    pub uism: f64,
    /// Contrast.
    pub uiconm: f64,
    /// `0.0282 uicm + 0.2953 uism + 3.5753 uiconm`.
    pub uiqm: f64,
}

/// UIQM of an RGB image with the FUnIE-GAN settings ([`UiqmConfig::funie_gan`]).
pub fn uiqm(img: &Image) -> Result<f64> {
    Ok(uiqm_with(img, &UiqmConfig::funie_gan())?.uiqm)
}

/// UIQM and its terms with explicit settings. The image must be RGB and at least one tile large.
pub fn uiqm_with(img: &Image, cfg: &UiqmConfig) -> Result<UiqmComponents> {
    check_rgb("UIQM", img)?;
    check_finite_image("UIQM input", img)?;
    if cfg.block < 2 {
        return Err(MetricsError::InvalidArgument(format!(
            "UIQM block must be at least 2 pixels, got {}",
            cfg.block
        )));
    }
    if img.width() < cfg.block || img.height() < cfg.block {
        return Err(MetricsError::TooSmall {
            metric: "UIQM",
            width: img.width(),
            height: img.height(),
            min: cfg.block,
        });
    }
    let order = match cfg.channel_order {
        ChannelOrder::Rgb => [0, 1, 2],
        ChannelOrder::Bgr => [2, 1, 0],
    };
    let (w, h) = img.size();
    let planes: Vec<PlaneF64> = order
        .iter()
        .map(|&c| {
            let data = img
                .plane(c)
                .iter()
                .map(|&v| {
                    let v = f64::from(v);
                    if cfg.quantize_u8 {
                        (v.clamp(0.0, 1.0) * UIQM_PIXEL_SCALE).round_ties_even()
                    } else {
                        v * UIQM_PIXEL_SCALE
                    }
                })
                .collect();
            PlaneF64::new(w, h, data)
        })
        .collect();

    let uicm = uicm(&planes);
    let uism = uism(&planes, cfg.block);
    let uiconm = uiconm(&planes, cfg.block);
    let uiqm = UIQM_WEIGHTS[0] * uicm + UIQM_WEIGHTS[1] * uism + UIQM_WEIGHTS[2] * uiconm;
    Ok(UiqmComponents {
        uicm,
        uism,
        uiconm,
        uiqm,
    })
}

/// FUnIE-GAN's `mu_a`: the asymmetric alpha-trimmed mean with its off-by-one left cut.
fn trimmed_mean(mut v: Vec<f64>) -> f64 {
    v.par_sort_unstable_by(f64::total_cmp);
    let k = v.len();
    // The same float expressions as the reference, so the cut points agree for every K.
    let t_l = (UICM_ALPHA * k as f64).ceil() as usize;
    let t_r = (UICM_ALPHA * k as f64).floor() as usize;
    let start = (t_l + 1).min(k);
    let end = k - t_r;
    let sum: f64 = if start < end {
        v[start..end].iter().sum()
    } else {
        0.0
    };
    sum / (k - t_l - t_r) as f64
}

fn mean_sq_dev(v: &[f64], mu: f64) -> f64 {
    v.iter().map(|x| (x - mu) * (x - mu)).sum::<f64>() / v.len() as f64
}

fn uicm(p: &[PlaneF64]) -> f64 {
    let (r, g, b) = (&p[0].data, &p[1].data, &p[2].data);
    let rg: Vec<f64> = r.iter().zip(g).map(|(r, g)| r - g).collect();
    let yb: Vec<f64> = r
        .iter()
        .zip(g)
        .zip(b)
        .map(|((r, g), b)| (r + g) / 2.0 - b)
        .collect();
    let (mu_rg, mu_yb) = rayon::join(|| trimmed_mean(rg.clone()), || trimmed_mean(yb.clone()));
    let s_rg = mean_sq_dev(&rg, mu_rg);
    let s_yb = mean_sq_dev(&yb, mu_yb);
    UICM_WEIGHTS[0] * mu_rg.hypot(mu_yb) + UICM_WEIGHTS[1] * (s_rg + s_yb).sqrt()
}

/// Tiles `(x0, y0)` of the `k1 x k2` grid and the grid's tile count.
fn tiles(w: usize, h: usize, block: usize) -> (usize, usize) {
    (w / block, h / block)
}

/// `EME = 2 / (k1 k2) sum ln(max / min)` over tiles; tiles with min or max 0 add 0.
fn eme(p: &PlaneF64, block: usize) -> f64 {
    let (k1, k2) = tiles(p.width, p.height, block);
    let mut val = 0.0;
    for l in 0..k1 {
        for k in 0..k2 {
            let (mut mx, mut mn) = (f64::NEG_INFINITY, f64::INFINITY);
            for y in k * block..(k + 1) * block {
                for &v in &p.data[y * p.width + l * block..y * p.width + (l + 1) * block] {
                    mx = mx.max(v);
                    mn = mn.min(v);
                }
            }
            if mn != 0.0 && mx != 0.0 {
                val += (mx / mn).ln();
            }
        }
    }
    2.0 / (k1 * k2) as f64 * val
}

fn uism(p: &[PlaneF64], block: usize) -> f64 {
    let emes: Vec<f64> = p
        .par_iter()
        .map(|ch| {
            let mag = sobel_magnitude(ch);
            let max = mag.data.iter().copied().fold(0.0, f64::max);
            let edge = if max > 0.0 {
                let factor = UIQM_PIXEL_SCALE / max;
                mag.zip_map(ch, |m, v| m * factor * v)
            } else {
                mag
            };
            eme(&edge, block)
        })
        .collect();
    emes.iter().zip(UISM_WEIGHTS).map(|(e, w)| w * e).sum()
}

fn uiconm(p: &[PlaneF64], block: usize) -> f64 {
    let (w, h) = (p[0].width, p[0].height);
    let (k1, k2) = tiles(w, h, block);
    let mut val = 0.0;
    for l in 0..k1 {
        for k in 0..k2 {
            let (mut mx, mut mn) = (f64::NEG_INFINITY, f64::INFINITY);
            for ch in p {
                for y in k * block..(k + 1) * block {
                    for &v in &ch.data[y * w + l * block..y * w + (l + 1) * block] {
                        mx = mx.max(v);
                        mn = mn.min(v);
                    }
                }
            }
            let (top, bot) = (mx - mn, mx + mn);
            if top != 0.0 && bot != 0.0 {
                let t = top / bot;
                val += t * t.ln();
            }
        }
    }
    -1.0 / (k1 * k2) as f64 * val
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trimmed_mean_follows_the_reference_cut() {
        // K = 10: ceil(1.0) = 1 and floor(1.0) = 1; values 2..=8 (indices 2..9) are summed
        // and divided by 10 - 2 = 8.
        let v: Vec<f64> = (0..10).map(f64::from).collect();
        let want = (2..9).map(f64::from).sum::<f64>() / 8.0;
        assert_eq!(trimmed_mean(v), want);
        // K = 25: ceil(2.5) = 3 on the left (plus one), floor(2.5) = 2 on the right.
        let v: Vec<f64> = (0..25).map(f64::from).collect();
        let want = (4..23).map(f64::from).sum::<f64>() / (25.0 - 3.0 - 2.0);
        assert_eq!(trimmed_mean(v), want);
    }

    #[test]
    fn flat_images_give_finite_values() {
        for v in [0.0, 0.4, 1.0] {
            let img = Image::filled(20, 20, 3, v);
            let c = uiqm_with(&img, &UiqmConfig::funie_gan()).unwrap();
            assert!(c.uiqm.is_finite(), "{v}: {c:?}");
            assert_eq!(c.uism, 0.0);
            assert_eq!(c.uiconm, 0.0);
        }
    }

    #[test]
    fn grey_images_have_no_colourfulness_penalty_but_no_colour_either() {
        let mut img = Image::filled(20, 20, 3, 0.0);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                *v = (i % 20) as f32 / 19.0;
            }
        }
        let c = uiqm_with(&img, &UiqmConfig::funie_gan()).unwrap();
        assert_eq!(c.uicm, 0.0);
        assert!(c.uism > 0.0 && c.uiconm > 0.0, "{c:?}");
    }

    #[test]
    fn bgr_order_swaps_red_and_blue() {
        let mut img = Image::filled(16, 16, 3, 0.2);
        for (i, v) in img.plane_mut(0).iter_mut().enumerate() {
            *v = 0.3 + 0.5 * ((i * 7 % 13) as f32 / 13.0);
        }
        let mut swapped = img.clone();
        let red = img.plane(0).to_vec();
        let blue = img.plane(2).to_vec();
        swapped.plane_mut(0).copy_from_slice(&blue);
        swapped.plane_mut(2).copy_from_slice(&red);
        let rgb = UiqmConfig {
            block: 8,
            ..UiqmConfig::funie_gan()
        };
        let a = uiqm_with(&img, &UiqmConfig::shallow_uwnet()).unwrap();
        let b = uiqm_with(&swapped, &rgb).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn rejects_small_and_grey_images() {
        let img = Image::filled(9, 30, 3, 0.5);
        assert!(matches!(
            uiqm(&img),
            Err(MetricsError::TooSmall { min: 10, .. })
        ));
        let g = Image::filled(30, 30, 1, 0.5);
        assert!(matches!(uiqm(&g), Err(MetricsError::NotRgb { .. })));
    }
}
