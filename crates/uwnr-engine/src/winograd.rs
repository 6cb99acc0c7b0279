//! Winograd F(4x4, 3x3) for the stride-1 3x3 convolutions (Lavin and Gray, "Fast Algorithms
//! for Convolutional Neural Networks", CVPR 2016): each 4x4 output tile is
//! `A^T [ (G g G^T) . (B^T d B) ] A` over its 6x6 input tile `d`, so the 144 multiplies per
//! tile and channel pair of the direct method become 36, done as 36 independent GEMMs
//! `M_e = V_e U_e` (`V_e`: tiles x cin, `U_e`: cin x cout) on the same micro-kernels as the
//! direct convolutions. The input and output transforms work on whole channel runs of the
//! channels-last map and vectorise over channels; the bias and activation are applied after
//! the output transform. Interpolation points 0, +-1, +-2, +-1/2 (the matrices below).

use rayon::prelude::*;

use crate::kernels::{Act, Isa, Tile, act, run_tile};
use crate::tensor::{Feature, SharedMut};

/// Output tile side.
const M: usize = 4;
/// Input tile side (`M + 3 - 1`).
const T: usize = 6;
/// Products per tile (`T * T`).
const E: usize = T * T;
/// Below these channel counts the transforms cost more than the products they save.
const MIN_CHANNELS: usize = 16;
/// Bytes of transformed input and products held per chunk of tiles.
const CHUNK_BYTES: usize = 8 << 20;
/// Chunk size bounds, in tiles.
const MIN_CHUNK: usize = 48;
const MAX_CHUNK: usize = 1024;

/// `G` (6x3) of F(4, 3).
const G: [[f64; 3]; T] = [
    [1.0 / 4.0, 0.0, 0.0],
    [-1.0 / 6.0, -1.0 / 6.0, -1.0 / 6.0],
    [-1.0 / 6.0, 1.0 / 6.0, -1.0 / 6.0],
    [1.0 / 24.0, 1.0 / 12.0, 1.0 / 6.0],
    [1.0 / 24.0, -1.0 / 12.0, 1.0 / 6.0],
    [0.0, 0.0, 1.0],
];

/// A stride-1 3x3 convolution with zero padding 1, by Winograd F(4x4, 3x3).
#[derive(Clone, Debug)]
pub(crate) struct Winograd {
    isa: Isa,
    cin: usize,
    cout: usize,
    act: Act,
    /// `[e][panel][cin][NR]`.
    u: Vec<f32>,
    /// `cout` biases in packed order.
    bias: Vec<f32>,
}

impl Winograd {
    /// Whether Winograd pays for a layer of these widths.
    pub fn worthwhile(cin: usize, cout: usize) -> bool {
        cin >= MIN_CHANNELS && cout >= MIN_CHANNELS
    }

    /// Transforms PyTorch-layout weights `[cout][cin][3][3]`; packed output channel `n` is
    /// original channel `order[n]`.
    pub fn new(
        isa: Isa,
        weight: &[f32],
        bias: &[f32],
        cout: usize,
        cin: usize,
        act: Act,
        order: Option<&[usize]>,
    ) -> Self {
        let nr = isa.nr();
        let panels = cout.div_ceil(nr);
        let mut u = vec![0.0f32; E * panels * cin * nr];
        let mut packed_bias = vec![0.0; cout];
        for (n, b) in packed_bias.iter_mut().enumerate() {
            *b = bias[order.map_or(n, |o| o[n])];
        }
        // One (panel, input channel) at a time, so each product's NR columns are written as
        // one contiguous run.
        let mut run = vec![0.0f32; E * nr];
        for p in 0..panels {
            for ci in 0..cin {
                run.fill(0.0);
                for col in 0..nr.min(cout - p * nr) {
                    let n = p * nr + col;
                    let co = order.map_or(n, |o| o[n]);
                    let g = &weight[(co * cin + ci) * 9..(co * cin + ci + 1) * 9];
                    // G g G^T.
                    let mut gg = [[0.0f64; 3]; T];
                    for (i, row) in gg.iter_mut().enumerate() {
                        for (kx, v) in row.iter_mut().enumerate() {
                            *v = (0..3).map(|ky| G[i][ky] * f64::from(g[ky * 3 + kx])).sum();
                        }
                    }
                    for i in 0..T {
                        for j in 0..T {
                            let v: f64 = (0..3).map(|kx| gg[i][kx] * G[j][kx]).sum();
                            run[(i * T + j) * nr + col] = v as f32;
                        }
                    }
                }
                for e in 0..E {
                    let at = (e * panels + p) * cin * nr + ci * nr;
                    u[at..at + nr].copy_from_slice(&run[e * nr..(e + 1) * nr]);
                }
            }
        }
        Self {
            isa,
            cin,
            cout,
            act,
            u,
            bias: packed_bias,
        }
    }

