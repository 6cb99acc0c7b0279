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

/// Support (half-width) of the triangle filter, in input pixels at scale 1 (PIL's
/// `struct filter BILINEAR = {bilinear_filter, 1.0}`).
const TRIANGLE_SUPPORT: f64 = 1.0;
/// Fractional bits of Pillow's 8-bit fixed-point coefficients (`PRECISION_BITS = 32 - 8 - 2`).
const PIL_PRECISION_BITS: u32 = 32 - 8 - 2;
/// Fractional bits of OpenCV's 8-bit `INTER_LINEAR` weights (`INTER_RESIZE_COEF_BITS`).
const CV_COEF_BITS: u32 = 11;
/// `INTER_RESIZE_COEF_SCALE = 1 << INTER_RESIZE_COEF_BITS`.
const CV_COEF_SCALE: i32 = 1 << CV_COEF_BITS;

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

/// Pillow's fixed-point coefficients (`normalize_coeffs_8bpc`): round half away from zero.
fn pil_fixed_taps(taps: &[Taps]) -> Vec<(usize, Vec<i32>)> {
    let one = f64::from(1_u32 << PIL_PRECISION_BITS);
    taps.iter()
        .map(|t| {
            let k = t
                .weights
                .iter()
                .map(|&w| {
                    if w < 0.0 {
                        (-0.5 + w * one) as i32
                    } else {
                        (0.5 + w * one) as i32
                    }
                })
                .collect();
            (t.start, k)
        })
        .collect()
}

/// Pillow's `clip8`: the accumulated fixed-point value shifted down and clamped to u8.
fn pil_clip8(v: i32) -> u8 {
    (v >> PIL_PRECISION_BITS).clamp(0, i32::from(u8::MAX)) as u8
}

/// Pillow's `Image.resize((width, height), Image.BILINEAR)` on an 8-bit image, bit for bit
/// (`ImagingResampleInner`: horizontal pass over the rows the vertical pass needs, rounded to
/// u8, then the vertical pass; a pass is skipped when its size does not change).
pub fn pil_resize_bilinear_u8(src: &U8Image, width: usize, height: usize) -> Result<U8Image> {
    check_sizes(src.width, src.height, width, height)?;
    let cn = src.channels;
    let half = 1_i32 << (PIL_PRECISION_BITS - 1);
    let vtaps = pil_fixed_taps(&triangle_taps(src.height, height));
    // Rows of the source used by the vertical pass (`ybox_first`, `ybox_last`).
    let y_first = vtaps.first().map_or(0, |t| t.0);
    let y_last = vtaps.last().map_or(0, |t| t.0 + t.1.len());

    let (tmp, tmp_w, row_offset) = if width != src.width {
        let htaps = pil_fixed_taps(&triangle_taps(src.width, width));
        let rows = y_last - y_first;
        let mut tmp = vec![0_u8; rows * width * cn];
        tmp.par_chunks_mut(width * cn)
            .enumerate()
            .for_each(|(r, dst)| {
                let y = r + y_first;
                let row = &src.data[y * src.width * cn..(y + 1) * src.width * cn];
                for (xx, (start, k)) in htaps.iter().enumerate() {
                    for c in 0..cn {
                        let mut ss = half;
                        for (i, &w) in k.iter().enumerate() {
                            ss += i32::from(row[(start + i) * cn + c]) * w;
                        }
                        dst[xx * cn + c] = pil_clip8(ss);
                    }
                }
            });
        (tmp, width, y_first)
    } else {
        (src.data.clone(), src.width, 0)
    };

    if height == src.height {
        // Without a vertical pass Pillow returns the horizontal result, which then holds all
        // rows (the vertical bounds span the whole input).
        return U8Image::new(width, height, cn, tmp);
    }
    let mut out = vec![0_u8; height * tmp_w * cn];
    out.par_chunks_mut(tmp_w * cn)
        .zip(vtaps.par_iter())
        .for_each(|(dst, (start, k))| {
            let y0 = start - row_offset;
            for (x, d) in dst.iter_mut().enumerate() {
                let mut ss = half;
                for (i, &w) in k.iter().enumerate() {
                    ss += i32::from(tmp[(y0 + i) * tmp_w * cn + x]) * w;
                }
                *d = pil_clip8(ss);
            }
        });
    U8Image::new(tmp_w, height, cn, out)
}

