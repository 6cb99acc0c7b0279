//! The GAN baseline's underwater image-formation layer on one image, without a training
//! framework: `I = k · V(r) · S_w( J · t + B · (1 − t) )` with `t = exp(−β · d)`,
//! `d = depth · range_m` metres, `V(r) = 1 + a r² + b r⁴ + c r⁶` and the optional 3x3 binomial
//! blur `S_w(x) = (1 − w) x + w G(x)`. The stages, their sources and what is simplified are
//! described with the differentiable form that training uses (`uwnr-gan-train`'s `imaging`);
//! this one follows it operation by operation in f32, and the training wing's tests compare
//! the two.

use rayon::prelude::*;
use uwnr_core::Image;

use crate::config::{
    BETA_MAX, BINOMIAL, GAIN_MAX, GAIN_MIN, ImagingConfig, RAW_PARAMS, RGB, VIGNETTE_MAX,
};
use crate::error::{GanError, Result};

/// The image-formation parameters of one render.
#[derive(Clone, Debug, PartialEq)]
pub struct WaterValues {
    /// Attenuation per metre, R, G, B, in `[0, BETA_MAX]`.
    pub beta: [f32; 3],
    /// Veiling light, R, G, B, in `[0, 1]`.
    pub backlight: [f32; 3],
    /// Vignetting coefficients `(a, b, c)` of `r², r⁴, r⁶`, each in `[−VIGNETTE_MAX, 0]`.
    pub vignette: [f32; 3],
    /// Camera gain `k` in `[GAIN_MIN, GAIN_MAX]`.
    pub gain: f32,
    /// Blur weight `w` in `[0, 1]` (used only when the imaging config has the blur on).
    pub blur: f32,
}

/// The logistic function, as burn computes it (`1 / (1 + exp(−x))`).
fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

impl WaterValues {
    /// Maps the head's raw outputs to the parameters' ranges with sigmoids:
    /// `β = BETA_MAX σ(x₀..₃)`, `B = σ(x₃..₆)`, `(a, b, c) = −VIGNETTE_MAX σ(x₆..₉)`,
    /// `k = GAIN_MIN + (GAIN_MAX − GAIN_MIN) σ(x₉)`, `w = σ(x₁₀)`.
    #[must_use]
    pub fn from_raw(raw: &[f32; RAW_PARAMS]) -> Self {
        let s = raw.map(sigmoid);
        Self {
            beta: [s[0], s[1], s[2]].map(|v| v * BETA_MAX),
            backlight: [s[3], s[4], s[5]],
            vignette: [s[6], s[7], s[8]].map(|v| v * (-VIGNETTE_MAX)),
            gain: s[9] * (GAIN_MAX - GAIN_MIN) + GAIN_MIN,
            blur: s[10],
        }
    }
}

/// Squared normalised radius `r²` of every pixel of an `h x w` image, row-major: 0 at the
/// centre (between pixels for even sizes), 1 at the corner pixels' centres. A single pixel has
/// `r = 0`.
#[must_use]
pub fn radius_squared(h: usize, w: usize) -> Vec<f32> {
    let (cy, cx) = ((h as f64 - 1.0) / 2.0, (w as f64 - 1.0) / 2.0);
    let norm = cx * cx + cy * cy;
    (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let (dx, dy) = (x as f64 - cx, y as f64 - cy);
                if norm > 0.0 {
                    ((dx * dx + dy * dy) / norm) as f32
                } else {
                    0.0
                }
            })
        })
        .collect()
}

/// The 3x3 binomial blur of one plane, renormalised by the kernel weight inside the image.
fn binomial_blur(plane: &[f32], w: usize, h: usize) -> Vec<f32> {
    let k = |dy: usize, dx: usize| BINOMIAL[dy] * BINOMIAL[dx] / 16.0;
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let (mut sum, mut support) = (0.0f32, 0.0f32);
            for dy in 0..3 {
                let Some(yy) = (y + dy).checked_sub(1).filter(|&v| v < h) else {
                    continue;
                };
                for dx in 0..3 {
                    let Some(xx) = (x + dx).checked_sub(1).filter(|&v| v < w) else {
                        continue;
                    };
                    sum += k(dy, dx) * plane[yy * w + xx];
                    support += k(dy, dx);
                }
            }
            *o = sum / support;
        }
    });
    out
}

/// The clean image is RGB and the depth map one channel of its size.
pub fn check_inputs(clean: &Image, depth: &Image) -> Result<()> {
    if clean.channels() != RGB {
        return Err(GanError::ShapeMismatch {
            what: "clean image channels",
            expected: vec![RGB],
            got: vec![clean.channels()],
        });
    }
    if depth.channels() != 1 || depth.size() != clean.size() {
        return Err(GanError::ShapeMismatch {
            what: "depth map (channels, width, height)",
            expected: vec![1, clean.width(), clean.height()],
            got: vec![depth.channels(), depth.width(), depth.height()],
        });
    }
    Ok(())
}

