//! Direct convolutions on channels-last maps: 3x3 (stride 1 or 2, zero padding 1) and 1x1,
//! with the bias and activation fused into the store.
//!
//! Output pixel `(y, x)` of a 3x3 convolution with stride `s` reads padded input pixels
//! `(s y + ky, s x + kx)`, `ky, kx < 3`: for a run of `MR` pixels of one output row, each tap
//! is a `MR x cin` block of the input with rows `s cin` floats apart, so the nine taps are
//! nine `(offset, weight panel)` pairs of one micro-kernel call and nothing is copied. Work is
//! split over (output row, panel of `NR` output channels) so both cores stay busy from the
//! 128-row first level down to the 16-row bottleneck.
//!
//! With bf16 products ([`Dot`]) the source map is first rounded into a bf16 copy of the same
//! geometry, each pixel's channels padded to a whole number of pairs, and the weights are
//! packed in pairs once (see [`crate::kernels::bf16`]); sums and epilogue stay f32.

use rayon::prelude::*;

use crate::kernels::bf16::{self, padded};
use crate::kernels::{Act, Dot, Isa, Tile, run_tile, run_tile_bf16};
use crate::tensor::{Feature, Pool, SharedMut};

/// A convolution packed for one instruction set.
#[derive(Clone, Debug)]
pub(crate) struct Conv {
    pub isa: Isa,
    pub dot: Dot,
    pub cin: usize,
    pub cout: usize,
    /// 1 or 3.
    pub k: usize,
    /// 1 or 2.
    pub stride: usize,
    pub act: Act,
    /// `[panel][tap][cin][NR]` (empty for bf16 products).
    panels: Vec<f32>,
    /// `[panel][tap][padded(cin) / 2][NR][2]` bf16 (empty for f32 products).
    panels_bf16: Vec<u16>,
    /// `[panel][NR]`.
    bias: Vec<f32>,
}

