//! Resampling: an antialiased bilinear (triangle-filter) resize of f32 images, and bit-exact
//! ports of the two 8-bit resizes the released UWNR code relies on.
//!
//! - [`resize_bilinear`]: separable convolution with the triangle filter `max(0, 1 - |x|)`,
//!   whose support is widened by the scale factor when shrinking (antialiased), as PIL's
//!   `BILINEAR`; computed in f32/f64 without quantisation. This is the resize uwnr uses
//!   everywhere (depth maps to the image size, light-field maps to the clean image's size, ...).
//!   [`fit_within`] uses it to shrink an image so its longer side is at most a bound.
//! - [`pil_resize_bilinear_u8`]: Pillow's `Image.resize((w, h), BILINEAR)` on 8-bit images
//!   (`libImaging/Resample.c`: `precompute_coeffs`, `normalize_coeffs_8bpc` with
//!   `PRECISION_BITS = 32 - 8 - 2`, horizontal pass then vertical pass, each rounded to u8).
//!   torchvision's `Resize` on a PIL image calls exactly this. Checked against Pillow 12.3;
//!   Pillow 13 runs the vertical pass first for some size combinations (one side growing, the
//!   other shrinking), which moves some pixels by one code value.
//! - [`cv_resize_linear_u8`] and [`cv_resize_linear_scale_u8`]: OpenCV 4.x
//!   `cv2.resize(img, dsize=(w, h))` / `cv2.resize(img, None, fx=.., fy=..)` with `INTER_LINEAR`
//!   on 8-bit images (`modules/imgproc/src/resize.cpp`: pixel-centre mapping
//!   `(d + 0.5) * scale - 0.5` in f32, 11-bit fixed-point weights `INTER_RESIZE_COEF_BITS`,
//!   horizontal sums kept as i32, vertical combination
//!   `((b0 * (s0 >> 4)) >> 16) + ((b1 * (s1 >> 4)) >> 16) + 2) >> 2`).

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::image::{Image, quantise_u8};

mod opencv;
mod pil;

pub use opencv::{cv_resize_linear_scale_u8, cv_resize_linear_u8};
pub use pil::pil_resize_bilinear_u8;

/// Support (half-width) of the triangle filter, in input pixels at scale 1 (PIL's
/// `struct filter BILINEAR = {bilinear_filter, 1.0}`).
const TRIANGLE_SUPPORT: f64 = 1.0;

/// An interleaved (HWC) 8-bit image, the representation the ports of PIL and OpenCV work on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct U8Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Samples per pixel.
    pub channels: usize,
    /// `height * width * channels` samples, row-major, channels interleaved.
    pub data: Vec<u8>,
}

