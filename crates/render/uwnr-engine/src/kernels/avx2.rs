//! The AVX2 + FMA micro-kernel: 6 pixels x 16 channels, 12 ymm accumulators.

use std::arch::x86_64::{
    __m256, __m256i, _mm256_add_ps, _mm256_broadcast_ss, _mm256_fmadd_ps, _mm256_loadu_ps,
    _mm256_loadu_si256, _mm256_maskload_ps, _mm256_maskstore_ps, _mm256_max_ps, _mm256_mul_ps,
    _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps,
};

use super::act::LEAKY_RELU_SLOPE;
use super::{Act, Tile, epilogue};

const MR: usize = 6;
const NR: usize = 16;
const LANES: usize = 8;

/// # Safety
/// See [`super::run_tile`]; the CPU must have AVX2 and FMA.
pub(super) unsafe fn tile(t: &Tile<'_>) {
    // SAFETY: forwarded.
    unsafe {
        match t.m {
            1 => tile_m::<1>(t),
            2 => tile_m::<2>(t),
            3 => tile_m::<3>(t),
            4 => tile_m::<4>(t),
            5 => tile_m::<5>(t),
            _ => tile_m::<MR>(t),
        }
    }
}

#[target_feature(enable = "avx2,fma")]
unsafe fn tile_m<const M: usize>(t: &Tile<'_>) {
    let mut acc: [[__m256; 2]; M] = [[_mm256_setzero_ps(); 2]; M];
    for (tap, &off) in t.taps.iter().enumerate() {
        // SAFETY: caller's contract on the A and B ranges.
        unsafe {
            let a = t.a.offset(off);
            let mut b = t.b.add(tap * t.k * NR);
            for kk in 0..t.k {
                let b0 = _mm256_loadu_ps(b);
                let b1 = _mm256_loadu_ps(b.add(LANES));
                for (m, accm) in acc.iter_mut().enumerate() {
                    let av = _mm256_broadcast_ss(&*a.add(m * t.lda + kk));
                    accm[0] = _mm256_fmadd_ps(av, b0, accm[0]);
                    accm[1] = _mm256_fmadd_ps(av, b1, accm[1]);
                }
                b = b.add(NR);
            }
        }
    }
    if matches!(t.act, Act::Identity | Act::LeakyRelu) {
        // SAFETY: caller's contract on the output range and the NR biases.
        unsafe { store_in_registers(t, &acc) };
        return;
    }
    let mut buf = [[0.0f32; NR]; M];
    for (vals, accm) in buf.iter_mut().zip(&acc) {
        // SAFETY: each row of buf holds NR = 2 x LANES floats.
        unsafe {
            _mm256_storeu_ps(vals.as_mut_ptr(), accm[0]);
            _mm256_storeu_ps(vals.as_mut_ptr().add(LANES), accm[1]);
        }
    }
    // SAFETY: caller's contract on the output range.
    unsafe { epilogue::<NR, _>(t, &mut buf) };
}

/// The epilogue of [`tile_m`] for the activations that are cheap in registers: bias, the
/// values `C` holds when accumulating, LeakyReLU, and masked stores of the `n` columns, with
/// no round trip through memory.
///
/// # Safety
/// As [`super::run_tile`] for `t.c` and `t.bias`; the CPU must have AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
unsafe fn store_in_registers<const M: usize>(t: &Tile<'_>, acc: &[[__m256; 2]; M]) {
    // Lane j of half h is stored where column h * LANES + j < n: -1 (all bits) in the mask.
    let lanes: [i32; 2 * NR] = std::array::from_fn(|i| if i < NR { -1 } else { 0 });
    let cols = t.n.min(NR);
    // SAFETY: the window [NR - cols + h * LANES, + LANES) lies inside `lanes`; its first
    // `cols - h * LANES` entries are -1.
    let masks: [__m256i; 2] = std::array::from_fn(|h| unsafe {
        let from = (NR - cols + h * LANES).min(2 * NR - LANES);
        _mm256_loadu_si256(lanes.as_ptr().add(from).cast())
    });
    let full = [cols >= LANES, cols == NR];
    let live = [true, cols > LANES];
    // SAFETY: bias holds NR values.
    let bias = unsafe { [_mm256_loadu_ps(t.bias), _mm256_loadu_ps(t.bias.add(LANES))] };
    let slope = _mm256_set1_ps(LEAKY_RELU_SLOPE);
    let leaky = t.act == Act::LeakyRelu;
    for (row, accm) in acc.iter().enumerate().take(t.m) {
        for half in 0..2 {
            if !live[half] {
                continue;
            }
            // SAFETY: row < m and the stored lanes are columns < n: inside the output range.
            unsafe {
                let dst = t.c.add(row * t.ldc + half * LANES);
                let mut v = _mm256_add_ps(accm[half], bias[half]);
                if t.accumulate {
                    let old = if full[half] {
                        _mm256_loadu_ps(dst)
                    } else {
                        _mm256_maskload_ps(dst, masks[half])
                    };
                    v = _mm256_add_ps(v, old);
                }
                if leaky {
                    v = _mm256_max_ps(v, _mm256_mul_ps(v, slope));
                }
                if full[half] {
                    _mm256_storeu_ps(dst, v);
                } else {
                    _mm256_maskstore_ps(dst, masks[half], v);
                }
            }
        }
    }
}