/// OpenCV's `cvRound` / `saturate_cast<int>` on a float: round half to even.
fn cv_round(v: f64) -> i64 {
    v.round_ties_even() as i64
}

/// OpenCV's `saturate_cast<short>(float)`.
fn cv_saturate_i16(v: f32) -> i32 {
    (v.round_ties_even() as i32).clamp(i32::from(i16::MIN), i32::from(i16::MAX))
}

/// OpenCV `cv2.resize(src, dsize=(width, height), interpolation=INTER_LINEAR)` on an 8-bit
/// image, bit for bit (OpenCV 4.x `cv::resize` / `cv::hal::resize`, no IPP: OpenCV does not use
/// IPP's inexact 8-bit linear resize by default).
pub fn cv_resize_linear_u8(src: &U8Image, width: usize, height: usize) -> Result<U8Image> {
    check_sizes(src.width, src.height, width, height)?;
    let inv_x = width as f64 / src.width as f64;
    let inv_y = height as f64 / src.height as f64;
    Ok(cv_resize_impl(src, width, height, inv_x, inv_y))
}

/// OpenCV `cv2.resize(src, dsize=None, fx=fx, fy=fy, interpolation=INTER_LINEAR)` on an 8-bit
/// image: the output size is `round(size * f)` (half to even) but coordinates are mapped with
/// the scale `1 / f`, not `size / output_size`.
pub fn cv_resize_linear_scale_u8(src: &U8Image, fx: f64, fy: f64) -> Result<U8Image> {
    if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite()) {
        return Err(CoreError::InvalidArgument(format!(
            "resize factors must be positive, got fx={fx}, fy={fy}"
        )));
    }
    let width = cv_round(src.width as f64 * fx).max(0) as usize;
    let height = cv_round(src.height as f64 * fy).max(0) as usize;
    check_sizes(src.width, src.height, width, height)?;
    Ok(cv_resize_impl(src, width, height, fx, fy))
}

fn cv_resize_impl(src: &U8Image, dw: usize, dh: usize, inv_x: f64, inv_y: f64) -> U8Image {
    let (sw, sh, cn) = (src.width, src.height, src.channels);
    if (dw, dh) == (sw, sh) {
        return src.clone();
    }
    let scale_x = 1.0 / inv_x;
    let scale_y = 1.0 / inv_y;
    let (iscale_x, iscale_y) = (cv_round(scale_x), cv_round(scale_y));
    let is_area_fast = (scale_x - iscale_x as f64).abs() < f64::EPSILON
        && (scale_y - iscale_y as f64).abs() < f64::EPSILON;
    // OpenCV: "in case of scale_x && scale_y is equal to 2, INTER_AREA (fast) also is equal to
    // INTER_LINEAR" and switches to the 2x2 box average.
    if is_area_fast && iscale_x == 2 && iscale_y == 2 {
        return cv_resize_area_fast2(src, dw, dh);
    }

    // Horizontal taps: source pixel index and the two 11-bit weights.
    let xtaps: Vec<(usize, [i32; 2])> = (0..dw)
        .map(|dx| {
            let (sx, f) = cv_linear_position(dx, scale_x, sw);
            (sx, cv_weights(f))
        })
        .collect();
    let coef = CV_COEF_SCALE;
    let horizontal = |row: &[u8], out: &mut [i32]| {
        for (dx, &(sx, [a0, a1])) in xtaps.iter().enumerate() {
            let next = (sx + 1).min(sw - 1);
            for c in 0..cn {
                out[dx * cn + c] = if sx + 1 >= sw {
                    // Beyond the last source pixel OpenCV copies it (`S[sx] * ONE`).
                    i32::from(row[sx * cn + c]) * coef
                } else {
                    i32::from(row[sx * cn + c]) * a0 + i32::from(row[next * cn + c]) * a1
                };
            }
        }
    };
    let row_of = |y: usize| &src.data[y * sw * cn..(y + 1) * sw * cn];

    let mut out = vec![0_u8; dw * dh * cn];
    out.par_chunks_mut(dw * cn)
        .enumerate()
        .for_each(|(dy, dst)| {
            let fy = ((dy as f64 + 0.5) * scale_y - 0.5) as f32;
            let sy = fy.floor();
            let fy = fy - sy;
            let sy = sy as i64;
            let [b0, b1] = cv_weights(fy);
            // Rows outside the image are clamped (`clip(sy, 0, ssize.height)`).
            let clampy = |y: i64| y.clamp(0, sh as i64 - 1) as usize;
            let mut s0 = vec![0_i32; dw * cn];
            let mut s1 = vec![0_i32; dw * cn];
            horizontal(row_of(clampy(sy)), &mut s0);
            horizontal(row_of(clampy(sy + 1)), &mut s1);
            for ((d, &a), &b) in dst.iter_mut().zip(&s0).zip(&s1) {
                // VResizeLinear<uchar, int, short, FixedPtCast<int, uchar, 22>>.
                *d = ((((b0 * (a >> 4)) >> 16) + ((b1 * (b >> 4)) >> 16) + 2) >> 2) as u8;
            }
        });
    U8Image {
        width: dw,
        height: dh,
        channels: cn,
        data: out,
    }
}

