//! Colour-texture statistics: a fixed, weight-free 155-d image descriptor for distribution
//! distances when no InceptionV3 is available. The Fréchet distance on it is called FD-ct
//! ("Fréchet distance on colour-texture features"); it is not FID and its values are not
//! comparable with FID's.
//!
//! It describes what separates underwater renders from real underwater photos: colour cast and
//! its spread, haze (dark channel), contrast and detail at several scales, and the low-frequency
//! layout of light. The image is first area-averaged to [`COLOR_TEXTURE_WORKING_SIZE`]²
//! pixels (whatever its aspect ratio, like Inception's 299²) and clamped to [0, 1]; L*a*b*
//! is skimage's `rgb2lab` ([`uwnr_core::color::rgb_to_lab_px`]) divided by 100. The vector,
//! in order:
//!
//! | index   | count | what |
//! |---------|-------|------|
//! | 0..9    | 9  | L, a, b: mean, standard deviation, cube root of the third central moment |
//! | 9..15   | 6  | R, G, B: mean, standard deviation |
//! | 15..18  | 3  | chroma `sqrt(a^2 + b^2)`: mean, std; mean HSV saturation |
//! | 18..26  | 8  | histogram of L in 8 equal bins over [0, 100] (fractions) |
//! | 26..75  | 49 | joint a-b histogram, 7 x 7 bins of 20 over [-70, 70) (a-major; fractions; outside values go to edge bins; neutral grey sits mid-bin) |
//! | 75..77  | 2  | dark channel (min over RGB, then a 7x7 minimum filter): mean, std |
//! | 77..83  | 6  | Sobel gradient magnitude of L at scales 1, 1/2, 1/4 (2x2 area pyramid): mean, std |
//! | 83..95  | 12 | mean absolute derivative of L along 0, 45, 90 and 135 degrees at the 3 scales (scale-major) |
//! | 95..107 | 12 | RMS of difference-of-Gaussian bands of L, a, b between sigma 0-1, 1-2, 2-4, 4-8 px (channel-major) |
//! | 107..155 | 48 | layout: mean L, a, b over a 4 x 4 grid (row-major cells, L, a, b per cell) |
//!
//! Filters use scipy.ndimage's reflect border; Gaussians are truncated at 4 sigma (scipy's
//! default). Derivatives are Sobel responses divided by 8, so a unit ramp has slope 1.

use rayon::prelude::*;
use uwnr_core::Image;
use uwnr_core::color::{rgb_to_lab_px, saturation_px};

use crate::error::{Result, check_finite_image, check_rgb};
use crate::features::FeatureExtractor;
use crate::filter::{PlaneF64, correlate_axis0, correlate_axis1, gaussian_filter, gaussian_kernel};
use crate::resize::resize_area;

/// Side of the square working image.
pub const COLOR_TEXTURE_WORKING_SIZE: usize = 128;
/// Length of the descriptor.
pub const COLOR_TEXTURE_DIM: usize = 155;

/// L*a*b* values are divided by this, bringing L to [0, 1].
const LAB_SCALE: f64 = 100.0;
const L_HIST_BINS: usize = 8;
/// An odd count keeps a = b = 0 in the middle of a bin (grey is not exactly 0 after rounding).
const AB_HIST_BINS: usize = 7;
/// The a-b histogram spans [-AB_HIST_RANGE, AB_HIST_RANGE) in L*a*b* units.
const AB_HIST_RANGE: f64 = 70.0;
/// Dark channel patch side (He, Sun, Tang 2009 use 15 px at full resolution).
const DARK_CHANNEL_PATCH: usize = 7;
/// Pyramid levels for the gradient statistics.
const GRADIENT_SCALES: usize = 3;
/// Sobel taps sum to 8 in absolute value on a unit ramp.
const SOBEL_NORM: f64 = 8.0;
const SOBEL_DERIVATIVE: [f64; 3] = [-1.0, 0.0, 1.0];
const SOBEL_SMOOTH: [f64; 3] = [1.0, 2.0, 1.0];
/// Band edges of the difference-of-Gaussian energies (0 = the image itself).
const DOG_SIGMAS: [f64; 5] = [0.0, 1.0, 2.0, 4.0, 8.0];
/// scipy.ndimage.gaussian_filter's default truncation.
const GAUSSIAN_TRUNCATE: f64 = 4.0;
/// Cells per side of the layout grid.
const LAYOUT_GRID: usize = 4;

/// The colour-texture descriptor (see the module docs for the exact layout).
#[derive(Clone, Copy, Debug, Default)]
pub struct ColorTextureFeatures;

impl ColorTextureFeatures {
    /// The descriptor extractor.
    #[must_use]
    pub fn new() -> Self {
        Self
    }
}

impl FeatureExtractor for ColorTextureFeatures {
    fn dim(&self) -> usize {
        COLOR_TEXTURE_DIM
    }

    fn name(&self) -> &str {
        "color-texture-v1"
    }

