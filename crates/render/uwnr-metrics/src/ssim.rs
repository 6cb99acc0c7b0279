//! Structural similarity (Wang, Bovik, Sheikh, Simoncelli 2004, "Image quality assessment:
//! from error visibility to structural similarity"):
//! `SSIM = (2 mu_x mu_y + C1)(2 s_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(s_x^2 + s_y^2 + C2))`,
//! `C1 = (K1 R)^2`, `C2 = (K2 R)^2`, averaged over the image.
//!
//! This replicates scikit-image 0.26's `skimage.metrics.structural_similarity` exactly:
//! - [`SsimOptions::wang2004`] (the default of [`ssim`]) is `gaussian_weights=True, sigma=1.5,
//!   use_sample_covariance=False, K1=0.01, K2=0.03`: local statistics from
//!   `scipy.ndimage.gaussian_filter(truncate=3.5)`, an 11x11 window;
//! - [`SsimOptions::skimage_default`] is skimage's default call (7x7 uniform window, sample
//!   covariance with `N/(N-1)`, N = 49), what the FUnIE-GAN and Shallow-UWnet evaluation
//!   scripts compute;
//! - borders: the filters reflect the image (`mode="reflect"`, edge pixel repeated); the SSIM
//!   map is then cropped by `(win_size - 1) / 2` pixels on every side and averaged in f64;
//! - colour: SSIM per channel (`channel_axis=2`), then the mean over channels.
//!
//! Images are compared as given (f32 in [0, 1] widened to f64, so an 8-bit file is u8 / 255)
//! with `data_range` 1.0 by default. SSIM is unchanged when both images and `data_range` are
//! scaled together, so this equals skimage on the u8 arrays with `data_range=255`.
//! [`ssim_gray`] measures one channel, ITU-R BT.601 luma (see [`crate::psnr`]).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::error::{MetricsError, Result, check_data_range, check_rgb, check_same_shape};
use crate::filter::{PlaneF64, gaussian_filter, gaussian_kernel, uniform_filter};
use crate::psnr::luma_bt601;

/// Wang et al.'s constants K1, K2 and Gaussian width.
pub const SSIM_K1: f64 = 0.01;
pub const SSIM_K2: f64 = 0.03;
pub const SSIM_SIGMA: f64 = 1.5;
/// skimage truncates the Gaussian at 3.5 sigma "to give an 11-tap filter" at sigma 1.5.
pub const SSIM_GAUSSIAN_TRUNCATE: f64 = 3.5;
/// skimage's default (uniform) window side.
pub const SSIM_UNIFORM_WINDOW: usize = 7;

/// How local means and variances are weighted.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum SsimWindow {
    /// Gaussian weights of standard deviation `sigma`, truncated at 3.5 sigma.
    Gaussian { sigma: f64 },
    /// A flat `size x size` window (odd `size`).
    Uniform { size: usize },
}

/// Parameters of [`ssim_with`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SsimOptions {
    /// Local weighting.
    pub window: SsimWindow,
    /// `C1 = (k1 data_range)^2`.
    pub k1: f64,
    /// `C2 = (k2 data_range)^2`.
    pub k2: f64,
    /// Difference between the largest and smallest possible values (1.0 for [0, 1] images).
    pub data_range: f64,
    /// Normalise (co)variances by `N - 1` instead of `N`, N the window's pixel count.
    pub sample_covariance: bool,
}

impl SsimOptions {
    /// Wang et al. 2004 as skimage reproduces it (Gaussian sigma 1.5, population covariance).
    #[must_use]
    pub fn wang2004(data_range: f64) -> Self {
        Self {
            window: SsimWindow::Gaussian { sigma: SSIM_SIGMA },
            k1: SSIM_K1,
            k2: SSIM_K2,
            data_range,
            sample_covariance: false,
        }
    }

    /// skimage's defaults: a 7x7 uniform window and sample covariance.
    #[must_use]
    pub fn skimage_default(data_range: f64) -> Self {
        Self {
            window: SsimWindow::Uniform {
                size: SSIM_UNIFORM_WINDOW,
            },
            k1: SSIM_K1,
            k2: SSIM_K2,
            data_range,
            sample_covariance: true,
        }
    }

