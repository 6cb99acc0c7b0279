//! Pillow's 8-bit `BILINEAR` resize, bit for bit (`libImaging/Resample.c`), on the triangle
//! taps of the parent module.

use rayon::prelude::*;

use super::{Taps, U8Image, check_sizes, triangle_taps};
use crate::error::Result;

/// Fractional bits of Pillow's 8-bit fixed-point coefficients (`PRECISION_BITS = 32 - 8 - 2`).
const PIL_PRECISION_BITS: u32 = 32 - 8 - 2;

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
