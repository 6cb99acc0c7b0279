//! bf16 operands for the products: the rounding of runs (f32 to bf16, round to nearest even, as
//! `vcvtne2ps2bf16`; the scalar rule is [`super::bf16_bits`]), the packing of `B` in the pairs
//! `vdpbf16ps` reads, and the emulated kernel that runs anywhere.
//!
//! bf16 is the upper half of an f32: 8 exponent bits, 8 significant bits (7 stored), so a
//! rounded value is within a relative `u = 2^-8` of the f32 one. `vdpbf16ps` multiplies the
//! pairs `(a[2i], a[2i+1])` and `(b[2i], b[2i+1])` of each 32-bit lane and adds both products
//! to the lane's f32 sum; a product of two bf16 values is exact in f32 (16 significant bits),
//! so the only roundings are the operands' and the f32 additions. The emulation widens the
//! pairs to f32 and does the same two multiply-adds per lane (odd element first, as the
//! instruction's definition), so both kernels differ only in the additions' rounding (the
//! instruction flushes denormals; the emulation does not).
//!
//! Layouts: `A` rows are bf16 runs along `k` (`k` even, a zero appended to odd runs);
//! `B` is `[k / 2][NR][2]`: for each pair of `k`, the `NR` columns' two values side by side,
//! so one 32-bit lane of a `B` vector is one column's pair.

use super::bf16_bits::{round, widen};
use super::{Isa, MAX_NR, Tile, epilogue};

/// Whether this CPU has AVX512_BF16 (with AVX-512F).
#[must_use]
pub fn native_supported() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bf16")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `k` rounded up to a whole number of bf16 pairs.
#[must_use]
pub fn padded(k: usize) -> usize {
    k.next_multiple_of(2)
}

/// Rounds `src` into `dst[..src.len()]` and zeroes the rest of `dst` (the pad of an odd run).
/// `native` uses `vcvtne2ps2bf16` (same results on normal numbers; it flushes denormals).
///
/// # Safety
/// `native` only where [`native_supported`].
#[inline(always)]
pub unsafe fn round_run(native: bool, src: &[f32], dst: &mut [u16]) {
    debug_assert!(dst.len() >= src.len());
    #[cfg(target_arch = "x86_64")]
    if native {
        // SAFETY: the caller checked the CPU.
        unsafe { super::avx512bf16::round_run(src, dst) };
        return;
    }
    let _ = native;
    let (head, tail) = dst.split_at_mut(src.len());
    for (d, &s) in head.iter_mut().zip(src) {
        *d = round(s);
    }
    tail.fill(0);
}

/// Packs a `[k][nr]` f32 panel as `[padded(k) / 2][nr][2]` bf16 pairs (zero pairs past `k`).
#[must_use]
pub fn pack_pairs(panel: &[f32], k: usize, nr: usize) -> Vec<u16> {
    let kp = padded(k);
    let mut out = vec![0u16; kp * nr];
    for kk in 0..k {
        for n in 0..nr {
            out[((kk / 2) * nr + n) * 2 + kk % 2] = round(panel[kk * nr + n]);
        }
    }
    out
}