    /// Writes the convolution of `src` (padded by 1) into `dst` (same size, `cout` channels).
    pub fn run(&self, src: &Feature, dst: &mut Feature) {
        debug_assert_eq!(src.pad, 1);
        debug_assert_eq!((src.c, dst.c), (self.cin, self.cout));
        debug_assert_eq!((src.h, src.w), (dst.h, dst.w));
        let (ty, tx) = (src.h.div_ceil(M), src.w.div_ceil(M));
        let tiles = ty * tx;
        let per_tile = E * (self.cin + self.cout) * std::mem::size_of::<f32>();
        let chunk = (CHUNK_BYTES / per_tile)
            .clamp(MIN_CHUNK, MAX_CHUNK)
            .min(tiles);
        let mut v = vec![0.0f32; E * chunk * self.cin];
        let mut m = vec![0.0f32; E * chunk * self.cout];
        let mut start = 0;
        while start < tiles {
            let n = chunk.min(tiles - start);
            self.input_transform(src, tx, start, n, chunk, &mut v);
            self.products(&v, &mut m, n, chunk);
            self.output_transform(&m, dst, tx, start, n, chunk);
            start += n;
        }
    }

    /// `V[e][t][ci]` for tiles `start .. start + n`.
    fn input_transform(
        &self,
        src: &Feature,
        tx: usize,
        start: usize,
        n: usize,
        chunk: usize,
        v: &mut [f32],
    ) {
        let cin = self.cin;
        let vp = SharedMut(v.as_mut_ptr());
        let isa = self.isa;
        (0..n).into_par_iter().for_each_init(
            || Scratch::new(E * cin),
            |sc, t| {
                let Scratch { a: d, b: s } = sc;
                let tile = start + t;
                let (oy, ox) = ((tile / tx) * M, (tile % tx) * M);
                // Padded rows / columns oy .. oy + 6 hold input rows oy - 1 .. oy + 4.
                for r in 0..T {
                    let py = oy + r;
                    let row = &mut d[r * T * cin..(r + 1) * T * cin];
                    if py >= src.h + 2 {
                        row.fill(0.0);
                        continue;
                    }
                    let cols = (src.w + 2 - ox).min(T);
                    let base = py * src.row_stride() + ox * cin;
                    row[..cols * cin].copy_from_slice(&src.data[base..base + cols * cin]);
                    row[cols * cin..].fill(0.0);
                }
                // SAFETY: tile t owns V[e][t][..] for every e; the ISA is supported.
                unsafe { transform_input(isa, d, s, vp, t, chunk, cin) };
            },
        );
    }

    /// `M_e = V_e U_e` for every product `e`, split over (e, panel).
    fn products(&self, v: &[f32], m: &mut [f32], n: usize, chunk: usize) {
        let (cin, cout, isa) = (self.cin, self.cout, self.isa);
        let (nr, mr) = (isa.nr(), isa.mr());
        let panels = cout.div_ceil(nr);
        let zero_bias = [0.0f32; crate::kernels::MAX_NR];
        let mp = SharedMut(m.as_mut_ptr());
        let taps = [0isize];
        (0..E * panels).into_par_iter().for_each(|item| {
            let (e, p) = (item / panels, item % panels);
            let cols = (cout - p * nr).min(nr);
            let mut t = 0;
            while t < n {
                let rows = (n - t).min(mr);
                let tile = Tile {
                    // SAFETY (pointer arithmetic): inside V, U and M by their shapes.
                    a: unsafe { v.as_ptr().add((e * chunk + t) * cin) },
                    lda: cin,
                    taps: &taps,
                    k: cin,
                    b: unsafe { self.u.as_ptr().add((e * panels + p) * cin * nr) },
                    bias: zero_bias.as_ptr(),
                    c: unsafe { mp.get().add((e * chunk + t) * cout + p * nr) },
                    ldc: cout,
                    m: rows,
                    n: cols,
                    act: Act::Identity,
                };
                // SAFETY: reads rows t .. t + rows of V_e and panel p of U_e; writes those rows
                // of M_e in panel p's columns, which no other item writes.
                unsafe { run_tile(isa, &tile) };
                t += rows;
            }
        });
    }