/// Renders `clean` (RGB in [0, 1]) with its `depth` (1 channel, [0, 1], larger = farther, the
/// same size) under `values`: `k · V(r) · S_w(J t + B (1 − t))`, clamped to [0, 1] (the render
/// is in range by construction; the clamp only removes rounding excursions).
pub fn render(
    clean: &Image,
    depth: &Image,
    values: &WaterValues,
    config: &ImagingConfig,
) -> Result<Image> {
    check_inputs(clean, depth)?;
    let (w, h) = clean.size();
    let range = config.range_m as f32;
    let r2 = radius_squared(h, w);
    let [a, b, c] = values.vignette;
    let vignette: Vec<f32> = r2
        .iter()
        .map(|&r2| {
            let r4 = r2 * r2;
            let r6 = r4 * r2;
            r2 * a + r4 * b + r6 * c + 1.0
        })
        .collect();
    let d = depth.data();
    let mut data = Vec::with_capacity(RGB * w * h);
    for ch in 0..RGB {
        let (beta, veil) = (values.beta[ch], values.backlight[ch]);
        let j = &clean.data()[ch * w * h..(ch + 1) * w * h];
        let mut plane: Vec<f32> = j
            .par_iter()
            .zip(d.par_iter())
            .map(|(&j, &d)| {
                let t = (-(beta * (d * range))).exp();
                j * t + (-t + 1.0) * veil
            })
            .collect();
        if config.blur {
            let g = binomial_blur(&plane, w, h);
            let wt = values.blur;
            for (p, g) in plane.iter_mut().zip(g) {
                *p = *p * (-wt + 1.0) + g * wt;
            }
        }
        data.extend(
            plane
                .iter()
                .zip(&vignette)
                .map(|(&p, &v)| (p * v * values.gain).clamp(0.0, 1.0)),
        );
    }
    Ok(Image::from_planar(w, h, RGB, data)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_water_and_no_vignette_leave_the_image() {
        let values = WaterValues {
            beta: [0.0; 3],
            backlight: [0.5; 3],
            vignette: [0.0; 3],
            gain: 1.0,
            blur: 0.0,
        };
        let clean =
            Image::from_planar(3, 2, 3, (0..18).map(|i| i as f32 / 18.0).collect()).unwrap();
        let depth = Image::from_planar(3, 2, 1, vec![0.7; 6]).unwrap();
        let out = render(&clean, &depth, &values, &ImagingConfig::default()).unwrap();
        assert_eq!(out, clean);
    }

    #[test]
    fn far_pixels_take_the_veiling_light() {
        let values = WaterValues {
            beta: [BETA_MAX; 3],
            backlight: [0.2, 0.5, 0.8],
            vignette: [0.0; 3],
            gain: 1.0,
            blur: 0.0,
        };
        let clean = Image::from_planar(2, 1, 3, vec![1.0; 6]).unwrap();
        // Depth 1 is 10 m: exp(−15) of the scene is left.
        let depth = Image::from_planar(2, 1, 1, vec![0.0, 1.0]).unwrap();
        let out = render(&clean, &depth, &values, &ImagingConfig::default()).unwrap();
        for (c, veil) in [0.2f32, 0.5, 0.8].into_iter().enumerate() {
            assert_eq!(out.plane(c)[0], 1.0);
            assert!((out.plane(c)[1] - veil).abs() < 1e-5);
        }
    }

    #[test]
    fn a_flat_image_stays_flat_under_the_blur_and_the_corners_darken() {
        let values = WaterValues {
            beta: [0.0; 3],
            backlight: [0.0; 3],
            vignette: [-VIGNETTE_MAX; 3],
            gain: 1.0,
            blur: 1.0,
        };
        let cfg = ImagingConfig {
            blur: true,
            ..ImagingConfig::default()
        };
        let clean = Image::from_planar(5, 5, 3, vec![0.4; 75]).unwrap();
        let depth = Image::from_planar(5, 5, 1, vec![0.0; 25]).unwrap();
        let out = render(&clean, &depth, &values, &cfg).unwrap();
        assert!((out.plane(0)[12] - 0.4).abs() < 1e-6);
        assert!((out.plane(0)[0] - 0.4 * (1.0 - 3.0 * VIGNETTE_MAX)).abs() < 1e-5);
    }

    #[test]
    fn the_raw_mapping_stays_in_range() {
        for x in [-50.0f32, 0.0, 50.0] {
            let v = WaterValues::from_raw(&[x; RAW_PARAMS]);
            assert!(v.beta.iter().all(|b| (0.0..=BETA_MAX).contains(b)));
            assert!((GAIN_MIN..=GAIN_MAX).contains(&v.gain));
            assert!(v.vignette.iter().all(|a| (-VIGNETTE_MAX..=0.0).contains(a)));
        }
    }
}
