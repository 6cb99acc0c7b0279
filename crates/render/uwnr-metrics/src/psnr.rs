//! Peak signal-to-noise ratio, `PSNR = 10 log10(R^2 / MSE)`, as
//! `skimage.metrics.peak_signal_noise_ratio(target, pred, data_range=R)` computes it: the mean
//! squared error over every value of every channel, in f64.
//!
//! `psnr_gray` measures the same on ITU-R BT.601 luma `Y = 0.299 R + 0.587 G + 0.114 B` of the
//! (gamma-encoded) RGB values, the weights of OpenCV's `cvtColor(RGB2GRAY)` that Shallow-UWnet's
//! evaluation (`metrics_calculation.py`) uses for its PSNR. Y is kept in f64 (OpenCV rounds it
//! to u8 first, which moves PSNR by a few hundredths of a dB); it is not the 16..235
//! "studio-range" Y of YCbCr that super-resolution papers call the Y channel.

use uwnr_core::Image;

use crate::error::{Result, check_data_range, check_rgb, check_same_shape};
use crate::filter::PlaneF64;

/// The data range of images in [0, 1] (uwnr's `Image` convention): the default `R`.
pub const DEFAULT_DATA_RANGE: f64 = 1.0;

/// ITU-R BT.601 luma weights for R, G, B (OpenCV `RGB2GRAY`).
pub const LUMA_BT601: [f64; 3] = [0.299, 0.587, 0.114];

/// Mean squared error over all values of two images of the same shape, in f64.
pub fn mse(pred: &Image, target: &Image) -> Result<f64> {
    check_same_shape(pred, target)?;
    Ok(mean_squared_diff(pred.data(), target.data()))
}

fn mean_squared_diff(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len().max(1);
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = f64::from(x) - f64::from(y);
            d * d
        })
        .sum();
    sum / n as f64
}

fn psnr_from_mse(mse: f64, data_range: f64) -> f64 {
    // MSE 0 (identical images) gives +inf, as skimage returns.
    10.0 * (data_range * data_range / mse).log10()
}

/// PSNR in dB over all channels, `10 log10(data_range^2 / MSE)`; `+inf` for identical images.
///
/// Images are compared as given (uwnr's [0, 1] f32, widened to f64; an 8-bit file therefore
/// counts as u8 / 255), so `data_range` is 1.0 ([`DEFAULT_DATA_RANGE`]) for them.
pub fn psnr(pred: &Image, target: &Image, data_range: f64) -> Result<f64> {
    check_data_range(data_range)?;
    Ok(psnr_from_mse(mse(pred, target)?, data_range))
}

/// PSNR in dB on ITU-R BT.601 luma ([`LUMA_BT601`]) of two RGB images; `+inf` when equal.
pub fn psnr_gray(pred: &Image, target: &Image, data_range: f64) -> Result<f64> {
    check_data_range(data_range)?;
    check_same_shape(pred, target)?;
    check_rgb("PSNR (luma)", pred)?;
    let (a, b) = (luma_bt601(pred), luma_bt601(target));
    let sum: f64 = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    Ok(psnr_from_mse(sum / a.data.len().max(1) as f64, data_range))
}

/// BT.601 luma of an RGB image as an f64 plane (the caller checks the channel count).
pub(crate) fn luma_bt601(img: &Image) -> PlaneF64 {
    let (r, g, b) = (img.plane(0), img.plane(1), img.plane(2));
    let data = r
        .iter()
        .zip(g)
        .zip(b)
        .map(|((&r, &g), &b)| {
            LUMA_BT601[0] * f64::from(r)
                + LUMA_BT601[1] * f64::from(g)
                + LUMA_BT601[2] * f64::from(b)
        })
        .collect();
    PlaneF64::new(img.width(), img.height(), data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MetricsError;

    #[test]
    fn constant_error_of_a_tenth_is_20_db() {
        let target = Image::filled(8, 6, 3, 0.5);
        let pred = Image::filled(8, 6, 3, 0.6);
        let v = psnr(&pred, &target, 1.0).unwrap();
        // (0.6 - 0.5) in f32 is 0.1 to about 1e-8, hence the tolerance.
        assert!((v - 20.0).abs() < 1e-5, "{v}");
        let g = psnr_gray(&pred, &target, 1.0).unwrap();
        assert!((g - 20.0).abs() < 1e-5, "{g}");
        // A data range of 255 on the same numbers adds 20 log10(255) dB.
        let v255 = psnr(&pred, &target, 255.0).unwrap();
        assert!((v255 - v - 20.0 * 255f64.log10()).abs() < 1e-9);
    }

    #[test]
    fn identical_images_give_infinity_and_psnr_is_symmetric() {
        let a = Image::filled(4, 4, 3, 0.25);
        assert_eq!(psnr(&a, &a, 1.0).unwrap(), f64::INFINITY);
        let mut b = a.clone();
        b.data_mut()[5] = 0.75;
        assert_eq!(psnr(&a, &b, 1.0).unwrap(), psnr(&b, &a, 1.0).unwrap());
    }

    #[test]
    fn rejects_bad_inputs() {
        let a = Image::filled(4, 4, 3, 0.25);
        let b = Image::filled(4, 5, 3, 0.25);
        assert!(matches!(
            psnr(&a, &b, 1.0),
            Err(MetricsError::ShapeMismatch { .. })
        ));
        assert!(matches!(
            psnr(&a, &a, 0.0),
            Err(MetricsError::InvalidDataRange(_))
        ));
        let g = Image::filled(4, 4, 1, 0.25);
        assert!(matches!(
            psnr_gray(&g, &g, 1.0),
            Err(MetricsError::NotRgb { .. })
        ));
        // Plain PSNR works on any number of channels.
        assert_eq!(psnr(&g, &g, 1.0).unwrap(), f64::INFINITY);
    }

    #[test]
    fn luma_uses_bt601_weights() {
        let mut img = Image::filled(1, 1, 3, 0.0);
        img.data_mut().copy_from_slice(&[1.0, 0.0, 0.0]);
        assert!((luma_bt601(&img).data[0] - 0.299).abs() < 1e-12);
        img.data_mut().copy_from_slice(&[0.0, 0.0, 1.0]);
        assert!((luma_bt601(&img).data[0] - 0.114).abs() < 1e-12);
    }
}
