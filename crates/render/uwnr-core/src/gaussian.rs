//! OpenCV's 8-bit Gaussian blur, bit for bit: `cv2.GaussianBlur(img_u8, (0, 0), sigma)`.
//!
//! What OpenCV 4.x does for 8-bit images (`modules/imgproc/src/smooth.dispatch.cpp`,
//! `smooth.simd.hpp`, `fixedpoint.inl.hpp`):
//! - kernel size from sigma: `cvRound(sigma * 3 * 2 + 1) | 1` (the 8-bit rule; 4 sigma for other
//!   depths), so sigma 15, 60, 90 give 91, 361 and 541 taps;
//! - kernel `exp(-x^2 / (2 sigma^2))` normalised to sum 1 (`getGaussianKernelBitExact`), then
//!   converted to 8 fractional bits by error diffusion from the outside in, the centre tap taking
//!   whatever makes the sum exactly 256 (`getGaussianKernelFixedPoint_ED`);
//! - separable, horizontal then vertical: the horizontal sums `k * u8` are kept exactly (16-bit,
//!   8 fractional bits), the vertical sums `k * h` have 16 fractional bits and are rounded with
//!   `(v + 2^15) >> 16`;
//! - default border `BORDER_REFLECT_101` (`gfedcb|abcdefgh|gfedcba`), reflected repeatedly as
//!   `borderInterpolate` does when the kernel is wider than the image.
//!
//! All of this is integer arithmetic, so the port folds the reflected taps of each output
//! position into one weight per source pixel: the result is unchanged and a 541-tap kernel on a
//! 77-pixel row costs 77 multiply-adds per output instead of 541.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::index::reflect101;
use crate::resize::U8Image;

/// Kernel radius in sigmas for 8-bit images (OpenCV: `sigma * (depth == CV_8U ? 3 : 4) * 2 + 1`).
const SIGMAS_PER_SIDE_U8: f64 = 3.0;
/// Fractional bits of the 8-bit kernel (`ufixedpoint16::fixedShift`).
const KERNEL_BITS: u32 = 8;
/// Fractional bits after the vertical pass (`ufixedpoint32::fixedShift`).
const SUM_BITS: u32 = 16;

/// Kernel size OpenCV picks for `GaussianBlur(img_u8, (0, 0), sigma)`: `cvRound(6 sigma + 1) | 1`.
#[must_use]
pub fn cv_gaussian_ksize_u8(sigma: f64) -> usize {
    let k = (sigma * SIGMAS_PER_SIDE_U8 * 2.0 + 1.0).round_ties_even() as i64;
    (k | 1).max(1) as usize
}

/// OpenCV's bit-exact Gaussian kernel (`getGaussianKernelBitExact`): `n` taps summing to 1 in
/// double precision. `n` must be odd.
#[must_use]
pub fn cv_gaussian_kernel(n: usize, sigma: f64) -> Vec<f64> {
    let half = (n - 1) / 2;
    let scale2x = -0.125 / (sigma * sigma);
    // Offsets are doubled (`x = 1 - n, 3 - n, ...`) so that they stay integers.
    let values: Vec<f64> = (0..half)
        .map(|i| {
            let x = 2 * i as i64 + 1 - n as i64;
            ((x * x) as f64 * scale2x).exp()
        })
        .collect();
    let mut sum = values.iter().fold(0.0, |acc, v| acc + v);
    sum *= 2.0;
    sum += 1.0;
    let mul = 1.0 / sum;
    let mut kernel = vec![0.0; n];
    for (i, v) in values.iter().enumerate() {
        kernel[i] = v * mul;
        kernel[n - 1 - i] = v * mul;
    }
    kernel[half] = mul;
    kernel
}

/// OpenCV's 8-fractional-bit kernel for 8-bit images (`getGaussianKernelFixedPoint_ED`): error
/// diffusion over the outer taps, rounded half to even, the centre completing the sum to 256.
#[must_use]
pub fn cv_gaussian_kernel_fixed(sigma: f64) -> Vec<u32> {
    let n = cv_gaussian_ksize_u8(sigma);
    let kernel = cv_gaussian_kernel(n, sigma);
    let one = f64::from(1_u32 << KERNEL_BITS);
    let half = n / 2;
    let mut fixed = vec![0_i64; n];
    let mut err = 0.0;
    let mut sum = 0;
    for i in 0..half {
        let adjusted = kernel[i] * one + err;
        let v = adjusted.round_ties_even() as i64;
        err = adjusted - v as f64;
        fixed[i] = v;
        fixed[n - 1 - i] = v;
        sum += v;
    }
    fixed[half] = (1_i64 << KERNEL_BITS) - 2 * sum;
    fixed.into_iter().map(|v| v.max(0) as u32).collect()
}

/// Folded taps per output position, keyed by (sigma bits, length).
type TapCache = HashMap<(u64, usize), Arc<Vec<Vec<(usize, u32)>>>>;

/// Most folded tap tables kept (the light field uses three).
const TAP_CACHE_CAPACITY: usize = 32;

/// [`folded_taps`] of the fixed kernel of `sigma` over a side of `len`, cached: the light-field
/// map blurs images of the same size with the same three sigmas over and over.
fn cached_taps(sigma: f64, len: usize) -> Arc<Vec<Vec<(usize, u32)>>> {
    static CACHE: OnceLock<Mutex<TapCache>> = OnceLock::new();
    let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
    let key = (sigma.to_bits(), len);
    if let Some(taps) = cache.lock().ok().and_then(|c| c.get(&key).cloned()) {
        return taps;
    }
    let taps = Arc::new(folded_taps(&cv_gaussian_kernel_fixed(sigma), len));
    if let Ok(mut c) = cache.lock() {
        if c.len() >= TAP_CACHE_CAPACITY {
            c.clear();
        }
        c.insert(key, Arc::clone(&taps));
    }
    taps
}

