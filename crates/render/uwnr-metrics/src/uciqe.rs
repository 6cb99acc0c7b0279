//! UCIQE, the underwater colour image quality evaluation of Yang and Sowmya 2015 ("An underwater
//! color image quality evaluation metric", IEEE TIP): `UCIQE = 0.4680 sigma_c + 0.2745 con_l
//! + 0.2576 mu_s`.
//!
//! Implementations differ in colour space scaling and in what "saturation" and "contrast" mean.
//! This one follows `nmetrics` in `nevaluate.py` of xueleichen/PSNR-SSIM-UCIQE-UIQM-Python (the
//! version after its 2022 fix of con_l), the skimage-based script many papers cite:
//! - CIE L*a*b* of the sRGB image as `skimage.color.rgb2lab` (D65; L in 0..100), through
//!   [`uwnr_core::color::rgb_to_lab_px`];
//! - `sigma_c`: population standard deviation of chroma `sqrt(a^2 + b^2)`;
//! - `con_l`: mean of the brightest `round(1% N)` L values minus mean of the darkest
//!   `round(1% N)` (numpy's round-half-even; at least one pixel here, where the script would
//!   average an empty slice below 50 pixels);
//! - `mu_s`: mean over pixels of `chroma / L`, 0 where chroma or L is 0.
//!
//! Because L, a and b keep skimage's units, values are around 10..40 for natural photos, not
//! the 0..1 of implementations that rescale Lab (OpenCV's 8-bit Lab, MATLAB ports).
//! The image is measured as given (f32 in [0, 1] widened to f64; no quantisation).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::color::rgb_to_lab_px;

use crate::error::{Result, check_finite_image, check_rgb};

/// UCIQE weights c1, c2, c3 (Yang and Sowmya 2015).
pub const UCIQE_WEIGHTS: [f64; 3] = [0.4680, 0.2745, 0.2576];
/// Fraction of pixels at each end of the luminance range that defines con_l.
pub const UCIQE_CONTRAST_FRACTION: f64 = 0.01;

/// UCIQE and its three terms.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UciqeComponents {
    /// Standard deviation of chroma.
    pub sigma_c: f64,
    /// Contrast of luminance (top 1% mean minus bottom 1% mean of L).
    pub con_l: f64,
    /// Mean saturation `chroma / L`.
    pub mu_s: f64,
    /// `0.4680 sigma_c + 0.2745 con_l + 0.2576 mu_s`.
    pub uciqe: f64,
}

/// UCIQE of an RGB image.
pub fn uciqe(img: &Image) -> Result<f64> {
    Ok(uciqe_components(img)?.uciqe)
}

/// UCIQE and its terms.
pub fn uciqe_components(img: &Image) -> Result<UciqeComponents> {
    check_rgb("UCIQE", img)?;
    check_finite_image("UCIQE input", img)?;
    let (r, g, b) = (img.plane(0), img.plane(1), img.plane(2));
    // (L, chroma) per pixel.
    let lc: Vec<(f64, f64)> = (0..r.len())
        .into_par_iter()
        .map(|i| {
            let lab = rgb_to_lab_px([f64::from(r[i]), f64::from(g[i]), f64::from(b[i])]);
            (lab[0], (lab[1] * lab[1] + lab[2] * lab[2]).sqrt())
        })
        .collect();
    let n = lc.len();
    let nf = n as f64;

    let mean_c = lc.iter().map(|p| p.1).sum::<f64>() / nf;
    let sigma_c = (lc
        .iter()
        .map(|p| (p.1 - mean_c) * (p.1 - mean_c))
        .sum::<f64>()
        / nf)
        .sqrt();

    let mut lum: Vec<f64> = lc.iter().map(|p| p.0).collect();
    lum.par_sort_unstable_by(f64::total_cmp);
    let top = ((UCIQE_CONTRAST_FRACTION * nf).round_ties_even() as usize).clamp(1, n);
    let high = lum[n - top..].iter().sum::<f64>() / top as f64;
    let low = lum[..top].iter().sum::<f64>() / top as f64;
    let con_l = high - low;

    let mu_s = lc
        .iter()
        .map(|&(l, c)| if c != 0.0 && l != 0.0 { c / l } else { 0.0 })
        .sum::<f64>()
        / nf;

    let uciqe = UCIQE_WEIGHTS[0] * sigma_c + UCIQE_WEIGHTS[1] * con_l + UCIQE_WEIGHTS[2] * mu_s;
    Ok(UciqeComponents {
        sigma_c,
        con_l,
        mu_s,
        uciqe,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MetricsError;

    #[test]
    fn flat_images_have_no_spread_or_contrast() {
        for v in [0.0, 0.3, 1.0] {
            let c = uciqe_components(&Image::filled(5, 7, 3, v)).unwrap();
            assert!(c.uciqe.is_finite());
            assert!(c.sigma_c.abs() < 1e-12, "{c:?}");
            assert_eq!(c.con_l, 0.0);
        }
        // Black: L = 0 and chroma = 0, so saturation counts 0.
        assert_eq!(uciqe(&Image::filled(4, 4, 3, 0.0)).unwrap(), 0.0);
    }

    #[test]
    fn half_black_half_white_has_full_luminance_contrast() {
        let mut img = Image::filled(10, 10, 3, 0.0);
        for c in 0..3 {
            for v in &mut img.plane_mut(c)[50..] {
                *v = 1.0;
            }
        }
        let c = uciqe_components(&img).unwrap();
        assert!((c.con_l - 100.0).abs() < 1e-3, "{c:?}");
        assert!(c.sigma_c < 1e-2 && c.mu_s < 1e-3, "{c:?}");
    }

    #[test]
    fn pixel_order_does_not_matter() {
        let mut img = Image::filled(6, 4, 3, 0.0);
        for (i, v) in img.data_mut().iter_mut().enumerate() {
            *v = ((i * 37 % 71) as f32) / 71.0;
        }
        let mut flipped = img.clone();
        for c in 0..3 {
            flipped.plane_mut(c).reverse();
        }
        let (a, b) = (uciqe(&img).unwrap(), uciqe(&flipped).unwrap());
        assert!((a - b).abs() < 1e-12, "{a} {b}");
    }

    #[test]
    fn needs_rgb() {
        let g = Image::filled(4, 4, 1, 0.5);
        assert!(matches!(uciqe(&g), Err(MetricsError::NotRgb { .. })));
    }
}