    fn extract(&self, img: &Image) -> Result<Vec<f64>> {
        check_rgb("colour-texture features", img)?;
        check_finite_image("colour-texture input", img)?;
        let s = COLOR_TEXTURE_WORKING_SIZE;
        let rgb: Vec<Vec<f64>> = resize_area(img, s, s)
            .into_iter()
            .map(|p| p.into_iter().map(|v| v.clamp(0.0, 1.0)).collect())
            .collect();
        let n = s * s;
        let mut lab = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        let mut sat = vec![0.0; n];
        let mut dark = vec![0.0; n];
        for i in 0..n {
            let px = [rgb[0][i], rgb[1][i], rgb[2][i]];
            let v = rgb_to_lab_px(px);
            for c in 0..3 {
                lab[c][i] = v[c] / LAB_SCALE;
            }
            sat[i] = saturation_px(px);
            dark[i] = px[0].min(px[1]).min(px[2]);
        }

        let mut f = Vec::with_capacity(COLOR_TEXTURE_DIM);
        // Moments.
        for p in &lab {
            let (m, sd, skew) = moments(p);
            f.extend([m, sd, skew]);
        }
        for p in &rgb {
            let (m, sd, _) = moments(p);
            f.extend([m, sd]);
        }
        let chroma: Vec<f64> = lab[1]
            .iter()
            .zip(&lab[2])
            .map(|(a, b)| a.hypot(*b))
            .collect();
        let (cm, csd, _) = moments(&chroma);
        f.extend([cm, csd, mean(&sat)]);
        // Histograms.
        let mut lh = [0.0; L_HIST_BINS];
        let mut abh = [0.0; AB_HIST_BINS * AB_HIST_BINS];
        let ab_bin = |v: f64| {
            let t = (v * LAB_SCALE + AB_HIST_RANGE) / (2.0 * AB_HIST_RANGE) * AB_HIST_BINS as f64;
            (t.floor().max(0.0) as usize).min(AB_HIST_BINS - 1)
        };
        for i in 0..n {
            let lb =
                ((lab[0][i] * L_HIST_BINS as f64).floor().max(0.0) as usize).min(L_HIST_BINS - 1);
            lh[lb] += 1.0;
            abh[ab_bin(lab[1][i]) * AB_HIST_BINS + ab_bin(lab[2][i])] += 1.0;
        }
        f.extend(lh.iter().map(|c| c / n as f64));
        f.extend(abh.iter().map(|c| c / n as f64));
        // Haze.
        let dc = min_filter(&dark, s, s, DARK_CHANNEL_PATCH);
        let (dm, dsd, _) = moments(&dc);
        f.extend([dm, dsd]);
        // Gradients of L over a pyramid.
        let mut level = PlaneF64::new(s, s, lab[0].clone());
        let mut magnitude_stats = Vec::new();
        let mut oriented = Vec::new();
        for k in 0..GRADIENT_SCALES {
            if k > 0 {
                level = halve(&level);
            }
            let d0 = correlate_axis1(&correlate_axis0(&level, &SOBEL_DERIVATIVE), &SOBEL_SMOOTH);
            let d1 = correlate_axis0(&correlate_axis1(&level, &SOBEL_DERIVATIVE), &SOBEL_SMOOTH);
            let gy: Vec<f64> = d0.data.iter().map(|v| v / SOBEL_NORM).collect();
            let gx: Vec<f64> = d1.data.iter().map(|v| v / SOBEL_NORM).collect();
            let mag: Vec<f64> = gx.iter().zip(&gy).map(|(x, y)| x.hypot(*y)).collect();
            let (mm, msd, _) = moments(&mag);
            magnitude_stats.extend([mm, msd]);
            let r2 = std::f64::consts::FRAC_1_SQRT_2;
            let mean_abs = |g: &dyn Fn(usize) -> f64| {
                (0..gx.len()).map(|i| g(i).abs()).sum::<f64>() / gx.len() as f64
            };
            oriented.extend([
                mean_abs(&|i| gx[i]),
                mean_abs(&|i| r2 * (gx[i] + gy[i])),
                mean_abs(&|i| gy[i]),
                mean_abs(&|i| r2 * (gy[i] - gx[i])),
            ]);
        }
        f.extend(magnitude_stats);
        f.extend(oriented);
        // Band energies.
        let bands: Vec<Vec<f64>> = lab
            .par_iter()
            .map(|p| {
                let plane = PlaneF64::new(s, s, p.clone());
                let blurred: Vec<PlaneF64> = DOG_SIGMAS
                    .iter()
                    .map(|&sigma| {
                        if sigma == 0.0 {
                            plane.clone()
                        } else {
                            gaussian_filter(&plane, &gaussian_kernel(sigma, GAUSSIAN_TRUNCATE))
                        }
                    })
                    .collect();
                blurred
                    .windows(2)
                    .map(|w| {
                        let ms = w[0]
                            .data
                            .iter()
                            .zip(&w[1].data)
                            .map(|(a, b)| (a - b) * (a - b))
                            .sum::<f64>()
                            / n as f64;
                        ms.sqrt()
                    })
                    .collect()
            })
            .collect();
        f.extend(bands.into_iter().flatten());
        // Layout.
        let cell = s / LAYOUT_GRID;
        for gy in 0..LAYOUT_GRID {
            for gx in 0..LAYOUT_GRID {
                for p in &lab {
                    let mut sum = 0.0;
                    for y in gy * cell..(gy + 1) * cell {
                        sum += p[y * s + gx * cell..y * s + (gx + 1) * cell]
                            .iter()
                            .sum::<f64>();
                    }
                    f.push(sum / (cell * cell) as f64);
                }
            }
        }
        debug_assert_eq!(f.len(), COLOR_TEXTURE_DIM);
        Ok(f)
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Mean, population standard deviation and the cube root of the third central moment.
fn moments(v: &[f64]) -> (f64, f64, f64) {
    let m = mean(v);
    let n = v.len() as f64;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n;
    let third = v.iter().map(|x| (x - m).powi(3)).sum::<f64>() / n;
    (m, var.sqrt(), third.cbrt())
}

/// Minimum over a `k x k` window clipped at the borders (separable).
fn min_filter(p: &[f64], w: usize, h: usize, k: usize) -> Vec<f64> {
    let r = k / 2;
    let mut rows = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r).min(w - 1));
            rows[y * w + x] = p[y * w + x0..=y * w + x1]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            out[y * w + x] = (y0..=y1)
                .map(|yy| rows[yy * w + x])
                .fold(f64::INFINITY, f64::min);
        }
    }
    out
}

