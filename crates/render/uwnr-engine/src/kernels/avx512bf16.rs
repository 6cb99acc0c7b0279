//! The AVX512_BF16 micro-kernel: 12 pixels x 32 channels, 24 zmm f32 accumulators, one
//! `vdpbf16ps` per accumulator and pair of `k` (32 multiply-adds, twice an f32 FMA's), with
//! the `A` pair broadcast as one 32-bit value. The AVX512_BF16 intrinsics, target feature and
//! run-time detection are stable since Rust 1.89 (the workspace needs 1.95), so no inline
//! assembly is needed.

use std::arch::x86_64::{
    __m512, __m512bh, __m512i, _mm512_cvtne2ps_pbh, _mm512_dpbf16_ps, _mm512_loadu_ps,
    _mm512_loadu_si512, _mm512_set1_epi32, _mm512_setzero_ps, _mm512_storeu_ps,
    _mm512_storeu_si512,
};

use super::bf16_bits::round;
use super::{Tile, epilogue};

const MR: usize = 12;
const NR: usize = 32;
const LANES: usize = 16;

/// # Safety
/// See [`super::run_tile_bf16`]; the CPU must have AVX-512F and AVX512_BF16.
pub(super) unsafe fn tile(t: &Tile<'_, u16>) {
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

/// 32 bf16 values as the pair vector `vdpbf16ps` takes.
#[inline(always)]
fn as_bh(v: __m512i) -> __m512bh {
    // SAFETY: both are 512 bits of plain data.
    unsafe { std::mem::transmute::<__m512i, __m512bh>(v) }
}

#[target_feature(enable = "avx512f,avx512bf16")]
unsafe fn tile_m<const M: usize>(t: &Tile<'_, u16>) {
    let mut acc: [[__m512; 2]; M] = [[_mm512_setzero_ps(); 2]; M];
    let pairs = t.k / 2;
    for (tap, &off) in t.taps.iter().enumerate() {
        // SAFETY: caller's contract on the A and B ranges (k even, B `[k / 2][NR][2]`).
        unsafe {
            let a = t.a.offset(off);
            let mut b = t.b.add(tap * t.k * NR);
            for p in 0..pairs {
                let b0 = as_bh(_mm512_loadu_si512(b.cast::<__m512i>()));
                let b1 = as_bh(_mm512_loadu_si512(b.add(2 * LANES).cast::<__m512i>()));
                for (m, accm) in acc.iter_mut().enumerate() {
                    let pair = a.add(m * t.lda + 2 * p).cast::<i32>().read_unaligned();
                    let av = as_bh(_mm512_set1_epi32(pair));
                    accm[0] = _mm512_dpbf16_ps(accm[0], av, b0);
                    accm[1] = _mm512_dpbf16_ps(accm[1], av, b1);
                }
                b = b.add(2 * NR);
            }
        }
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

/// The native path of `bf16::round_run`: `vcvtne2ps2bf16`, 32 values at a time, the tail by
/// [`round`].
///
/// # Safety
/// The CPU must have AVX-512F and AVX512_BF16; `dst.len() >= src.len()`.
#[target_feature(enable = "avx512f,avx512bf16")]
pub(super) unsafe fn round_run(src: &[f32], dst: &mut [u16]) {
    let n = src.len();
    let whole = n - n % (2 * LANES);
    let mut i = 0;
    while i < whole {
        // SAFETY: i + 32 <= n <= dst.len().
        unsafe {
            let lo = _mm512_loadu_ps(src.as_ptr().add(i));
            let hi = _mm512_loadu_ps(src.as_ptr().add(i + LANES));
            // The second operand fills the low half of the result.
            let v = _mm512_cvtne2ps_pbh(hi, lo);
            let bits = std::mem::transmute::<__m512bh, __m512i>(v);
            _mm512_storeu_si512(dst.as_mut_ptr().add(i).cast::<__m512i>(), bits);
        }
        i += 2 * LANES;
    }
    for (d, &s) in dst[whole..n].iter_mut().zip(&src[whole..]) {
        *d = round(s);
    }
    dst[n..].fill(0);
}