impl U8Image {
    /// Wraps interleaved data; fails when the length does not match.
    pub fn new(width: usize, height: usize, channels: usize, data: Vec<u8>) -> Result<Self> {
        if data.len() != width * height * channels {
            return Err(CoreError::ShapeMismatch {
                expected: (height, width, channels),
                got: (data.len(), 0, 0),
            });
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Quantises an [`Image`] with the round-half-up rule `(v * 255 + 0.5).clamp(0, 255)`
    /// ([`quantise_u8`]).
    #[must_use]
    pub fn from_image(img: &Image) -> Self {
        let (n, cn) = (img.width() * img.height(), img.channels());
        let mut data = vec![0_u8; n * cn];
        for c in 0..cn {
            for (i, &v) in img.plane(c).iter().enumerate() {
                data[i * cn + c] = quantise_u8(v);
            }
        }
        Self {
            width: img.width(),
            height: img.height(),
            channels: img.channels(),
            data,
        }
    }

    /// Converts to a planar f32 [`Image`] with values `code / 255`.
    pub fn to_image(&self) -> Result<Image> {
        let hwc: Vec<f32> = self.data.iter().map(|&v| f32::from(v) / 255.0).collect();
        Image::from_interleaved(self.width, self.height, self.channels, &hwc)
    }
}

/// Triangle-filter weights of one output position: the first input index and the weights.
struct Taps {
    start: usize,
    weights: Vec<f64>,
}

/// Pillow's `precompute_coeffs` for the triangle filter over the whole input range
/// (`box = (0, in_size)`): for each output position, the first input index and the normalised
/// weights.
fn triangle_taps(in_size: usize, out_size: usize) -> Vec<Taps> {
    let scale = in_size as f64 / out_size as f64;
    let filterscale = scale.max(1.0);
    let support = TRIANGLE_SUPPORT * filterscale;
    let ss = 1.0 / filterscale;
    (0..out_size)
        .map(|xx| {
            let center = (xx as f64 + 0.5) * scale;
            // C's `(int)` truncates toward zero; negative values are clamped to 0 right after.
            let xmin = ((center - support + 0.5) as i64).max(0) as usize;
            let xmax = ((center + support + 0.5) as i64).min(in_size as i64) as usize;
            let mut weights: Vec<f64> = (xmin..xmax.max(xmin))
                .map(|x| {
                    let t = ((x as f64 - center + 0.5) * ss).abs();
                    if t < 1.0 { 1.0 - t } else { 0.0 }
                })
                .collect();
            let total: f64 = weights.iter().sum();
            if total != 0.0 {
                for w in &mut weights {
                    *w /= total;
                }
            }
            Taps {
                start: xmin,
                weights,
            }
        })
        .collect()
}

fn check_sizes(in_w: usize, in_h: usize, out_w: usize, out_h: usize) -> Result<()> {
    if in_w == 0 || in_h == 0 {
        return Err(CoreError::Empty {
            width: in_w,
            height: in_h,
        });
    }
    if out_w == 0 || out_h == 0 {
        return Err(CoreError::InvalidArgument(format!(
            "cannot resize to {out_w}x{out_h}"
        )));
    }
    Ok(())
}

/// Resizes every channel to `width x height` with an antialiased triangle (bilinear) filter,
/// as PIL's `BILINEAR` but in floating point (no quantisation): when shrinking, the filter
/// support grows with the scale factor so every input pixel contributes. Separable,
/// horizontal pass then vertical pass, parallel over channels and rows.
pub fn resize_bilinear(img: &Image, width: usize, height: usize) -> Result<Image> {
    let (in_w, in_h) = img.size();
    check_sizes(in_w, in_h, width, height)?;
    if (in_w, in_h) == (width, height) {
        return Ok(img.clone());
    }
    let htaps = triangle_taps(in_w, width);
    let vtaps = triangle_taps(in_h, height);
    let to_f32 = |taps: Vec<Taps>| -> Vec<(usize, Vec<f32>)> {
        taps.into_iter()
            .map(|t| (t.start, t.weights.iter().map(|&w| w as f32).collect()))
            .collect()
    };
    let (htaps, vtaps) = (to_f32(htaps), to_f32(vtaps));

    let mut out = vec![0.0_f32; width * height * img.channels()];
    out.par_chunks_mut(width * height)
        .enumerate()
        .for_each(|(c, out_plane)| {
            let plane = img.plane(c);
            // Horizontal pass: in_h rows of `width`.
            let mut tmp = vec![0.0_f32; width * in_h];
            tmp.par_chunks_mut(width)
                .zip(plane.par_chunks(in_w))
                .for_each(|(dst, src)| {
                    for (d, (start, w)) in dst.iter_mut().zip(&htaps) {
                        *d = src[*start..*start + w.len()]
                            .iter()
                            .zip(w)
                            .map(|(s, k)| s * k)
                            .sum();
                    }
                });
            // Vertical pass.
            out_plane
                .par_chunks_mut(width)
                .zip(vtaps.par_iter())
                .for_each(|(dst, (start, w))| {
                    dst.fill(0.0);
                    for (i, &k) in w.iter().enumerate() {
                        let row = &tmp[(start + i) * width..(start + i + 1) * width];
                        for (d, &s) in dst.iter_mut().zip(row) {
                            *d += s * k;
                        }
                    }
                });
        });
    Image::from_planar(width, height, img.channels(), out)
}

/// The size of a `(width, height)` image shrunk so that its longer side is at most `max_side`,
/// aspect kept: both sides are scaled by `max_side / longer side` (in f64) and rounded to the
/// nearest integer, at least 1. A size that already fits is returned unchanged (never enlarged);
/// a `max_side` of 0 counts as 1.
///
/// For example `(1000, 500)` in 256 gives `(256, 128)` and `(1000, 1)` in 10 gives `(10, 1)`.
#[must_use]
pub fn fit_within_dims((width, height): (usize, usize), max_side: usize) -> (usize, usize) {
    let max_side = max_side.max(1);
    let long = width.max(height);
    if long <= max_side {
        return (width, height);
    }
    let scale = max_side as f64 / long as f64;
    let side = |v: usize| ((v as f64 * scale).round() as usize).clamp(1, max_side);
    (side(width), side(height))
}

/// `img` shrunk with [`resize_bilinear`] to [`fit_within_dims`]`(img.size(), max_side)`, so
/// that its longer side is at most `max_side` with the aspect kept; an image that already fits
/// is returned as it is (a copy), never enlarged.
pub fn fit_within(img: &Image, max_side: usize) -> Result<Image> {
    let (width, height) = fit_within_dims(img.size(), max_side);
    if (width, height) == img.size() {
        return Ok(img.clone());
    }
    resize_bilinear(img, width, height)
}

/// The f32 taps of one axis: per output position, the first input index and the weights.
type AxisTaps = Vec<(usize, Vec<f32>)>;

/// [`resize_bilinear`] of one image, evaluated on demand over any set of output rows and
/// columns: the values are exactly those `resize_bilinear` computes (the same taps and the same
/// order of operations), without the whole output in memory. A render of a large photo samples
/// the 256x256 light field this way, one tile at a time.
#[derive(Debug)]
pub struct LazyResize<'a> {
    img: &'a Image,
    width: usize,
    height: usize,
    /// `None` when the size is unchanged (the values are the image's own).
    taps: Option<(AxisTaps, AxisTaps)>,
}

impl<'a> LazyResize<'a> {
    /// `img` resized to `width x height`.
    pub fn new(img: &'a Image, width: usize, height: usize) -> Result<Self> {
        let (in_w, in_h) = img.size();
        check_sizes(in_w, in_h, width, height)?;
        let taps = ((in_w, in_h) != (width, height)).then(|| {
            let to_f32 = |taps: Vec<Taps>| -> AxisTaps {
                taps.into_iter()
                    .map(|t| (t.start, t.weights.iter().map(|&w| w as f32).collect()))
                    .collect()
            };
            (
                to_f32(triangle_taps(in_w, width)),
                to_f32(triangle_taps(in_h, height)),
            )
        });
        Ok(Self {
            img,
            width,
            height,
            taps,
        })
    }

