//! Winograd F(4x4, 3x3) for the stride-1 3x3 convolutions (Lavin and Gray, "Fast Algorithms
//! for Convolutional Neural Networks", CVPR 2016): each 4x4 output tile is
//! `A^T [ (G g G^T) . (B^T d B) ] A` over its 6x6 input tile `d`, so the 144 multiplies per
//! tile and channel pair of the direct method become 36, done as 36 independent GEMMs
//! `M_e = V_e U_e` (`V_e`: tiles x cin, `U_e`: cin x cout) on the same micro-kernels as the
//! direct convolutions. The input and output transforms work on whole channel runs of the
//! channels-last map and vectorise over channels; the bias and activation are applied after
//! the output transform. Interpolation points 0, +-1, +-2, +-1/2 (the matrices below).
//! F(2x2, 3x3) (points 0, +-1: 16 products per 2x2 tile) runs on the same code with 4x4 input
//! tiles. Transforms read tiles inside the map where they lie and write `V` and the output
//! pixels in place; a chunk of tiles is sized so that large transformed weights stream from
//! memory once per layer.
//!
//! With bf16 products ([`Dot`]), `U` is rounded once when the layer is packed and each run of
//! `V` when the input transform writes it (in pairs along `cin`, see
//! [`crate::kernels::bf16`]); the transforms, the sums and the output transform stay f32.
//!
//! Why one file of about 970 lines: the two tile sizes, the f32 and bf16 paths and their
//! input and output transforms share the tile geometry, the chunking and the in-place writes
//! through [`SharedMut`]; split apart, each part would re-derive those invariants (which tile
//! reads which pixels, which chunk writes which rows) that the unsafe writes rely on.

use rayon::prelude::*;

use crate::kernels::bf16::{self, padded};
use crate::kernels::{Act, Dot, Isa, Tile, act, run_tile, run_tile_bf16};
use crate::tensor::{Feature, Pool, SharedMut};

/// Below these channel counts the transforms cost more than the products they save.
const MIN_CHANNELS: usize = 16;
/// Bytes of transformed input and products held per chunk of tiles, at least: small enough
/// for the caches when the transformed weights are small.
const CHUNK_BYTES: usize = 8 << 20;
/// At most: a layer whose transformed weights `U` are large streams them from memory once per
/// chunk, so its chunk grows with `U` (twice its size) up to this.
const MAX_CHUNK_BYTES: usize = 64 << 20;
/// Reduction block of the products: `KC x NR` weights (32 KiB for AVX-512) stay in L1.
const KC: usize = 192;
/// The same for bf16 weights (half the bytes per value; even).
const KC_BF16: usize = 2 * KC;
/// Layers whose transformed weights are at most this large (the 64- and 32-channel layers of
/// the shipped networks) run [`Winograd::run_local`]: the weights stay in each core's L2 while
/// its own chunks pass through.
const LOCAL_MAX_U_BYTES: usize = 1280 << 10;
/// Transformed input and products of one such chunk, at most: with the weights, within a
/// 2 MiB L2.
const LOCAL_CHUNK_BYTES: usize = 1 << 20;
/// The local pipeline needs this many chunks to keep every core busy; fewer tiles take the
/// shared path.
const LOCAL_MIN_CHUNKS: usize = 8;
/// Chunk size bounds, in tiles.
const MIN_CHUNK: usize = 48;
const MAX_CHUNK: usize = 4096;

/// `G` (6x3) of F(4, 3).
const G4: [[f64; 3]; 6] = [
    [1.0 / 4.0, 0.0, 0.0],
    [-1.0 / 6.0, -1.0 / 6.0, -1.0 / 6.0],
    [-1.0 / 6.0, 1.0 / 6.0, -1.0 / 6.0],
    [1.0 / 24.0, 1.0 / 12.0, 1.0 / 6.0],
    [1.0 / 24.0, -1.0 / 12.0, 1.0 / 6.0],
    [0.0, 0.0, 1.0],
];

/// `G` (4x3) of F(2, 3), interpolation points 0, +-1.
const G2: [[f64; 3]; 4] = [
    [1.0, 0.0, 0.0],
    [0.5, 0.5, 0.5],
    [0.5, -0.5, 0.5],
    [0.0, 0.0, 1.0],
];

/// The output tile of a Winograd convolution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum WinoTile {
    /// F(4x4, 3x3): 36 products per 16 outputs (4x fewer multiplies than direct), transformed
    /// weights 4x the size of the kernel.
    F4,
    /// F(2x2, 3x3): 16 products per 4 outputs (2.25x fewer), weights 16/9 the size: for deep,
    /// small layers, where streaming the transformed weights costs more than the products.
    F2,
}

