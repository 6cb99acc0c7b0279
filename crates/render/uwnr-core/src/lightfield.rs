//! The UWNR light-field map ("LFR" module), exactly as the released code computes it.
//!
//! Paper (Ye, Chen et al., CVPR-W 2022): `x_g = mean over sigma in {15, 60, 90} of
//! Gauss_sigma(x_u)`, `x_l = Normalise(log x_g)`. Released code, `MutiScaleLuminanceEstimation`
//! in `myutils/dcp.py`, applied to a uint8 RGB array:
//!
//! ```text
//! img = cv2.resize(img, dsize=None, fx=0.3, fy=0.3)             # INTER_LINEAR, 256 -> 77
//! Luminance = np.ones_like(img).astype(np.float)                # float64
//! for sigma in [15, 60, 90]:
//!     L1 = np.log10(cv2.GaussianBlur(img, (0, 0), sigma))       # uint8 in, float16 out
//!     L1 = np.clip(L1, 0, 255); Luminance += L1
//! Luminance = Luminance / 3
//! L = (Luminance - min) / (max - min + 0.0001)                  # over all channels together
//! L = np.uint8(L * 255)                                         # truncation
//! L = cv2.resize(L, dsize=(w, h))                               # back to the input size
//! ```
//!
//! Every step is reproduced bit for bit: OpenCV's 8-bit resize and blur through
//! [`crate::resize`] and [`crate::gaussian`], and `np.log10` of a uint8 array, which NumPy
//! evaluates in float16 (the smallest float type holding uint8): `log10f` rounded to half
//! precision. At render time the reference first goes through torchvision's
//! `Resize([256, 256])` on the PIL image, i.e. PIL's antialiased bilinear resize
//! ([`crate::resize::pil_resize_bilinear_u8`]); in training the map is computed on the 256x256
//! crop itself. Because the map is always computed at 0.3 x 256 pixels, it does not depend on the
//! resolution of the reference.
//!
//! The min-max normalisation discards the reference's overall brightness and contrast: a global
//! gain is an offset in log space and a gamma a scale, and both cancel. [`LightFieldMap::Absolute`]
//! is the same map normalised by the fixed range every 8-bit image falls in instead, so it keeps
//! them; a network trained with it needs it at render time too (the authors' checkpoint needs
//! [`LightFieldMap::Paper`]), which is why the generator's config records the map.

use std::sync::OnceLock;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{CoreError, Result};
use crate::gaussian::cv_gaussian_blur_u8;
use crate::image::Image;
use crate::resize::{
    U8Image, cv_resize_linear_scale_u8, cv_resize_linear_u8, pil_resize_bilinear_u8,
    resize_bilinear,
};

/// Gaussian sigmas of the multi-scale luminance estimate (paper Sec. 3.2; released code
/// `sigma_list = [15, 60, 90]`).
pub const LF_SIGMAS: [f64; 3] = [15.0, 60.0, 90.0];
/// Downscale factor before blurring (released code: `cv2.resize(img, None, fx=0.3, fy=0.3)`).
pub const LF_SCALE: f64 = 0.3;
/// Side of the square the reference is resized to at render time (released test code:
/// `transforms.Resize([256, 256])`).
pub const LF_REFERENCE_SIZE: usize = 256;
/// Added to the range in the min-max normalisation (released code: `max - min + 0.0001`).
pub const LF_NORM_EPS: f64 = 0.0001;

/// Channels of the reference the light field is computed from (RGB).
const LF_CHANNELS: usize = 3;

/// How the multi-scale log luminance is normalised to [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightFieldMap {
    /// The released code: min-max over the image's own values (all channels together). Keeps the
    /// spatial and between-channel pattern, drops overall brightness and contrast.
    #[default]
    Paper,
    /// The fixed range of the luminance of any 8-bit image, `[1/3, (1 + 3 log10 255) / 3]`, so a
    /// darker or lower-contrast reference gives a darker or flatter map. Otherwise identical.
    Absolute,
    /// The absolute map's mean over the frame, channel by channel: the reference's overall
    /// brightness at each scale, none of its layout (a network fed it cannot copy the
    /// reference's scene).
    Global,
}

impl LightFieldMap {
    /// The name used in configs and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Absolute => "absolute",
            Self::Global => "global",
        }
    }
}

impl std::str::FromStr for LightFieldMap {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        match s {
            "paper" => Ok(Self::Paper),
            "absolute" => Ok(Self::Absolute),
            "global" => Ok(Self::Global),
            other => Err(format!(
                "unknown light-field map '{other}' (expected paper, absolute or global)"
            )),
        }
    }
}

impl std::fmt::Display for LightFieldMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `np.clip(np.log10(v), 0, 255)` for every uint8 value `v`, as NumPy computes it on a uint8
/// array: `log10f` rounded to float16 (`log10(0) = -inf` clips to 0).
fn log10_u8_table() -> &'static [f64; 256] {
    static TABLE: OnceLock<[f64; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0.0; 256];
        for (v, out) in t.iter_mut().enumerate().skip(1) {
            *out = half::f16::from_f32((v as f32).log10())
                .to_f64()
                .clamp(0.0, 255.0);
        }
        t
    })
}