/// 2x2 area average (even sides).
fn halve(p: &PlaneF64) -> PlaneF64 {
    let (w, h) = (p.width / 2, p.height / 2);
    let mut data = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = 2 * y * p.width + 2 * x;
            data[y * w + x] =
                0.25 * (p.data[i] + p.data[i + 1] + p.data[i + p.width] + p.data[i + p.width + 1]);
        }
    }
    PlaneF64::new(w, h, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(w: usize, h: usize) -> Image {
        let mut img = Image::filled(w, h, 3, 0.0);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                *v = 0.3 + 0.2 * c as f32 + 0.15 * (x * 0.3).sin() * (y * 0.2 + c as f32).cos();
            }
        }
        img
    }

    #[test]
    fn descriptor_has_the_documented_length_and_is_finite() {
        let fx = ColorTextureFeatures::new();
        for img in [
            textured(200, 150),
            textured(31, 47),
            Image::filled(1, 1, 3, 0.0),
            Image::filled(64, 64, 3, 1.0),
        ] {
            let f = fx.extract(&img).unwrap();
            assert_eq!(f.len(), fx.dim());
            assert!(f.iter().all(|v| v.is_finite()), "{f:?}");
        }
    }

    #[test]
    fn flat_grey_has_no_texture_and_a_single_histogram_bin() {
        let f = ColorTextureFeatures::new()
            .extract(&Image::filled(50, 40, 3, 0.5))
            .unwrap();
        assert!(
            f[77..107].iter().all(|v| v.abs() < 1e-12),
            "{:?}",
            &f[77..107]
        );
        let l_hist = &f[18..26];
        assert!((l_hist.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(l_hist.iter().filter(|&&v| v > 0.0).count(), 1);
        let ab_hist = &f[26..75];
        // Grey has a = b = 0 (to rounding): the middle bin on both axes.
        assert!((ab_hist[3 * AB_HIST_BINS + 3] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn layout_sees_a_flip_but_global_statistics_do_not() {
        let img = textured(128, 128);
        let mut flipped = img.clone();
        for c in 0..3 {
            let p = flipped.plane_mut(c);
            for row in p.chunks_mut(128) {
                row.reverse();
            }
        }
        let fx = ColorTextureFeatures::new();
        let (a, b) = (fx.extract(&img).unwrap(), fx.extract(&flipped).unwrap());
        for i in 0..77 {
            assert!(
                (a[i] - b[i]).abs() < 1e-9,
                "index {i}: {} vs {}",
                a[i],
                b[i]
            );
        }
        let layout_diff: f64 = a[107..]
            .iter()
            .zip(&b[107..])
            .map(|(x, y)| (x - y).abs())
            .sum();
        assert!(layout_diff > 1e-3, "{layout_diff}");
    }

    #[test]
    fn a_blue_cast_moves_b_negative() {
        let fx = ColorTextureFeatures::new();
        let mut blue = textured(64, 64);
        for v in blue.plane_mut(0) {
            *v *= 0.3;
        }
        let grey = fx.extract(&Image::filled(64, 64, 3, 0.5)).unwrap();
        let cast = fx.extract(&blue).unwrap();
        assert!(
            cast[6] < grey[6] - 0.05,
            "mean b {} vs {}",
            cast[6],
            grey[6]
        );
    }
}