impl WinoTile {
    /// Output tile side.
    pub fn m(self) -> usize {
        match self {
            Self::F4 => 4,
            Self::F2 => 2,
        }
    }

    /// Input tile side.
    pub fn t(self) -> usize {
        self.m() + 2
    }

    fn g(self, i: usize, k: usize) -> f64 {
        match self {
            Self::F4 => G4[i][k],
            Self::F2 => G2[i][k],
        }
    }
}

/// A stride-1 3x3 convolution with zero padding 1, by Winograd F(4x4, 3x3) or F(2x2, 3x3).
#[derive(Clone, Debug)]
pub(crate) struct Winograd {
    isa: Isa,
    dot: Dot,
    tile: WinoTile,
    cin: usize,
    cout: usize,
    act: Act,
    /// `[e][panel][cin][NR]` (empty for bf16 products).
    u: Vec<f32>,
    /// `[e][panel][padded(cin) / 2][NR][2]` bf16 (empty for f32 products).
    u_bf16: Vec<u16>,
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
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        isa: Isa,
        dot: Dot,
        tile: WinoTile,
        weight: &[f32],
        bias: &[f32],
        cout: usize,
        cin: usize,
        act: Act,
        order: Option<&[usize]>,
    ) -> Self {
        let nr = isa.nr();
        let panels = cout.div_ceil(nr);
        let t = tile.t();
        let e_n = t * t;
        let mut u = vec![0.0f32; e_n * panels * cin * nr];
        let mut packed_bias = vec![0.0; cout];
        for (n, b) in packed_bias.iter_mut().enumerate() {
            *b = bias[order.map_or(n, |o| o[n])];
        }
        // One (panel, input channel) at a time, so each product's NR columns are written as
        // one contiguous run.
        let mut run = vec![0.0f32; e_n * nr];
        for p in 0..panels {
            for ci in 0..cin {
                run.fill(0.0);
                for col in 0..nr.min(cout - p * nr) {
                    let n = p * nr + col;
                    let co = order.map_or(n, |o| o[n]);
                    let g = &weight[(co * cin + ci) * 9..(co * cin + ci + 1) * 9];
                    // G g G^T.
                    let mut gg = [[0.0f64; 3]; 6];
                    for (i, row) in gg.iter_mut().enumerate().take(t) {
                        for (kx, v) in row.iter_mut().enumerate() {
                            *v = (0..3)
                                .map(|ky| tile.g(i, ky) * f64::from(g[ky * 3 + kx]))
                                .sum();
                        }
                    }
                    for i in 0..t {
                        for j in 0..t {
                            let v: f64 = (0..3).map(|kx| gg[i][kx] * tile.g(j, kx)).sum();
                            run[(i * t + j) * nr + col] = v as f32;
                        }
                    }
                }
                for e in 0..e_n {
                    let at = (e * panels + p) * cin * nr + ci * nr;
                    u[at..at + nr].copy_from_slice(&run[e * nr..(e + 1) * nr]);
                }
            }
        }
        let mut u_bf16 = Vec::new();
        if dot.is_bf16() {
            u_bf16.reserve(e_n * panels * padded(cin) * nr);
            for panel in u.chunks_exact(cin * nr) {
                u_bf16.extend(bf16::pack_pairs(panel, cin, nr));
            }
            u = Vec::new();
        }
        Self {
            isa,
            dot,
            tile,
            cin,
            cout,
            act,
            u,
            u_bf16,
            bias: packed_bias,
        }
    }

    /// Writes the convolution of `src` (padded by 1) into `dst` (same size, `cout` channels);
    /// the transformed input and the products live in buffers of `pool`.
    pub fn run(&self, src: &Feature, dst: &mut Feature, pool: &mut Pool) {
        self.run_scheduled(src, dst, pool, Schedule::Auto);
    }

    /// [`Self::run`] on a given schedule.
    fn run_scheduled(&self, src: &Feature, dst: &mut Feature, pool: &mut Pool, schedule: Schedule) {
        match self.tile {
            WinoTile::F4 => self.run_with::<4, 6>(src, dst, pool, schedule),
            WinoTile::F2 => self.run_with::<2, 4>(src, dst, pool, schedule),
        }
    }

    /// [`Self::run`] for output tiles of `M` (input tiles of `T = M + 2`).
    fn run_with<const M: usize, const T: usize>(
        &self,
        src: &Feature,
        dst: &mut Feature,
        pool: &mut Pool,
        schedule: Schedule,
    ) {
        const { assert!(T == M + 2) };
        let e_n = T * T;
        debug_assert_eq!(src.pad, 1);
        debug_assert_eq!((src.c, dst.c), (self.cin, self.cout));
        debug_assert_eq!((src.h, src.w), (dst.h, dst.w));
        let (ty, tx) = (src.h.div_ceil(M), src.w.div_ceil(M));
        let tiles = ty * tx;
        let bf = self.dot.is_bf16();
        // Values of V per tile and product, and bytes per value of V and U.
        let (kv, elem) = if bf {
            (padded(self.cin), std::mem::size_of::<u16>())
        } else {
            (self.cin, std::mem::size_of::<f32>())
        };
        let per_tile = e_n * (kv * elem + self.cout * std::mem::size_of::<f32>());
        let u_bytes = (self.u.len() + self.u_bf16.len()) * elem;
        match schedule {
            Schedule::Auto if u_bytes <= LOCAL_MAX_U_BYTES => {
                let mr = self.isa.mr();
                let chunk = (LOCAL_CHUNK_BYTES / per_tile / mr).max(1) * mr;
                if tiles >= LOCAL_MIN_CHUNKS * chunk {
                    self.run_local::<M, T>(src, dst, chunk);
                    return;
                }
            }
            Schedule::Local { chunk } => {
                self.run_local::<M, T>(src, dst, chunk.max(1));
                return;
            }
            Schedule::Auto | Schedule::Shared => {}
        }
        let budget = (2 * u_bytes).clamp(CHUNK_BYTES, MAX_CHUNK_BYTES);
        let chunk = (budget / per_tile).clamp(MIN_CHUNK, MAX_CHUNK).min(tiles);
        // Every run of V and M a product reads is written first, so stale buffers do. A bf16
        // V lives in an f32 buffer of half the length.
        let v_len = e_n * chunk * kv;
        let mut v = pool.take_stale(if bf { v_len.div_ceil(2) } else { v_len });
        let mut m = pool.take_stale(e_n * chunk * self.cout);
        let mut start = 0;
        while start < tiles {
            let n = chunk.min(tiles - start);
            let out = self.v_out(&mut v);
            self.input_transform::<M, T>(src, tx, start, n, chunk, out);
            self.products(e_n, &v, &mut m, n, chunk);
            self.output_transform::<M, T>(&m, dst, tx, start, n, chunk);
            start += n;
        }
        pool.give_vec(v);
        pool.give_vec(m);
    }

    /// Where the input transform writes `V` in the buffer `v`: f32 runs, or bf16 runs (in the
    /// rounding this CPU has) in an f32 buffer of half the length.
    fn v_out(&self, v: &mut [f32]) -> VOut {
        if self.dot.is_bf16() {
            VOut::Bf16 {
                v: SharedMut(v.as_mut_ptr().cast::<u16>()),
                native: self.dot == Dot::Bf16Native,
            }
        } else {
            VOut::F32(SharedMut(v.as_mut_ptr()))
        }
    }

    /// `V[e][t][ci]` for tiles `start .. start + n`, into `out` (a buffer of
    /// `E * chunk` runs of `cin` floats, or of `padded(cin)` bf16 values).
    fn input_transform<const M: usize, const T: usize>(
        &self,
        src: &Feature,
        tx: usize,
        start: usize,
        n: usize,
        chunk: usize,
        out: VOut,
    ) {
        (0..n).into_par_iter().for_each_init(
            || Scratch::new(T * T * self.cin, (T * T + T) * self.cin),
            // SAFETY: tile t owns V[e][t][..] for every e.
            |sc, t| unsafe { self.input_tile::<M, T>(src, tx, start + t, t, chunk, out, sc) },
        );
    }

    /// The input transform of map tile `tile` into slot `t` of `out`.
    ///
    /// # Safety
    /// `t < chunk`, `out` holds `E * chunk` runs, and no other thread writes slot `t` of
    /// `out` meanwhile.
    #[allow(clippy::too_many_arguments)]
    unsafe fn input_tile<const M: usize, const T: usize>(
        &self,
        src: &Feature,
        tx: usize,
        tile: usize,
        t: usize,
        chunk: usize,
        out: VOut,
        sc: &mut Scratch,
    ) {
        let cin = self.cin;
        let stride = src.row_stride();
        let Scratch { a: d, b: s } = sc;
        let (oy, ox) = ((tile / tx) * M, (tile % tx) * M);
        // Padded rows / columns oy .. oy + 6 hold input rows oy - 1 .. oy + 4. A tile inside
        // the padded map is read where it lies; one over its edge is gathered into `d` with
        // zeros beyond.
        let (rows, cols) = ((src.h + 2 - oy).min(T), (src.w + 2 - ox).min(T));
        let (tile_src, tile_stride): (&[f32], usize) = if rows == T && cols == T {
            (&src.data[oy * stride + ox * cin..], stride)
        } else {
            for r in 0..T {
                let row = &mut d[r * T * cin..(r + 1) * T * cin];
                if r >= rows {
                    row.fill(0.0);
                    continue;
                }
                let base = (oy + r) * stride + ox * cin;
                row[..cols * cin].copy_from_slice(&src.data[base..base + cols * cin]);
                row[cols * cin..].fill(0.0);
            }
            (&d[..], T * cin)
        };
        // SAFETY: slot t is the caller's; the ISA is supported, and the CPU has AVX512_BF16
        // if `out` asks for its rounding.
        unsafe {
            transform_input::<T>(self.isa, tile_src, tile_stride, s, out, t, chunk, cin);
        }
    }

    /// `M_e = V_e U_e` for every product `e`, split over (e, panel); `v` is `[e][t][cin]`
    /// f32 or `[e][t][padded(cin)]` bf16 (in an f32 buffer of half the length).
    fn products(&self, e_n: usize, v: &[f32], m: &mut [f32], n: usize, chunk: usize) {
        let panels = self.cout.div_ceil(self.isa.nr());
        let (vp, mp) = (SharedConst(v.as_ptr()), SharedMut(m.as_mut_ptr()));
        (0..e_n * panels).into_par_iter().for_each(|item| {
            // SAFETY: V and M hold E * chunk runs; each (e, panel) writes its own columns of
            // M_e.
            unsafe { self.product(item / panels, item % panels, vp.get(), mp.get(), n, chunk) };
        });
    }

    /// Rows `0 .. n` of `M_e` in panel `p`'s `NR` columns, from `V_e` and panel `p` of `U_e`.
    ///
    /// # Safety
    /// `v` and `m` hold `E * chunk` runs (of `cin` f32 or `padded(cin)` bf16 values, and of
    /// `cout` floats); no other thread writes rows `0 .. n` of `M_e` in panel `p`'s columns
    /// meanwhile.
    unsafe fn product(
        &self,
        e: usize,
        p: usize,
        v: *const f32,
        m: *mut f32,
        n: usize,
        chunk: usize,
    ) {
        let (cout, isa) = (self.cout, self.isa);
        let (nr, mr) = (isa.nr(), isa.mr());
        let panels = cout.div_ceil(nr);
        let cols = (cout - p * nr).min(nr);
        let zero_bias = [0.0f32; crate::kernels::MAX_NR];
        let taps = [0isize];
        let bf = self.dot.is_bf16();
        let (kv, kc_max) = if bf {
            (padded(self.cin), KC_BF16)
        } else {
            (self.cin, KC)
        };
        // Blocks of the reduction small enough that the panel's KC x NR weights stay in L1
        // while every row tile of the chunk passes over them.
        let mut kb = 0;
        while kb < kv {
            let kc = kc_max.min(kv - kb);
            let mut t = 0;
            while t < n {
                let rows = (n - t).min(mr);
                let a_at = (e * chunk + t) * kv + kb;
                let b_at = ((e * panels + p) * kv + kb) * nr;
                // SAFETY (pointer arithmetic and the kernels): inside V, U and M by their
                // shapes (for bf16, kb is even, so `kb * nr` starts pair kb / 2 of the
                // `[k / 2][NR][2]` panel); reads rows t .. t + rows of V_e (columns kb .. kb +
                // kc) and that block of panel p of U_e; writes those rows of M_e in panel p's
                // columns, the caller's; the kernel is one this CPU runs.
                unsafe {
                    // The f32 operands' pointers are only formed (wrapping) for a bf16
                    // product, whose own operands replace them.
                    let tile = Tile {
                        a: v.wrapping_add(a_at),
                        lda: kv,
                        taps: &taps,
                        k: kc,
                        b: self.u.as_ptr().wrapping_add(b_at),
                        bias: zero_bias.as_ptr(),
                        c: m.add((e * chunk + t) * cout + p * nr),
                        ldc: cout,
                        m: rows,
                        n: cols,
                        act: Act::Identity,
                        accumulate: kb > 0,
                    };
                    if bf {
                        let bf_tile = tile.with_operands(
                            v.cast::<u16>().add(a_at),
                            self.u_bf16.as_ptr().add(b_at),
                        );
                        run_tile_bf16(isa, self.dot, &bf_tile);
                    } else {
                        run_tile(isa, &tile);
                    }
                }
                t += rows;
            }
            kb += kc;
        }
    }

    /// `A^T M A` + bias, activation, into the valid pixels of each output tile.
    fn output_transform<const M: usize, const T: usize>(
        &self,
        m: &[f32],
        dst: &mut Feature,
        tx: usize,
        start: usize,
        n: usize,
        chunk: usize,
    ) {
        let target = OutMap::new(dst);
        (0..n).into_par_iter().for_each_init(
            || Scratch::new(T * T * self.cout, T * T * self.cout),
            // SAFETY: tile start + t writes only its own pixels.
            |sc, t| unsafe { self.output_tile::<M, T>(m, &target, tx, start + t, t, chunk, sc) },
        );
    }

    /// The output transform of slot `t` of `m` into map tile `tile` of `target`.
    ///
    /// # Safety
    /// `t < chunk`, `m` holds `E * chunk` runs of `cout`; no other thread writes the tile's
    /// pixels meanwhile.
    #[allow(clippy::too_many_arguments)]
    unsafe fn output_tile<const M: usize, const T: usize>(
        &self,
        m: &[f32],
        target: &OutMap,
        tx: usize,
        tile: usize,
        t: usize,
        chunk: usize,
        sc: &mut Scratch,
    ) {
        let (oy, ox) = ((tile / tx) * M, (tile % tx) * M);
        let out = OutTile {
            dst: target.dst,
            at: target.origin + oy * target.row_stride + ox * self.cout,
            row_stride: target.row_stride,
            rows: M.min(target.h - oy),
            cols: M.min(target.w - ox),
        };
        // SAFETY: reads M[e][t][..]; writes the tile's own valid pixels of dst; the ISA is
        // supported.
        unsafe {
            transform_output::<M, T>(
                self.isa, m, t, chunk, self.cout, &self.bias, self.act, sc, &out,
            );
        }
    }

    /// [`Self::run_with`] for layers whose transformed weights fit in a core's cache: each
    /// thread takes chunks of `chunk` tiles through all three stages on its own, so the
    /// transformed input and the products stay in its cache between the stages.
    fn run_local<const M: usize, const T: usize>(
        &self,
        src: &Feature,
        dst: &mut Feature,
        chunk: usize,
    ) {
        let e_n = T * T;
        let tx = src.w.div_ceil(M);
        let tiles = src.h.div_ceil(M) * tx;
        let bf = self.dot.is_bf16();
        let kv = if bf { padded(self.cin) } else { self.cin };
        let v_len = e_n * chunk * kv;
        let v_floats = if bf { v_len.div_ceil(2) } else { v_len };
        let m_len = e_n * chunk * self.cout;
        let panels = self.cout.div_ceil(self.isa.nr());
        let target = OutMap::new(dst);
        let width = (T * T + T) * self.cin.max(self.cout);
        (0..tiles.div_ceil(chunk))
            .into_par_iter()
            .with_min_len(2)
            .for_each_init(
                || {
                    (
                        vec![0.0f32; v_floats],
                        vec![0.0f32; m_len],
                        Scratch::new(width, width),
                    )
                },
                |(v, m, sc), c| {
                    let start = c * chunk;
                    let n = chunk.min(tiles - start);
                    let out = self.v_out(v);
                    // SAFETY: V and M are this thread's own buffers of E * chunk runs; the
                    // chunk's tiles write only their own pixels of dst.
                    unsafe {
                        for t in 0..n {
                            self.input_tile::<M, T>(src, tx, start + t, t, chunk, out, sc);
                        }
                        for e in 0..e_n {
                            for p in 0..panels {
                                self.product(e, p, v.as_ptr(), m.as_mut_ptr(), n, chunk);
                            }
                        }
                        for t in 0..n {
                            self.output_tile::<M, T>(m, &target, tx, start + t, t, chunk, sc);
                        }
                    }
                },
            );
    }
}