/// The values `np.clip(np.log10(np.arange(256, dtype=np.uint8)), 0, 255)` used by the map
/// (exposed for the tests that check them against NumPy).
#[must_use]
pub fn log10_u8_values() -> Vec<f64> {
    log10_u8_table().to_vec()
}

/// The released procedure on an 8-bit RGB image at its own size: same size out.
pub fn light_field_raw_u8(img: &U8Image) -> Result<U8Image> {
    light_field_raw_u8_with(img, LightFieldMap::Paper)
}

/// [`light_field_raw_u8`] with the normalisation `map`.
pub fn light_field_raw_u8_with(img: &U8Image, map: LightFieldMap) -> Result<U8Image> {
    if img.channels != LF_CHANNELS {
        return Err(CoreError::ShapeMismatch {
            expected: (LF_CHANNELS, img.height, img.width),
            got: (img.channels, img.height, img.width),
        });
    }
    let small = cv_resize_linear_scale_u8(img, LF_SCALE, LF_SCALE)?;
    let table = log10_u8_table();
    let blurred = LF_SIGMAS
        .par_iter()
        .map(|&sigma| cv_gaussian_blur_u8(&small, sigma))
        .collect::<Result<Vec<_>>>()?;
    // Summed in the released order: ones + L(15) + L(60) + L(90).
    let mut luminance = vec![1.0_f64; small.data.len()];
    for b in &blurred {
        for (l, &v) in luminance.iter_mut().zip(&b.data) {
            *l += table[usize::from(v)];
        }
    }
    let count = LF_SIGMAS.len() as f64;
    for l in &mut luminance {
        *l /= count;
    }
    let (min, max) = match map {
        LightFieldMap::Paper => luminance
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            }),
        // Every blur of an all-0 image is 0 (log clipped to 0); of an all-255 image, 255.
        LightFieldMap::Absolute | LightFieldMap::Global => {
            (1.0 / count, (1.0 + count * table[255]) / count)
        }
    };
    let denom = max - min + LF_NORM_EPS;
    // `np.uint8(L * 255)` truncates; L is in [0, 1).
    let mut normalised: Vec<u8> = luminance
        .iter()
        .map(|&l| ((l - min) / denom * 255.0) as u8)
        .collect();
    if map == LightFieldMap::Global {
        flatten_channels(&mut normalised, small.channels);
    }
    let small = U8Image::new(small.width, small.height, small.channels, normalised)?;
    cv_resize_linear_u8(&small, img.width, img.height)
}

/// Sets every value of each channel of the interleaved `data` to that channel's mean (rounded).
fn flatten_channels(data: &mut [u8], channels: usize) {
    let pixels = data.len() / channels;
    for c in 0..channels {
        let sum: u64 = data
            .iter()
            .skip(c)
            .step_by(channels)
            .map(|&v| u64::from(v))
            .sum();
        let mean = ((sum as f64 / pixels.max(1) as f64).round()) as u8;
        for v in data.iter_mut().skip(c).step_by(channels) {
            *v = mean;
        }
    }
}

/// The render-time map on an 8-bit RGB reference: PIL bilinear resize to 256x256, then the
/// released procedure. Output 256x256x3.
pub fn light_field_u8(reference: &U8Image) -> Result<U8Image> {
    light_field_u8_with(reference, LightFieldMap::Paper)
}

/// Log10 units per unit of the absolute map: a value `v` of [`LightFieldMap::Absolute`] is
/// `mean over the blurs of log10(blur) / absolute_log10_range()` (before its 8-bit truncation).
#[must_use]
pub fn absolute_log10_range() -> f64 {
    log10_u8_table()[255] + LF_NORM_EPS
}

/// [`light_field_u8`] with the normalisation `map`.
pub fn light_field_u8_with(reference: &U8Image, map: LightFieldMap) -> Result<U8Image> {
    let resized = pil_resize_bilinear_u8(reference, LF_REFERENCE_SIZE, LF_REFERENCE_SIZE)?;
    light_field_raw_u8_with(&resized, map)
}

/// The render-time light-field map of a reference image: quantised to u8 (round half up, as the
/// released code sees uint8), PIL-resized to 256x256, then the released procedure. Returns a
/// 256x256x3 image with values `u8 / 255`.
pub fn light_field(reference: &Image) -> Result<Image> {
    light_field_with(reference, LightFieldMap::Paper)
}

/// [`light_field`] with the normalisation `map`.
pub fn light_field_with(reference: &Image, map: LightFieldMap) -> Result<Image> {
    light_field_u8_with(&U8Image::from_image(reference), map)?.to_image()
}

