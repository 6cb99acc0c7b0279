//! The AVX-512F micro-kernel: 12 pixels x 32 channels, 24 zmm accumulators.

use std::arch::x86_64::{
    __m512, __mmask16, _mm512_add_ps, _mm512_fmadd_ps, _mm512_loadu_ps, _mm512_mask_storeu_ps,
    _mm512_maskz_loadu_ps, _mm512_max_ps, _mm512_mul_ps, _mm512_set1_ps, _mm512_setzero_ps,
    _mm512_storeu_ps,
};

use super::act::LEAKY_RELU_SLOPE;
use super::{Act, Tile, epilogue};

const MR: usize = 12;
const NR: usize = 32;
const LANES: usize = 16;

/// # Safety
/// See [`super::run_tile`]; the CPU must have AVX-512F.
pub(super) unsafe fn tile(t: &Tile<'_>) {
    // SAFETY: forwarded.
    unsafe {
        match t.m {
            1 => tile_m::<1>(t),
            2 => tile_m::<2>(t),
            3 => tile_m::<3>(t),
            4 => tile_m::<4>(t),
            5 => tile_m::<5>(t),
            6 => tile_m::<6>(t),
            7 => tile_m::<7>(t),
            8 => tile_m::<8>(t),
            9 => tile_m::<9>(t),
            10 => tile_m::<10>(t),
            11 => tile_m::<11>(t),
            _ => tile_m::<MR>(t),
        }
    }
}

#[target_feature(enable = "avx512f")]
unsafe fn tile_m<const M: usize>(t: &Tile<'_>) {
    let mut acc: [[__m512; 2]; M] = [[_mm512_setzero_ps(); 2]; M];
    for (tap, &off) in t.taps.iter().enumerate() {
        // SAFETY: caller's contract on the A and B ranges.
        unsafe {
            let a = t.a.offset(off);
            let mut b = t.b.add(tap * t.k * NR);
            for kk in 0..t.k {
                let b0 = _mm512_loadu_ps(b);
                let b1 = _mm512_loadu_ps(b.add(LANES));
                for (m, accm) in acc.iter_mut().enumerate() {
                    let av = _mm512_set1_ps(*a.add(m * t.lda + kk));
                    accm[0] = _mm512_fmadd_ps(av, b0, accm[0]);
                    accm[1] = _mm512_fmadd_ps(av, b1, accm[1]);
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
            _mm512_storeu_ps(vals.as_mut_ptr(), accm[0]);
            _mm512_storeu_ps(vals.as_mut_ptr().add(LANES), accm[1]);
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
/// As [`super::run_tile`] for `t.c` and `t.bias`; the CPU must have AVX-512F.
#[target_feature(enable = "avx512f")]
unsafe fn store_in_registers<const M: usize>(t: &Tile<'_>, acc: &[[__m512; 2]; M]) {
    let masks: [__mmask16; 2] = [column_mask(t.n), column_mask(t.n.saturating_sub(LANES))];
    // SAFETY: bias holds NR values.
    let bias = unsafe { [_mm512_loadu_ps(t.bias), _mm512_loadu_ps(t.bias.add(LANES))] };
    let slope = _mm512_set1_ps(LEAKY_RELU_SLOPE);
    let leaky = t.act == Act::LeakyRelu;
    for (row, accm) in acc.iter().enumerate().take(t.m) {
        for (half, (&sum, &mask)) in accm.iter().zip(&masks).enumerate() {
            if mask == 0 {
                continue;
            }
            // SAFETY: row < m and the mask covers columns < n: inside the output range.
            unsafe {
                let dst = t.c.add(row * t.ldc + half * LANES);
                let mut v = _mm512_add_ps(sum, bias[half]);
                if t.accumulate {
                    v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(mask, dst));
                }
                if leaky {
                    v = _mm512_max_ps(v, _mm512_mul_ps(v, slope));
                }
                _mm512_mask_storeu_ps(dst, mask, v);
            }
        }
    }
}

/// The lanes of the first `n` (capped at 16) columns.
fn column_mask(n: usize) -> __mmask16 {
    if n >= LANES {
        0xFFFF
    } else {
        ((1u32 << n) - 1) as __mmask16
    }
}