/// The pixels of an output map, shared by the threads that write its tiles.
struct OutMap {
    dst: SharedMut,
    origin: usize,
    row_stride: usize,
    h: usize,
    w: usize,
}

impl OutMap {
    fn new(dst: &mut Feature) -> Self {
        Self {
            origin: dst.at(0, 0),
            row_stride: dst.row_stride(),
            h: dst.h,
            w: dst.w,
            dst: SharedMut(dst.data.as_mut_ptr()),
        }
    }
}

/// A read-only pointer shared between the threads that read disjoint or read-only data.
#[derive(Clone, Copy)]
struct SharedConst(*const f32);

impl SharedConst {
    /// The pointer (a method, so closures capture the whole `Sync` wrapper).
    fn get(self) -> *const f32 {
        self.0
    }
}

// SAFETY: only read, while the buffer it points into is borrowed by the caller.
unsafe impl Send for SharedConst {}
// SAFETY: as above.
unsafe impl Sync for SharedConst {}

/// How a layer's tiles pass through the three stages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Schedule {
    /// [`Schedule::Local`] where the transformed weights fit in a core's cache and there are
    /// enough tiles, [`Schedule::Shared`] elsewhere.
    Auto,
    /// Each stage over a large chunk of tiles in parallel, the threads sharing the chunk's
    /// buffers (the weights stream from memory once per chunk).
    #[cfg_attr(not(test), allow(dead_code))]
    Shared,
    /// Each thread takes its own chunks of this many tiles through all three stages.
    #[cfg_attr(not(test), allow(dead_code))]
    Local { chunk: usize },
}