/// The released procedure on an image at its own size (training crops): same size out, values
/// `u8 / 255`.
pub fn light_field_raw(image: &Image) -> Result<Image> {
    light_field_raw_with(image, LightFieldMap::Paper)
}

/// [`light_field_raw`] with the normalisation `map`.
pub fn light_field_raw_with(image: &Image, map: LightFieldMap) -> Result<Image> {
    light_field_raw_u8_with(&U8Image::from_image(image), map)?.to_image()
}

/// [`light_field`] resized with [`resize_bilinear`] to `width x height`: what rendering feeds the
/// network next to a clean image of that size.
pub fn light_field_for(reference: &Image, width: usize, height: usize) -> Result<Image> {
    light_field_for_with(reference, width, height, LightFieldMap::Paper)
}

/// [`light_field_for`] with the normalisation `map`.
pub fn light_field_for_with(
    reference: &Image,
    width: usize,
    height: usize,
    map: LightFieldMap,
) -> Result<Image> {
    resize_bilinear(&light_field_with(reference, map)?, width, height)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log10_table_is_float16_rounded() {
        let t = log10_u8_table();
        assert_eq!(t[0], 0.0);
        assert_eq!(t[1], 0.0);
        // log10(255) = 2.40654; float16 spacing in [2, 4) is 2^-9.
        assert!((t[255] - 2.40654).abs() < 1.0 / 512.0);
        assert_eq!((t[255] * 512.0).fract(), 0.0);
    }

    #[test]
    fn flat_image_gives_a_zero_map() {
        let img = U8Image::new(40, 30, 3, vec![120; 40 * 30 * 3]).unwrap();
        let lf = light_field_raw_u8(&img).unwrap();
        assert_eq!((lf.width, lf.height), (40, 30));
        assert!(lf.data.iter().all(|&v| v == 0));
    }

    #[test]
    fn map_spans_the_range() {
        // A horizontal ramp: the normalised map must reach 0 and (almost) 255.
        let mut data = Vec::new();
        for _y in 0..64 {
            for x in 0..64 {
                data.extend_from_slice(&[(x * 4) as u8, 100, 50]);
            }
        }
        let lf = light_field_u8(&U8Image::new(64, 64, 3, data).unwrap()).unwrap();
        assert_eq!((lf.width, lf.height), (256, 256));
        assert_eq!(*lf.data.iter().min().unwrap(), 0);
        assert!(*lf.data.iter().max().unwrap() >= 250);
    }

    #[test]
    fn the_global_map_keeps_brightness_and_drops_layout() {
        // A bright left half and its mirror: the absolute maps differ, the global ones do not,
        // and each global channel is the absolute map's mean.
        let image = |bright_left: bool| {
            let mut data = Vec::new();
            for _y in 0..256 {
                for x in 0..256 {
                    let v = if (x < 128) == bright_left { 220 } else { 30 };
                    data.extend_from_slice(&[v, v / 2, v / 3]);
                }
            }
            U8Image::new(256, 256, 3, data).unwrap()
        };
        let (left, right) = (image(true), image(false));
        let abs = |im| light_field_raw_u8_with(im, LightFieldMap::Absolute).unwrap();
        let global = |im| light_field_raw_u8_with(im, LightFieldMap::Global).unwrap();
        assert_ne!(abs(&left).data, abs(&right).data);
        let (gl, gr) = (global(&left), global(&right));
        assert_eq!((gl.width, gl.height), (256, 256));
        for c in 0..3 {
            let channel =
                |im: &U8Image| -> Vec<u8> { im.data.iter().skip(c).step_by(3).copied().collect() };
            let (l, r) = (channel(&gl), channel(&gr));
            assert!(l.iter().all(|&v| v == l[0]) && r.iter().all(|&v| v == r[0]));
            // Equal up to the resize's rounding at the halves' border; the absolute maps differ
            // by 31 at the left edge.
            assert!(l[0].abs_diff(r[0]) <= 4, "{} {}", l[0], r[0]);
            let (al, ar) = (channel(&abs(&left))[0], channel(&abs(&right))[0]);
            assert!(al.abs_diff(ar) >= 20, "{al} {ar}");
            let a = channel(&abs(&left));
            let mean = a.iter().map(|&v| f64::from(v)).sum::<f64>() / a.len() as f64;
            assert!((f64::from(l[0]) - mean).abs() <= 2.0, "{} {mean}", l[0]);
        }
        // A darker reference gives a darker global map.
        let dark = U8Image::new(256, 256, 3, vec![20; 256 * 256 * 3]).unwrap();
        assert!(global(&dark).data[0] < gl.data[0]);
        assert_eq!(
            "global".parse::<LightFieldMap>().unwrap(),
            LightFieldMap::Global
        );
    }

    #[test]
    fn rejects_grey_input() {
        let img = U8Image::new(8, 8, 1, vec![0; 64]).unwrap();
        assert!(light_field_raw_u8(&img).is_err());
    }
}
