//! OpenCV 4.x's 8-bit `INTER_LINEAR` resize, bit for bit (`modules/imgproc/src/resize.cpp`).

use rayon::prelude::*;

use super::{U8Image, check_sizes};
use crate::error::{CoreError, Result};

/// Fractional bits of OpenCV's 8-bit `INTER_LINEAR` weights (`INTER_RESIZE_COEF_BITS`).
const CV_COEF_BITS: u32 = 11;
/// `INTER_RESIZE_COEF_SCALE = 1 << INTER_RESIZE_COEF_BITS`.
const CV_COEF_SCALE: i32 = 1 << CV_COEF_BITS;

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
