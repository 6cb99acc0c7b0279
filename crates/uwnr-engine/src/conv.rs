//! Direct convolutions on channels-last maps: 3x3 (stride 1 or 2, zero padding 1) and 1x1,
//! with the bias and activation fused into the store.
//!
//! Output pixel `(y, x)` of a 3x3 convolution with stride `s` reads padded input pixels
//! `(s y + ky, s x + kx)`, `ky, kx < 3`: for a run of `MR` pixels of one output row, each tap
//! is a `MR x cin` block of the input with rows `s cin` floats apart, so the nine taps are
//! nine `(offset, weight panel)` pairs of one micro-kernel call and nothing is copied. Work is
//! split over (output row, panel of `NR` output channels) so both cores stay busy from the
//! 128-row first level down to the 16-row bottleneck.

use rayon::prelude::*;

use crate::kernels::{Act, Isa, Tile, run_tile};
use crate::tensor::{Feature, SharedMut};

/// A convolution packed for one instruction set.
#[derive(Clone, Debug)]
pub(crate) struct Conv {
    pub isa: Isa,
    pub cin: usize,
    pub cout: usize,
    /// 1 or 3.
    pub k: usize,
    /// 1 or 2.
    pub stride: usize,
    pub act: Act,
    /// `[panel][tap][cin][NR]`.
    panels: Vec<f32>,
    /// `[panel][NR]`.
    bias: Vec<f32>,
}

impl Conv {
    /// Packs PyTorch-layout weights `[cout][cin][k][k]`. Packed output channel `n` takes the
    /// weights of original channel `order[n]` (identity when `order` is `None`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        isa: Isa,
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
        Self {
            isa,
            cin,
            cout,
            k,
            stride,
            act,
            panels,
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
    /// needs `src.pad == 1`.
    pub fn run(&self, src: &Feature, dst: &mut Feature) {
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
                let conv = Conv::new(isa, &weight, &bias, cout, cin, k, stride, act, None);
                let src = Feature::from_planar(&input, k / 2);
                let (ho, wo) = conv.out_size(h, w);
                let mut dst = Feature::zeros(ho, wo, cout, 1);
                conv.run(&src, &mut dst);
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
}