    /// Side of the window, which is also the border cropped from the SSIM map (times 1/2).
    #[must_use]
    pub fn win_size(&self) -> usize {
        match self.window {
            SsimWindow::Gaussian { sigma } => {
                2 * ((SSIM_GAUSSIAN_TRUNCATE * sigma + 0.5) as usize) + 1
            }
            SsimWindow::Uniform { size } => size,
        }
    }

    fn validate(&self) -> Result<()> {
        check_data_range(self.data_range)?;
        match self.window {
            SsimWindow::Gaussian { sigma } if !(sigma.is_finite() && sigma > 0.0) => {
                return Err(MetricsError::InvalidArgument(format!(
                    "SSIM Gaussian sigma must be finite and > 0, got {sigma}"
                )));
            }
            SsimWindow::Uniform { size } if size < 2 || size % 2 == 0 => {
                return Err(MetricsError::InvalidArgument(format!(
                    "SSIM window size must be odd and > 1, got {size}"
                )));
            }
            _ => {}
        }
        if !(self.k1 >= 0.0 && self.k2 >= 0.0) {
            return Err(MetricsError::InvalidArgument(format!(
                "SSIM K1 and K2 must be >= 0, got {} and {}",
                self.k1, self.k2
            )));
        }
        Ok(())
    }
}

/// Mean SSIM over channels with Wang et al.'s settings ([`SsimOptions::wang2004`]).
///
/// Needs images of at least 11x11 pixels.
pub fn ssim(pred: &Image, target: &Image, data_range: f64) -> Result<f64> {
    ssim_with(pred, target, &SsimOptions::wang2004(data_range))
}

/// SSIM of the ITU-R BT.601 luma of two RGB images, Wang et al.'s settings.
pub fn ssim_gray(pred: &Image, target: &Image, data_range: f64) -> Result<f64> {
    ssim_gray_with(pred, target, &SsimOptions::wang2004(data_range))
}

/// Mean SSIM over channels with explicit options.
pub fn ssim_with(pred: &Image, target: &Image, opts: &SsimOptions) -> Result<f64> {
    check_same_shape(pred, target)?;
    opts.validate()?;
    check_size(pred, opts)?;
    let (w, h) = pred.size();
    let channels = pred.channels();
    let per_channel: Vec<f64> = (0..channels)
        .into_par_iter()
        .map(|c| {
            let x = PlaneF64::new(w, h, pred.plane(c).iter().map(|&v| f64::from(v)).collect());
            let y = PlaneF64::new(
                w,
                h,
                target.plane(c).iter().map(|&v| f64::from(v)).collect(),
            );
            ssim_plane(&x, &y, opts)
        })
        .collect();
    Ok(per_channel.iter().sum::<f64>() / channels.max(1) as f64)
}

/// SSIM of the BT.601 luma of two RGB images with explicit options.
pub fn ssim_gray_with(pred: &Image, target: &Image, opts: &SsimOptions) -> Result<f64> {
    check_same_shape(pred, target)?;
    check_rgb("SSIM (luma)", pred)?;
    opts.validate()?;
    check_size(pred, opts)?;
    Ok(ssim_plane(&luma_bt601(pred), &luma_bt601(target), opts))
}

fn check_size(img: &Image, opts: &SsimOptions) -> Result<()> {
    let win = opts.win_size();
    if img.width() < win || img.height() < win {
        return Err(MetricsError::TooSmall {
            metric: "SSIM",
            width: img.width(),
            height: img.height(),
            min: win,
        });
    }
    Ok(())
}