/// The emulated bf16 kernel at `isa`'s tile shape, compiled for `isa`'s instruction set.
///
/// # Safety
/// See [`super::run_tile_bf16`].
pub(super) unsafe fn emulated_tile(isa: Isa, t: &Tile<'_, u16>) {
    // SAFETY: forwarded; each variant's features are the ISA's, which the caller checked.
    unsafe {
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => emulated_avx512(t),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => emulated_avx2(t),
            _ => emulated::<16>(t),
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn emulated_avx512(t: &Tile<'_, u16>) {
    // SAFETY: forwarded.
    unsafe { emulated::<32>(t) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn emulated_avx2(t: &Tile<'_, u16>) {
    // SAFETY: forwarded.
    unsafe { emulated::<16>(t) }
}

/// Largest tile height of any variant.
const MAX_MR: usize = 12;

/// `NR`-wide tile of up to [`MAX_MR`] rows with f32 sums of widened bf16 pairs.
#[inline(always)]
unsafe fn emulated<const NR: usize>(t: &Tile<'_, u16>) {
    const { assert!(NR <= MAX_NR) };
    debug_assert!(t.m <= MAX_MR);
    let mut acc = [[0.0f32; NR]; MAX_MR];
    let pairs = t.k / 2;
    for (tap, &off) in t.taps.iter().enumerate() {
        // SAFETY: caller's contract on the A and B ranges.
        let a = unsafe { t.a.offset(off) };
        let panel = unsafe { std::slice::from_raw_parts(t.b.add(tap * t.k * NR), t.k * NR) };
        for (p, b) in panel.chunks_exact(2 * NR).enumerate().take(pairs) {
            let bw: [[f32; 2]; NR] =
                std::array::from_fn(|n| [widen(b[2 * n]), widen(b[2 * n + 1])]);
            for (m, accm) in acc.iter_mut().enumerate().take(t.m) {
                // SAFETY: row m < t.m, element 2p + 1 < k.
                let (a0, a1) = unsafe {
                    let r = a.add(m * t.lda + 2 * p);
                    (widen(*r), widen(*r.add(1)))
                };
                for (c, bw) in accm.iter_mut().zip(&bw) {
                    *c += a1 * bw[1];
                    *c += a0 * bw[0];
                }
            }
        }
    }
    // SAFETY: caller's contract on the output range.
    unsafe { epilogue::<NR, _>(t, &mut acc[..t.m]) };
}

/// The bf16 kernels this CPU runs, with the instruction sets whose tiles they fill: the
/// emulation on every supported ISA, `vdpbf16ps` on AVX-512 where present.
#[cfg(test)]
pub(crate) fn test_variants() -> Vec<(Isa, super::Dot)> {
    let mut v: Vec<(Isa, super::Dot)> = Isa::supported()
        .into_iter()
        .map(|i| (i, super::Dot::Bf16Emulated))
        .collect();
    if native_supported() && Isa::Avx512.is_supported() {
        v.insert(0, (Isa::Avx512, super::Dot::Bf16Native));
    }
    v
}

/// Relative bound `r(K)` on a bf16 dot product of `K` terms: `|s^ - s| <= r(K) sum_k |a_k b_k|`.
///
/// Each operand is rounded to the nearest bf16, within a relative `u = 2^-8` (8 significant
/// bits), and the product of two bf16 values is exact in f32, so each term is off by at most
/// `(2u + u^2) |a_k b_k|`. Adding `K` terms in f32 in any order (the pairs of `vdpbf16ps`, the
/// blocks of a split reduction) adds at most `gamma_K = K 2^-24 / (1 - K 2^-24)` of the sum of
/// their magnitudes (Higham, "Accuracy and Stability of Numerical Algorithms", 3.1). Together:
/// `r(K) = (1 + u)^2 (1 + gamma_K) - 1`, here with 1% slack for the f32 rounding of the
/// operands before they are rounded to bf16 (a relative 1e-6 at most in the transforms).
#[cfg(test)]
pub(crate) fn dot_bound(k: usize) -> f64 {
    const U_BF16: f64 = 1.0 / 256.0;
    const U_F32: f64 = 1.0 / 16_777_216.0;
    let gamma = k as f64 * U_F32 / (1.0 - k as f64 * U_F32);
    ((1.0 + U_BF16).powi(2) * (1.0 + gamma) - 1.0) * 1.01
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn native_rounding_matches_the_portable_one() {
        if !native_supported() {
            return;
        }
        let src: Vec<f32> = (0..77)
            .map(|i| ((i * 7919) % 1013) as f32 / 37.0 - 13.0 + 2f32.powi(-9) * i as f32)
            .collect();
        let mut want = vec![9u16; 80];
        let mut got = vec![9u16; 80];
        // SAFETY: checked above.
        unsafe {
            round_run(false, &src, &mut want);
            round_run(true, &src, &mut got);
        }
        assert_eq!(got, want);
        assert_eq!(&got[77..], &[0, 0, 0]);
    }

    #[test]
    fn pairs_interleave_k() {
        // [k = 3][nr = 2]
        let panel = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let p = pack_pairs(&panel, 3, 2);
        let w: Vec<f32> = p.iter().map(|&h| widen(h)).collect();
        assert_eq!(w, [1.0, 3.0, 2.0, 4.0, 5.0, 0.0, 6.0, 0.0]);
    }
}