    /// `A^T M A` + bias, activation, into the valid pixels of each output tile.
    fn output_transform(
        &self,
        m: &[f32],
        dst: &mut Feature,
        tx: usize,
        start: usize,
        n: usize,
        chunk: usize,
    ) {
        let cout = self.cout;
        let (h, w) = (dst.h, dst.w);
        let dp = SharedMut(dst.data.as_mut_ptr());
        let row_stride = dst.row_stride();
        let origin = dst.at(0, 0);
        let (isa, act, bias) = (self.isa, self.act, &self.bias[..]);
        (0..n).into_par_iter().for_each_init(
            || Scratch::new(E * cout),
            |sc, t| {
                let tile = start + t;
                let (oy, ox) = ((tile / tx) * M, (tile % tx) * M);
                // SAFETY: reads M[e][t][..]; the ISA is supported.
                unsafe { transform_output(isa, m, t, chunk, cout, bias, act, sc) };
                let o = &sc.b;
                for r in 0..M.min(h - oy) {
                    for s in 0..M.min(w - ox) {
                        let at = origin + (oy + r) * row_stride + (ox + s) * cout;
                        // SAFETY: pixel (oy + r, ox + s) is inside dst and belongs to this tile.
                        unsafe {
                            std::ptr::copy_nonoverlapping(
                                o[(r * M + s) * cout..].as_ptr(),
                                dp.get().add(at),
                                cout,
                            );
                        }
                    }
                }
            },
        );
    }
}

/// Per-thread scratch of the transforms.
struct Scratch {
    a: Vec<f32>,
    b: Vec<f32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Self {
            a: vec![0.0; n],
            b: vec![0.0; n],
        }
    }
}