    /// Output size `(width, height)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.img.channels()
    }

    /// Appends the values of channel `c` at output rows `rows` x columns `cols` (any indices
    /// below the output size), row-major, to `out`.
    ///
    /// # Panics
    /// If `c` or an index is out of range.
    pub fn sample(&self, c: usize, rows: &[usize], cols: &[usize], out: &mut Vec<f32>) {
        let plane = self.img.plane(c);
        let in_w = self.img.size().0;
        let Some((htaps, vtaps)) = &self.taps else {
            for &y in rows {
                let row = &plane[y * in_w..(y + 1) * in_w];
                out.extend(cols.iter().map(|&x| row[x]));
            }
            return;
        };
        // The source rows the requested rows read, through the horizontal pass.
        let lo = rows.iter().map(|&y| vtaps[y].0).min().unwrap_or(0);
        let hi = rows
            .iter()
            .map(|&y| vtaps[y].0 + vtaps[y].1.len())
            .max()
            .unwrap_or(0);
        let n = cols.len();
        let mut tmp = vec![0.0_f32; (hi - lo) * n];
        for (r, dst) in (lo..hi).zip(tmp.chunks_exact_mut(n.max(1))) {
            let src = &plane[r * in_w..(r + 1) * in_w];
            for (d, &x) in dst.iter_mut().zip(cols) {
                let (start, w) = &htaps[x];
                *d = src[*start..*start + w.len()]
                    .iter()
                    .zip(w)
                    .map(|(s, k)| s * k)
                    .sum();
            }
        }
        for &y in rows {
            let (start, w) = &vtaps[y];
            let at = out.len();
            out.resize(at + n, 0.0);
            let dst = &mut out[at..];
            for (i, &k) in w.iter().enumerate() {
                let row = &tmp[(start + i - lo) * n..(start + i - lo + 1) * n];
                for (d, &s) in dst.iter_mut().zip(row) {
                    *d += s * k;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