/// Where one output tile's valid pixels go.
struct OutTile {
    dst: SharedMut,
    /// Index of the tile's pixel (0, 0).
    at: usize,
    row_stride: usize,
    rows: usize,
    cols: usize,
}

/// Where the input transform writes `V`.
#[derive(Clone, Copy)]
enum VOut {
    /// `[e][t][cin]` f32.
    F32(SharedMut),
    /// `[e][t][padded(cin)]` bf16, rounded with `vcvtne2ps2bf16` if `native`.
    Bf16 { v: SharedMut<u16>, native: bool },
}

/// Per-thread scratch of the transforms.
struct Scratch {
    a: Vec<f32>,
    b: Vec<f32>,
}

impl Scratch {
    fn new(a: usize, b: usize) -> Self {
        Self {
            a: vec![0.0; a],
            b: vec![0.0; b],
        }
    }
}

/// Dispatches the input transform to the ISA's compilation of it.
///
/// # Safety
/// `isa` supported; `d` holds the tile's 6 rows, `stride` floats apart, of 6 pixels of `cin`;
/// `v` holds `E * chunk * cin` floats and tile `t < chunk`; no other thread writes tile `t`.
#[allow(clippy::too_many_arguments)]
unsafe fn transform_input<const T: usize>(
    isa: Isa,
    d: &[f32],
    stride: usize,
    s: &mut [f32],
    v: VOut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: forwarded.
        Isa::Avx512 => unsafe { input_avx512::<T>(d, stride, s, v, t, chunk, cin) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { input_avx2::<T>(d, stride, s, v, t, chunk, cin) },
        _ => unsafe { input_generic::<T>(d, stride, s, v, t, chunk, cin) },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn input_avx512<const T: usize>(
    d: &[f32],
    stride: usize,
    s: &mut [f32],
    v: VOut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    unsafe { input_generic::<T>(d, stride, s, v, t, chunk, cin) }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn input_avx2<const T: usize>(
    d: &[f32],
    stride: usize,
    s: &mut [f32],
    v: VOut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    unsafe { input_generic::<T>(d, stride, s, v, t, chunk, cin) }
}

/// `y = B^T x` over `T` channel runs of `n`: [`bt6`] or [`bt4`].
#[inline(always)]
fn bt<const T: usize>(x: [&[f32]; T], y: [&mut [f32]; T], n: usize) {
    let mut xs = x.into_iter();
    let mut ys = y.into_iter();
    if T == 6 {
        bt6(
            std::array::from_fn(|_| xs.next().expect("T runs")),
            std::array::from_fn(|_| ys.next().expect("T runs")),
            n,
        );
    } else {
        bt4(
            std::array::from_fn(|_| xs.next().expect("T runs")),
            std::array::from_fn(|_| ys.next().expect("T runs")),
            n,
        );
    }
}

/// `y[i] = (B^T x)[i]` of F(2, 3) for four channel runs.
#[inline(always)]
fn bt4(x: [&[f32]; 4], y: [&mut [f32]; 4], n: usize) {
    let [x0, x1, x2, x3] = x.map(|s| &s[..n]);
    let [y0, y1, y2, y3] = y.map(|s| &mut s[..n]);
    for c in 0..n {
        let (d0, d1, d2, d3) = (x0[c], x1[c], x2[c], x3[c]);
        y0[c] = d0 - d2;
        y1[c] = d1 + d2;
        y2[c] = d2 - d1;
        y3[c] = d1 - d3;
    }
}

/// `y[i] = (B^T x)[i]` of F(4, 3) for six channel runs `x[0..6]` of `n` into six runs.
#[inline(always)]
fn bt6(x: [&[f32]; 6], y: [&mut [f32]; 6], n: usize) {
    let [x0, x1, x2, x3, x4, x5] = x.map(|s| &s[..n]);
    let [y0, y1, y2, y3, y4, y5] = y.map(|s| &mut s[..n]);
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

/// `V = B^T d B` of one tile, written straight into its runs of `V`; `s` is scratch of
/// `E * cin` and `T * cin` more (a row of runs before their rounding to bf16).
///
/// # Safety
/// As [`transform_input`].
#[inline(always)]
unsafe fn input_generic<const T: usize>(
    d: &[f32],
    stride: usize,
    s: &mut [f32],
    v: VOut,
    t: usize,
    chunk: usize,
    cin: usize,
) {
    // Down the columns: s[col][i] = sum_r BT[i][r] d[r][col].
    for (col, sc) in s.chunks_exact_mut(T * cin).take(T).enumerate() {
        let x: [&[f32]; T] = std::array::from_fn(|r| &d[r * stride + col * cin..][..cin]);
        let mut runs = sc.chunks_exact_mut(cin);
        let y: [&mut [f32]; T] = std::array::from_fn(|_| runs.next().expect("T runs"));
        bt::<T>(x, y, cin);
    }
    // Along the rows: V[i][j] = sum_col BT[j][col] s[col][i].
    let (s, row) = s.split_at_mut(T * T * cin);
    let s: &[f32] = s;
    for i in 0..T {
        let x: [&[f32]; T] = std::array::from_fn(|col| &s[(col * T + i) * cin..][..cin]);
        match v {
            VOut::F32(v) => {
                // SAFETY: V[i * T + j][t] (j < T) are this tile's own runs of cin floats.
                let y: [&mut [f32]; T] = std::array::from_fn(|j| unsafe {
                    std::slice::from_raw_parts_mut(
                        v.get().add(((i * T + j) * chunk + t) * cin),
                        cin,
                    )
                });
                bt::<T>(x, y, cin);
            }
            VOut::Bf16 { v, native } => {
                // One row of T runs in f32 scratch, then rounded into V.
                let mut runs = row.chunks_exact_mut(cin);
                let y: [&mut [f32]; T] = std::array::from_fn(|_| runs.next().expect("T runs"));
                bt::<T>(x, y, cin);
                let kp = padded(cin);
                for (j, run) in row.chunks_exact(cin).take(T).enumerate() {
                    // SAFETY: V[i * T + j][t] is this tile's own run of padded(cin) values;
                    // `native` only where the CPU has AVX512_BF16.
                    unsafe {
                        let dst = std::slice::from_raw_parts_mut(
                            v.get().add(((i * T + j) * chunk + t) * kp),
                            kp,
                        );
                        bf16::round_run(native, run, dst);
                    }
                }
            }
        }
    }
}

/// Dispatches the output transform.
///
/// # Safety
/// `isa` supported; `m` holds `E * chunk * cout` floats, `t < chunk`; `out` names pixels of a
/// map of `cout` channels that only this tile writes.
#[allow(clippy::too_many_arguments)]
unsafe fn transform_output<const M: usize, const T: usize>(
    isa: Isa,
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
    out: &OutTile,
) {
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: forwarded.
        Isa::Avx512 => unsafe { output_avx512::<M, T>(m, t, chunk, cout, bias, a, sc, out) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { output_avx2::<M, T>(m, t, chunk, cout, bias, a, sc, out) },
        _ => unsafe { output_generic::<M, T>(m, t, chunk, cout, bias, a, sc, out) },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[allow(clippy::too_many_arguments)]
unsafe fn output_avx512<const M: usize, const T: usize>(
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
    out: &OutTile,
) {
    unsafe { output_generic::<M, T>(m, t, chunk, cout, bias, a, sc, out) };
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn output_avx2<const M: usize, const T: usize>(
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
    out: &OutTile,
) {
    unsafe { output_generic::<M, T>(m, t, chunk, cout, bias, a, sc, out) };
}

/// `y = A^T x` from `T` channel runs into `M`: [`at6`] or [`at4`].
#[inline(always)]
fn at<const M: usize, const T: usize>(x: [&[f32]; T], y: [&mut [f32]; M], n: usize) {
    let mut xs = x.into_iter();
    let mut ys = y.into_iter();
    if T == 6 {
        at6(
            std::array::from_fn(|_| xs.next().expect("T runs")),
            std::array::from_fn(|_| ys.next().expect("M runs")),
            n,
        );
    } else {
        at4(
            std::array::from_fn(|_| xs.next().expect("T runs")),
            std::array::from_fn(|_| ys.next().expect("M runs")),
            n,
        );
    }
}

/// `y[r] = (A^T x)[r]` of F(2, 3) for four channel runs into two.
#[inline(always)]
fn at4(x: [&[f32]; 4], y: [&mut [f32]; 2], n: usize) {
    let [x0, x1, x2, x3] = x.map(|s| &s[..n]);
    let [y0, y1] = y.map(|s| &mut s[..n]);
    for c in 0..n {
        let (m0, m1, m2, m3) = (x0[c], x1[c], x2[c], x3[c]);
        y0[c] = m0 + m1 + m2;
        y1[c] = m1 - m2 - m3;
    }
}

/// `y[r] = (A^T x)[r]` of F(4, 3) for six channel runs into four runs.
#[inline(always)]
fn at6(x: [&[f32]; 6], y: [&mut [f32]; 4], n: usize) {
    let [x0, x1, x2, x3, x4, x5] = x.map(|s| &s[..n]);
    let [y0, y1, y2, y3] = y.map(|s| &mut s[..n]);
    for c in 0..n {
        let (m0, m1, m2, m3, m4, m5) = (x0[c], x1[c], x2[c], x3[c], x4[c], x5[c]);
        let (s12, d12, s34, d34) = (m1 + m2, m1 - m2, m3 + m4, m3 - m4);
        y0[c] = m0 + s12 + s34;
        y1[c] = d12 + 2.0 * d34;
        y2[c] = s12 + 4.0 * s34;
        y3[c] = d12 + 8.0 * d34 + m5;
    }
}

/// `dst[r][s][c] = act(bias[c] + (A^T M A)[r][s][c])` for the tile's valid pixels; the
/// others go to scratch.
///
/// # Safety
/// As [`transform_output`].
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn output_generic<const M: usize, const T: usize>(
    m: &[f32],
    t: usize,
    chunk: usize,
    cout: usize,
    bias: &[f32],
    a: Act,
    sc: &mut Scratch,
    out: &OutTile,
) {
    let Scratch { a: tmp, b: spare } = sc;
    // Down the columns: tmp[j][r] = sum_i AT[r][i] M[i][j].
    for (j, tc) in tmp.chunks_exact_mut(M * cout).take(T).enumerate() {
        let x: [&[f32]; T] =
            std::array::from_fn(|i| &m[((i * T + j) * chunk + t) * cout..][..cout]);
        let mut runs = tc.chunks_exact_mut(cout);
        let y: [&mut [f32]; M] = std::array::from_fn(|_| runs.next().expect("M runs"));
        at::<M, T>(x, y, cout);
    }
    // Along the rows: o[r][s] = sum_j AT[s][j] tmp[j][r], into the pixels themselves.
    let tmp: &[f32] = tmp;
    let mut spare = spare.chunks_exact_mut(cout);
    for r in 0..M {
        let x: [&[f32]; T] = std::array::from_fn(|j| &tmp[(j * M + r) * cout..][..cout]);
        let y: [&mut [f32]; M] = std::array::from_fn(|s| {
            if r < out.rows && s < out.cols {
                // SAFETY: pixel (r, s) of the tile is inside dst and only this tile writes it.
                unsafe {
                    std::slice::from_raw_parts_mut(
                        out.dst.get().add(out.at + r * out.row_stride + s * cout),
                        cout,
                    )
                }
            } else {
                spare.next().expect("spare runs")
            }
        });
        at::<M, T>(x, y, cout);
        for s in 0..out.cols.min(M) {
            if r >= out.rows {
                break;
            }
            // SAFETY: as above.
            let px = unsafe {
                std::slice::from_raw_parts_mut(
                    out.dst.get().add(out.at + r * out.row_stride + s * cout),
                    cout,
                )
            };
            for (v, b) in px.iter_mut().zip(bias) {
                *v += b;
            }
            act::apply(a, px);
        }
    }
}

#[cfg(test)]
mod tests;