/// Source index and fraction of output column `d` (OpenCV's `fx = (float)((dx + 0.5) * scale_x
/// - 0.5)`, floored, clamped to the image with the fraction zeroed at the borders).
fn cv_linear_position(d: usize, scale: f64, size: usize) -> (usize, f32) {
    let f = ((d as f64 + 0.5) * scale - 0.5) as f32;
    let s = f.floor();
    let frac = f - s;
    let s = s as i64;
    if s < 0 {
        (0, 0.0)
    } else if s >= size as i64 - 1 {
        (size - 1, 0.0)
    } else {
        (s as usize, frac)
    }
}

/// The two 11-bit weights `saturate_cast<short>((1 - f) * 2048)`, `saturate_cast<short>(f * 2048)`.
fn cv_weights(f: f32) -> [i32; 2] {
    let scale = CV_COEF_SCALE as f32;
    [
        cv_saturate_i16((1.0 - f) * scale),
        cv_saturate_i16(f * scale),
    ]
}

/// OpenCV's `resizeAreaFast_` for an exact factor of 2 on 8-bit data: `(a + b + c + d + 2) >> 2`
/// where the 2x2 block lies inside the image (the SIMD path for 1, 3 or 4 channels), else the
/// rounded mean of the samples that do.
fn cv_resize_area_fast2(src: &U8Image, dw: usize, dh: usize) -> U8Image {
    const SCALE: usize = 2;
    let (sw, sh, cn) = (src.width, src.height, src.channels);
    let fast_mode = matches!(cn, 1 | 3 | 4);
    let at = |y: usize, x: usize, c: usize| u32::from(src.data[(y * sw + x) * cn + c]);
    let mut out = vec![0_u8; dw * dh * cn];
    out.par_chunks_mut(dw * cn)
        .enumerate()
        .for_each(|(dy, dst)| {
            let sy0 = dy * SCALE;
            if sy0 >= sh {
                return;
            }
            let full_cols = if sy0 + SCALE <= sh { sw / SCALE } else { 0 };
            for dx in 0..dw {
                let sx0 = dx * SCALE;
                for c in 0..cn {
                    let v = if dx < full_cols {
                        let sum = at(sy0, sx0, c)
                            + at(sy0, sx0 + 1, c)
                            + at(sy0 + 1, sx0, c)
                            + at(sy0 + 1, sx0 + 1, c);
                        if fast_mode {
                            (sum + 2) >> 2
                        } else {
                            cv_round(f64::from(sum as f32 * 0.25)) as u32
                        }
                    } else if sx0 >= sw {
                        0
                    } else {
                        let (mut sum, mut count) = (0_u32, 0_u32);
                        for y in sy0..(sy0 + SCALE).min(sh) {
                            for x in sx0..(sx0 + SCALE).min(sw) {
                                sum += at(y, x, c);
                                count += 1;
                            }
                        }
                        cv_round(f64::from(sum as f32 / count as f32)) as u32
                    };
                    dst[dx * cn + c] = v.min(255) as u8;
                }
            }
        });
    U8Image {
        width: dw,
        height: dh,
        channels: cn,
        data: out,
    }
}

#[cfg(test)]
mod tests;