impl Conv {
    /// Packs PyTorch-layout weights `[cout][cin][k][k]`. Packed output channel `n` takes the
    /// weights of original channel `order[n]` (identity when `order` is `None`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        isa: Isa,
        dot: Dot,
        weight: &[f32],
        bias: &[f32],
        cout: usize,
        cin: usize,
        k: usize,
        stride: usize,
        act: Act,
        order: Option<&[usize]>,
    ) -> Self {
        let nr = isa.nr();
        let taps = k * k;
        let panels_n = cout.div_ceil(nr);
        let mut panels = vec![0.0; panels_n * taps * cin * nr];
        let mut packed_bias = vec![0.0; panels_n * nr];
        for n in 0..cout {
            let co = order.map_or(n, |o| o[n]);
            let (p, col) = (n / nr, n % nr);
            packed_bias[n] = bias[co];
            for ci in 0..cin {
                for t in 0..taps {
                    panels[((p * taps + t) * cin + ci) * nr + col] =
                        weight[(co * cin + ci) * taps + t];
                }
            }
        }
        let mut panels_bf16 = Vec::new();
        if dot.is_bf16() {
            panels_bf16.reserve(panels_n * taps * padded(cin) * nr);
            for block in panels.chunks_exact(cin * nr) {
                panels_bf16.extend(bf16::pack_pairs(block, cin, nr));
            }
            panels = Vec::new();
        }
        Self {
            isa,
            dot,
            cin,
            cout,
            k,
            stride,
            act,
            panels,
            panels_bf16,
            bias: packed_bias,
        }
    }

    fn panels(&self) -> usize {
        self.cout.div_ceil(self.isa.nr())
    }

    /// Output size for an input of `h x w`.
    pub fn out_size(&self, h: usize, w: usize) -> (usize, usize) {
        (h.div_ceil(self.stride), w.div_ceil(self.stride))
    }

    /// Writes the convolution of `src` into `dst` (interior, `dst.c == cout`). A 3x3 kernel
    /// needs `src.pad == 1`. The bf16 copy of `src` lives in a buffer of `pool`.
    pub fn run(&self, src: &Feature, dst: &mut Feature, pool: &mut Pool) {
        if self.dot.is_bf16() {
            self.run_bf16(src, dst, pool);
            return;
        }
        debug_assert_eq!(src.c, self.cin);
        debug_assert_eq!(dst.c, self.cout);
        debug_assert!(self.k == 1 || src.pad == 1);
        let (ho, wo) = self.out_size(src.h, src.w);
        debug_assert_eq!((dst.h, dst.w), (ho, wo));
        let (nr, mr) = (self.isa.nr(), self.isa.mr());
        let taps: Vec<isize> = if self.k == 3 {
            (0..3)
                .flat_map(|ky| (0..3).map(move |kx| (ky, kx)))
                .map(|(ky, kx)| (ky * src.row_stride() + kx * src.c) as isize)
                .collect()
        } else {
            vec![0]
        };
        let lda = self.stride * self.cin;
        let panel_len = taps.len() * self.cin * nr;
        let out = SharedMut(dst.data.as_mut_ptr());
        let out_len = dst.data.len();
        let dst_at = |y: usize| dst.at(y, 0);
        let dst_rows: Vec<usize> = (0..ho).map(dst_at).collect();
        let npanels = self.panels();
        (0..ho * npanels).into_par_iter().for_each(|item| {
            let (y, p) = (item / npanels, item % npanels);
            // Row of the input the tile's first pixel reads at tap (0, 0): for 3x3 the padded
            // row `s y` (taps add 0..2 rows and columns), for 1x1 the interior row `s y`.
            let a_row = if self.k == 3 {
                self.stride * y * src.row_stride()
            } else {
                src.at(self.stride * y, 0)
            };
            let n = (self.cout - p * nr).min(nr);
            let mut x = 0;
            while x < wo {
                let m = (wo - x).min(mr);
                let c_off = dst_rows[y] + x * self.cout + p * nr;
                debug_assert!(c_off + (m - 1) * self.cout + n <= out_len);
                let tile = Tile {
                    // SAFETY (pointer arithmetic): inside src.data by the geometry above.
                    a: unsafe { src.data.as_ptr().add(a_row + x * lda) },
                    lda,
                    taps: &taps,
                    k: self.cin,
                    b: unsafe { self.panels.as_ptr().add(p * panel_len) },
                    bias: unsafe { self.bias.as_ptr().add(p * nr) },
                    c: unsafe { out.get().add(c_off) },
                    ldc: self.cout,
                    m,
                    n,
                    act: self.act,
                    accumulate: false,
                };
                // SAFETY: the A reads stay inside the padded source (rows s y .. s y + 2 of
                // the padded map, columns s x .. s (x + m - 1) + 2), B and bias inside the
                // panel, and C writes inside this item's own output row and channel panel.
                unsafe { run_tile(self.isa, &tile) };
                x += m;
            }
        });
    }
}