/// skimage's single-channel `structural_similarity`; the caller checked sizes and options.
fn ssim_plane(x: &PlaneF64, y: &PlaneF64, opts: &SsimOptions) -> f64 {
    let win = opts.win_size();
    let filter: Box<dyn Fn(&PlaneF64) -> PlaneF64> = match opts.window {
        SsimWindow::Gaussian { sigma } => {
            let k = gaussian_kernel(sigma, SSIM_GAUSSIAN_TRUNCATE);
            Box::new(move |p| gaussian_filter(p, &k))
        }
        SsimWindow::Uniform { size } => Box::new(move |p| uniform_filter(p, size)),
    };
    // skimage uses N = win_size^2 for the sample-covariance factor, whatever the weighting.
    let np = (win * win) as f64;
    let cov_norm = if opts.sample_covariance {
        np / (np - 1.0)
    } else {
        1.0
    };

    let ux = filter(x);
    let uy = filter(y);
    let uxx = filter(&x.zip_map(x, |a, b| a * b));
    let uyy = filter(&y.zip_map(y, |a, b| a * b));
    let uxy = filter(&x.zip_map(y, |a, b| a * b));

    let c1 = (opts.k1 * opts.data_range).powi(2);
    let c2 = (opts.k2 * opts.data_range).powi(2);
    let (w, h) = (x.width, x.height);
    let pad = (win - 1) / 2;
    let mut sum = 0.0;
    for row in pad..h - pad {
        for col in pad..w - pad {
            let i = row * w + col;
            let (mx, my) = (ux.data[i], uy.data[i]);
            let vx = cov_norm * (uxx.data[i] - mx * mx);
            let vy = cov_norm * (uyy.data[i] - my * my);
            let vxy = cov_norm * (uxy.data[i] - mx * my);
            let a1 = 2.0 * mx * my + c1;
            let a2 = 2.0 * vxy + c2;
            let b1 = mx * mx + my * my + c1;
            let b2 = vx + vy + c2;
            sum += (a1 * a2) / (b1 * b2);
        }
    }
    sum / ((h - 2 * pad) * (w - 2 * pad)) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(w: usize, h: usize, phase: f32) -> Image {
        let mut img = Image::filled(w, h, 3, 0.0);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                *v = 0.5 + 0.4 * ((x * 0.7 + phase).sin() * (y * 0.3 + c as f32).cos());
            }
        }
        img
    }

    #[test]
    fn ssim_of_an_image_with_itself_is_one() {
        let a = pattern(23, 17, 0.0);
        assert!((ssim(&a, &a, 1.0).unwrap() - 1.0).abs() < 1e-12);
        assert!((ssim_gray(&a, &a, 1.0).unwrap() - 1.0).abs() < 1e-12);
        let u = ssim_with(&a, &a, &SsimOptions::skimage_default(1.0)).unwrap();
        assert!((u - 1.0).abs() < 1e-12);
        // A flat image too: both variances are 0 and the constants keep the ratio at 1.
        let f = Image::filled(11, 11, 3, 0.3);
        assert!((ssim(&f, &f, 1.0).unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn ssim_is_symmetric_and_drops_with_distortion() {
        let a = pattern(30, 20, 0.0);
        let b = pattern(30, 20, 0.4);
        let c = pattern(30, 20, 1.2);
        let ab = ssim(&a, &b, 1.0).unwrap();
        assert!((ab - ssim(&b, &a, 1.0).unwrap()).abs() < 1e-14);
        let ac = ssim(&a, &c, 1.0).unwrap();
        assert!(ab < 1.0 && ac < ab, "{ab} {ac}");
    }

    #[test]
    fn window_sizes_and_size_checks() {
        assert_eq!(SsimOptions::wang2004(1.0).win_size(), 11);
        assert_eq!(SsimOptions::skimage_default(1.0).win_size(), 7);
        let small = Image::filled(10, 30, 3, 0.5);
        assert!(matches!(
            ssim(&small, &small, 1.0),
            Err(MetricsError::TooSmall { min: 11, .. })
        ));
        // 10 pixels are enough for the 7x7 window.
        assert!(ssim_with(&small, &small, &SsimOptions::skimage_default(1.0)).is_ok());
        let bad = SsimOptions {
            window: SsimWindow::Uniform { size: 4 },
            ..SsimOptions::skimage_default(1.0)
        };
        assert!(ssim_with(&small, &small, &bad).is_err());
    }
}