/// Dispatches the input transform to the ISA's compilation of it.
///
/// # Safety
/// `isa` supported; `v` holds `E * chunk * cin` floats and tile `t < chunk`; no other thread
/// writes tile `t`.
unsafe fn transform_input(
    isa: Isa,
    d: &mut [f32],
    s: &mut [f32],
    v: SharedMut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: forwarded.
        Isa::Avx512 => unsafe { input_avx512(d, s, v, t, chunk, cin) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { input_avx2(d, s, v, t, chunk, cin) },
        _ => unsafe { input_generic(d, s, v, t, chunk, cin) },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn input_avx512(
    d: &mut [f32],
    s: &mut [f32],
    v: SharedMut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    unsafe { input_generic(d, s, v, t, chunk, cin) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn input_avx2(
    d: &mut [f32],
    s: &mut [f32],
    v: SharedMut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    unsafe { input_generic(d, s, v, t, chunk, cin) }
}

/// `y[i] = (B^T x)[i]` for six channel runs `x[0..6]`; `y` is six contiguous runs of `n`.
#[inline(always)]
fn bt6(x: [&[f32]; T], y: &mut [f32], n: usize) {
    let [x0, x1, x2, x3, x4, x5] = x.map(|s| &s[..n]);
    let (y0, rest) = y.split_at_mut(n);
    let (y1, rest) = rest.split_at_mut(n);
    let (y2, rest) = rest.split_at_mut(n);
    let (y3, rest) = rest.split_at_mut(n);
    let (y4, rest) = rest.split_at_mut(n);
    let y5 = &mut rest[..n];
    for c in 0..n {
        let (d0, d1, d2, d3, d4, d5) = (x0[c], x1[c], x2[c], x3[c], x4[c], x5[c]);
        y0[c] = 4.0 * d0 - 5.0 * d2 + d4;
        y1[c] = -4.0 * (d1 + d2) + d3 + d4;
        y2[c] = 4.0 * (d1 - d2) - d3 + d4;
        y3[c] = 2.0 * (d3 - d1) - d2 + d4;
        y4[c] = 2.0 * (d1 - d3) - d2 + d4;
        y5[c] = 4.0 * d1 - 5.0 * d3 + d5;
    }
}

/// `V = B^T d B` of one tile; `d` is `[6 rows][6 cols][cin]`, `s` scratch of `E * cin`.
///
/// # Safety
/// As [`transform_input`].
#[inline(always)]
unsafe fn input_generic(
    d: &mut [f32],
    s: &mut [f32],
    v: SharedMut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    fn run(buf: &[f32], i: usize, n: usize) -> &[f32] {
        &buf[i * n..(i + 1) * n]
    }
    // Down the columns: s[col][i] = sum_r BT[i][r] d[r][col].
    for col in 0..T {
        let d: &[f32] = d;
        let x: [&[f32]; T] = std::array::from_fn(|r| run(d, r * T + col, cin));
        bt6(x, &mut s[col * T * cin..(col + 1) * T * cin], cin);
    }
    // Along the rows: V[i][j] = sum_col BT[j][col] s[col][i], six runs of row i at once.
    // The gathered tile is no longer needed: its first six runs hold one row of V.
    let row = &mut d[..T * cin];
    for i in 0..T {
        let x: [&[f32]; T] = std::array::from_fn(|col| run(s, col * T + i, cin));
        bt6(x, row, cin);
        for j in 0..T {
            // SAFETY: V[i * T + j][t] is this tile's own run.
            unsafe {
                std::ptr::copy_nonoverlapping(
                    row[j * cin..].as_ptr(),
                    v.get().add(((i * T + j) * chunk + t) * cin),
                    cin,
                );
            }
        }
    }
}

/// Dispatches the output transform.
///
/// # Safety
/// `isa` supported; `m` holds `E * chunk * cout` floats, `t < chunk`.
#[allow(clippy::too_many_arguments)]
unsafe fn transform_output(
    isa: Isa,
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
) {
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: forwarded.
        Isa::Avx512 => unsafe { output_avx512(m, t, chunk, cout, bias, a, sc) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { output_avx2(m, t, chunk, cout, bias, a, sc) },
        _ => output_generic(m, t, chunk, cout, bias, a, sc),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn output_avx512(
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
) {
    output_generic(m, t, chunk, cout, bias, a, sc);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn output_avx2(
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
) {
    output_generic(m, t, chunk, cout, bias, a, sc);
}

/// `y[r] = (A^T x)[r]` for six channel runs; `y` is four contiguous runs of `n`.
#[inline(always)]
fn at6(x: [&[f32]; T], y: &mut [f32], n: usize) {
    let [x0, x1, x2, x3, x4, x5] = x.map(|s| &s[..n]);
    let (y0, rest) = y.split_at_mut(n);
    let (y1, rest) = rest.split_at_mut(n);
    let (y2, rest) = rest.split_at_mut(n);
    let y3 = &mut rest[..n];
    for c in 0..n {
        let (m0, m1, m2, m3, m4, m5) = (x0[c], x1[c], x2[c], x3[c], x4[c], x5[c]);
        let (s12, d12, s34, d34) = (m1 + m2, m1 - m2, m3 + m4, m3 - m4);
        y0[c] = m0 + s12 + s34;
        y1[c] = d12 + 2.0 * d34;
        y2[c] = s12 + 4.0 * s34;
        y3[c] = d12 + 8.0 * d34 + m5;
    }
}

/// `sc.b[r][s][c] = act(bias[c] + (A^T M A)[r][s][c])` of one tile.
#[inline(always)]
fn output_generic(
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
) {
    let Scratch { a: tmp, b: o } = sc;
    // Down the columns: tmp[j][r] = sum_i AT[r][i] M[i][j].
    for j in 0..T {
        let x: [&[f32]; T] =
            std::array::from_fn(|i| &m[((i * T + j) * chunk + t) * cout..][..cout]);
        at6(x, &mut tmp[j * M * cout..(j + 1) * M * cout], cout);
    }
    // Along the rows: o[r][s] = sum_j AT[s][j] tmp[j][r].
    for r in 0..M {
        let x: [&[f32]; T] = std::array::from_fn(|j| &tmp[(j * M + r) * cout..][..cout]);
        at6(x, &mut o[r * M * cout..(r + 1) * M * cout], cout);
    }
    for px in o[..M * M * cout].chunks_exact_mut(cout) {
        for (v, b) in px.iter_mut().zip(bias) {
            *v += b;
        }
        act::apply(a, px);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference;
    use crate::tensor::Planar;

    fn values(seed: u64, n: usize, scale: f32) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0 * scale
            })
            .collect()
    }

    #[test]
    fn every_isa_matches_the_reference() {
        // Sizes that are not multiples of 4 (partial tiles) and channel counts around the
        // panel widths; a permuted channel order as the decoder uses.
        let cases = [
            (16, 16, 8, 8),
            (24, 40, 5, 13),
            (32, 16, 1, 2),
            (16, 48, 9, 4),
        ];
        for isa in Isa::supported() {
            for (i, &(cin, cout, h, w)) in cases.iter().enumerate() {
                let weight = values(i as u64 + 1, cout * cin * 9, 0.3);
                let bias = values(i as u64 + 50, cout, 0.5);
                let input = Planar {
                    channels: cin,
                    height: h,
                    width: w,
                    data: values(i as u64 + 90, cin * h * w, 1.0),
                };
                let order: Vec<usize> = (0..cout).rev().collect();
                let want = reference::activate(
                    Act::Elu,
                    reference::conv2d(&input, &weight, &bias, cout, 3, 1),
                );
                let conv = Winograd::new(isa, &weight, &bias, cout, cin, Act::Elu, Some(&order));
                let src = Feature::from_planar(&input, 1);
                let mut dst = Feature::zeros(h, w, cout, 1);
                conv.run(&src, &mut dst);
                let got = dst.to_planar();
                let mut diff = 0.0f32;
                for (n, &o) in order.iter().enumerate() {
                    let plane = h * w;
                    let g = &got.data[n * plane..(n + 1) * plane];
                    let e = &want.data[o * plane..(o + 1) * plane];
                    diff = diff.max(reference::max_abs_diff(g, e));
                }
                assert!(diff < 2e-5, "{isa:?} case {i}: {diff}");
            }
        }
    }
}