/// The taps of each output position with reflected indices folded together: for output `x`,
/// pairs `(source index, summed weight)` in index order.
fn folded_taps(kernel: &[u32], len: usize) -> Vec<Vec<(usize, u32)>> {
    let radius = (kernel.len() / 2) as i64;
    let mut dense = vec![0_u32; len];
    (0..len)
        .map(|x| {
            dense.fill(0);
            for (j, &k) in kernel.iter().enumerate() {
                dense[reflect101(x as i64 + j as i64 - radius, len)] += k;
            }
            dense
                .iter()
                .enumerate()
                .filter(|&(_, &w)| w != 0)
                .map(|(p, &w)| (p, w))
                .collect()
        })
        .collect()
}

/// `cv2.GaussianBlur(src, (0, 0), sigma)` on an 8-bit image (any number of channels), bit for
/// bit with OpenCV 4.x, including its default `BORDER_REFLECT_101`.
pub fn cv_gaussian_blur_u8(src: &U8Image, sigma: f64) -> Result<U8Image> {
    if !(sigma > 0.0 && sigma.is_finite()) {
        return Err(CoreError::InvalidArgument(format!(
            "Gaussian sigma must be positive, got {sigma}"
        )));
    }
    let (w, h, cn) = (src.width, src.height, src.channels);
    if w == 0 || h == 0 {
        return Err(CoreError::Empty {
            width: w,
            height: h,
        });
    }
    // OpenCV drops the kernel along a side of length 1 (`ksize.width = 1` when `width == 1`),
    // which leaves that side unchanged: a single tap of weight 1 (256 in fixed point).
    if w == 1 && h == 1 {
        return Ok(src.clone());
    }
    let unit = || Arc::new(vec![vec![(0, 1_u32 << KERNEL_BITS)]]);
    let xtaps = if w == 1 {
        unit()
    } else {
        cached_taps(sigma, w)
    };
    let ytaps = if h == 1 {
        unit()
    } else {
        cached_taps(sigma, h)
    };

    // Both passes run as "accumulate whole source rows into an output row", which vectorises;
    // the horizontal pass does so on the transposed image (one row per column).
    let columns = transpose_pixels(&src.data, w, h, cn); // [w][h * cn]
    // Horizontal pass: exact sums with 8 fractional bits (at most 255 * 256).
    let horizontal_t = accumulate_rows(&columns, h * cn, &xtaps); // [w][h * cn]
    let horizontal = transpose_pixels(&horizontal_t, h, w, cn); // [h][w * cn]
    // Vertical pass: 16 fractional bits, rounded to u8.
    let vertical = accumulate_rows(&horizontal, w * cn, &ytaps); // [h][w * cn]
    let round = 1_u32 << (SUM_BITS - 1);
    let out = vertical
        .iter()
        .map(|&a| ((a + round) >> SUM_BITS).min(u32::from(u8::MAX)) as u8)
        .collect();
    U8Image::new(w, h, cn, out)
}

/// `out[i] = sum over (p, k) in taps[i] of k * rows[p]`, element-wise over rows of `row_len`.
fn accumulate_rows<T>(rows: &[T], row_len: usize, taps: &[Vec<(usize, u32)>]) -> Vec<u32>
where
    T: Copy + Into<u32> + Sync,
{
    let mut out = vec![0_u32; taps.len() * row_len];
    out.par_chunks_mut(row_len)
        .zip(taps.par_iter())
        .for_each(|(acc, taps)| {
            for &(p, k) in taps {
                let row = &rows[p * row_len..(p + 1) * row_len];
                for (a, &v) in acc.iter_mut().zip(row) {
                    *a += k * v.into();
                }
            }
        });
    out
}

/// Swaps the two spatial axes of interleaved `[h][w][cn]` data, giving `[w][h][cn]`.
fn transpose_pixels<T: Copy + Default>(data: &[T], w: usize, h: usize, cn: usize) -> Vec<T> {
    let mut out = vec![T::default(); data.len()];
    for (y, row) in data.chunks_exact(w * cn).enumerate() {
        for (x, px) in row.chunks_exact(cn).enumerate() {
            let at = (x * h + y) * cn;
            out[at..at + cn].copy_from_slice(px);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_sizes_follow_the_8bit_rule() {
        assert_eq!(cv_gaussian_ksize_u8(15.0), 91);
        assert_eq!(cv_gaussian_ksize_u8(60.0), 361);
        assert_eq!(cv_gaussian_ksize_u8(90.0), 541);
        assert_eq!(cv_gaussian_ksize_u8(1.0), 7);
    }

    #[test]
    fn fixed_kernel_sums_to_256_and_is_symmetric() {
        for sigma in [0.8, 2.5, 15.0, 60.0, 90.0] {
            let k = cv_gaussian_kernel_fixed(sigma);
            assert_eq!(k.iter().sum::<u32>(), 256, "sigma {sigma}");
            let rev: Vec<u32> = k.iter().rev().copied().collect();
            assert_eq!(k, rev);
        }
    }

    #[test]
    fn constant_image_stays_constant() {
        let src = U8Image::new(5, 3, 3, vec![77; 45]).unwrap();
        let out = cv_gaussian_blur_u8(&src, 15.0).unwrap();
        assert!(out.data.iter().all(|&v| v == 77));
    }
}
