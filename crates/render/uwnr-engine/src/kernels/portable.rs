//! The portable micro-kernel: 4 pixels x 16 channels of plain `f32` arithmetic, which the
//! compiler vectorises for whatever target it builds (SSE2, NEON, ...).

use super::{Tile, epilogue};

const MR: usize = 4;
const NR: usize = 16;

/// # Safety
/// See [`super::run_tile`].
pub(super) unsafe fn tile(t: &Tile<'_>) {
    match t.m {
        1 => unsafe { tile_m::<1>(t) },
        2 => unsafe { tile_m::<2>(t) },
        3 => unsafe { tile_m::<3>(t) },
        _ => unsafe { tile_m::<MR>(t) },
    }
}

#[inline(always)]
unsafe fn tile_m<const M: usize>(t: &Tile<'_>) {
    let mut acc = [[0.0f32; NR]; M];
    for (tap, &off) in t.taps.iter().enumerate() {
        // SAFETY: caller's contract on the A and B ranges.
        let a = unsafe { t.a.offset(off) };
        let panel = unsafe { std::slice::from_raw_parts(t.b.add(tap * t.k * NR), t.k * NR) };
        for (kk, b) in panel.chunks_exact(NR).enumerate() {
            for (m, accm) in acc.iter_mut().enumerate() {
                let av = unsafe { *a.add(m * t.lda + kk) };
                for (c, &bv) in accm.iter_mut().zip(b) {
                    *c += av * bv;
                }
            }
        }
    }
    unsafe { epilogue::<NR, _>(t, &mut acc) };
}