impl Conv {
    /// [`Conv::run`] with bf16 operands.
    fn run_bf16(&self, src: &Feature, dst: &mut Feature, pool: &mut Pool) {
        debug_assert_eq!((src.c, dst.c), (self.cin, self.cout));
        debug_assert!(self.k == 1 || src.pad == 1);
        let (ho, wo) = self.out_size(src.h, src.w);
        debug_assert_eq!((dst.h, dst.w), (ho, wo));
        let (cin, kp) = (self.cin, padded(self.cin));
        // The source's every pixel (border included), `kp` bf16 values each.
        let pixels = src.data.len() / cin;
        let mut buf = pool.take_stale((pixels * kp).div_ceil(2));
        // SAFETY: the f32 buffer holds at least pixels * kp bf16 values; u16 is less aligned.
        let a =
            unsafe { std::slice::from_raw_parts_mut(buf.as_mut_ptr().cast::<u16>(), pixels * kp) };
        let native = self.dot == Dot::Bf16Native;
        let row_px = src.row_stride() / cin;
        a.par_chunks_mut(row_px * kp)
            .zip(src.data.par_chunks(row_px * cin))
            .for_each(|(dst_row, src_row)| {
                if kp == cin {
                    // SAFETY: `native` only where the CPU has AVX512_BF16.
                    unsafe { bf16::round_run(native, src_row, dst_row) };
                } else {
                    for (d, s) in dst_row.chunks_exact_mut(kp).zip(src_row.chunks_exact(cin)) {
                        // SAFETY: as above.
                        unsafe { bf16::round_run(native, s, d) };
                    }
                }
            });
        let (isa, dot) = (self.isa, self.dot);
        let (nr, mr) = (isa.nr(), isa.mr());
        // Offsets in the bf16 copy: a pixel's kp values where the f32 map has cin.
        let at = |f32_index: usize| f32_index / cin * kp;
        let taps: Vec<isize> = if self.k == 3 {
            (0..3)
                .flat_map(|ky| (0..3).map(move |kx| (ky, kx)))
                .map(|(ky, kx)| (ky * row_px * kp + kx * kp) as isize)
                .collect()
        } else {
            vec![0]
        };
        let lda = self.stride * kp;
        let panel_len = taps.len() * kp * nr;
        let out = SharedMut(dst.data.as_mut_ptr());
        let dst_rows: Vec<usize> = (0..ho).map(|y| dst.at(y, 0)).collect();
        let npanels = self.panels();
        let a: &[u16] = a;
        (0..ho * npanels).into_par_iter().for_each(|item| {
            let (y, p) = (item / npanels, item % npanels);
            let a_row = if self.k == 3 {
                self.stride * y * row_px * kp
            } else {
                at(src.at(self.stride * y, 0))
            };
            let n = (self.cout - p * nr).min(nr);
            let mut x = 0;
            while x < wo {
                let m = (wo - x).min(mr);
                let tile = Tile {
                    // SAFETY (pointer arithmetic): inside the bf16 copy, which has the f32
                    // map's geometry.
                    a: unsafe { a.as_ptr().add(a_row + x * lda) },
                    lda,
                    taps: &taps,
                    k: kp,
                    b: unsafe { self.panels_bf16.as_ptr().add(p * panel_len) },
                    bias: unsafe { self.bias.as_ptr().add(p * nr) },
                    c: unsafe { out.get().add(dst_rows[y] + x * self.cout + p * nr) },
                    ldc: self.cout,
                    m,
                    n,
                    act: self.act,
                    accumulate: false,
                };
                // SAFETY: as in `run`, on the bf16 copy; `dot` is a bf16 kernel the CPU runs.
                unsafe { run_tile_bf16(isa, dot, &tile) };
                x += m;
            }
        });
        pool.give_vec(buf);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{self, test_values as lcg};
    use crate::tensor::Planar;

    #[test]
    fn every_isa_matches_the_reference() {
        // Channel counts around the panel widths, odd widths for partial tiles.
        let cases = [
            (7, 16, 3, 2, 12, 10, Act::Elu),
            (8, 8, 3, 1, 5, 13, Act::LeakyRelu),
            (16, 40, 3, 1, 4, 7, Act::Identity),
            (33, 3, 3, 1, 6, 6, Act::Tanh),
            (24, 6, 1, 1, 3, 29, Act::LeakyRelu),
            (32, 64, 3, 2, 8, 26, Act::Identity),
        ];
        for isa in Isa::supported() {
            for (i, &(cin, cout, k, stride, h, w, act)) in cases.iter().enumerate() {
                let weight = lcg(i as u64 + 1, cout * cin * k * k, 0.3);
                let bias = lcg(i as u64 + 100, cout, 0.5);
                let input = Planar {
                    channels: cin,
                    height: h,
                    width: w,
                    data: lcg(i as u64 + 200, cin * h * w, 1.0),
                };
                let want = reference::conv2d(&input, &weight, &bias, cout, k, stride);
                let want = reference::activate(act, want);
                let conv = Conv::new(
                    isa,
                    Dot::F32,
                    &weight,
                    &bias,
                    cout,
                    cin,
                    k,
                    stride,
                    act,
                    None,
                );
                let src = Feature::from_planar(&input, k / 2);
                let (ho, wo) = conv.out_size(h, w);
                let mut dst = Feature::zeros(ho, wo, cout, 1);
                conv.run(&src, &mut dst, &mut Pool::default());
                let got = dst.to_planar();
                assert_eq!((got.height, got.width), (want.height, want.width));
                let diff = reference::max_abs_diff(&got.data, &want.data);
                assert!(diff < 1e-5, "{isa:?} case {i}: {diff}");
                // The border stays zero.
                let border: f32 = dst.data[..dst.row_stride()].iter().map(|v| v.abs()).sum();
                assert_eq!(border, 0.0);
            }
        }
    }

    #[test]
    fn bf16_variants_stay_within_the_rounding_bound() {
        // The network's stride-2 shapes (7 -> 64 with an odd, padded cin; c -> 2c) at odd
        // sizes, a 1x1 and a stride-1 3x3.
        let cases = [
            (7, 64, 3, 2, 13, 10, Act::Elu),
            (64, 128, 3, 2, 9, 11, Act::Elu),
            (256, 512, 3, 2, 4, 6, Act::Elu),
            (24, 6, 1, 1, 3, 29, Act::LeakyRelu),
            (33, 40, 3, 1, 5, 7, Act::Tanh),
        ];
        for (isa, dot) in bf16::test_variants() {
            for (i, &(cin, cout, k, stride, h, w, act)) in cases.iter().enumerate() {
                let scale = 1.5 / ((cin * k * k) as f32).sqrt();
                let weight = lcg(i as u64 + 11, cout * cin * k * k, scale);
                let bias = lcg(i as u64 + 110, cout, 0.1);
                let input = Planar {
                    channels: cin,
                    height: h,
                    width: w,
                    data: lcg(i as u64 + 210, cin * h * w, 1.0),
                };
                let want = reference::activate(
                    act,
                    reference::conv2d(&input, &weight, &bias, cout, k, stride),
                );
                // |error| <= r(K) sum |x w| (bf16::dot_bound), K = cin k^2: the reference
                // convolution of the magnitudes, without bias.
                let abs = |v: &[f32]| v.iter().map(|x| x.abs()).collect::<Vec<f32>>();
                let magnitude = Planar {
                    data: abs(&input.data),
                    ..input.clone()
                };
                let zero = vec![0.0; cout];
                let sums = reference::conv2d(&magnitude, &abs(&weight), &zero, cout, k, stride);
                let rel = bf16::dot_bound(cin * k * k);
                let run = |dot| {
                    let conv = Conv::new(isa, dot, &weight, &bias, cout, cin, k, stride, act, None);
                    let src = Feature::from_planar(&input, k / 2);
                    let (ho, wo) = conv.out_size(h, w);
                    let mut dst = Feature::zeros(ho, wo, cout, 1);
                    conv.run(&src, &mut dst, &mut Pool::default());
                    dst.to_planar()
                };
                let (got, exact) = (run(dot), run(Dot::F32));
                let mut ratio = 0.0f64;
                for ((g, e), s) in got.data.iter().zip(&want.data).zip(&sums.data) {
                    let err = (f64::from(*g) - f64::from(*e)).abs();
                    ratio = ratio.max(err / (rel * f64::from(*s) + 1e-5));
                }
                assert!(
                    ratio <= 1.0,
                    "{isa:?} {dot:?} case {i}: {ratio:.2} of the bound"
                );
                let moved = reference::max_abs_diff(&got.data, &exact.data);
                assert!(moved > 1e-5, "{isa:?} {dot:?} case {i}: bf16 equals f32");
            }
        }
    }
}
