//! The AVX2 + FMA micro-kernel: 6 pixels x 16 channels, 12 ymm accumulators.

use std::arch::x86_64::{
    __m256, _mm256_broadcast_ss, _mm256_fmadd_ps, _mm256_loadu_ps, _mm256_setzero_ps,
    _mm256_storeu_ps,
};

use super::{Tile, epilogue};

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
