//! Stride-1 convolutions with few output channels (the generator's output layer: 3 channels
//! for the paper's network, 6 for the anchored one). A micro-kernel tile is `NR` = 16 or 32
//! output channels wide, so for 3 outputs nine tenths of its work would be padding; here each
//! output pixel is instead `cout` dot products over its neighbourhood's channel runs, vectorised
//! along the input channels (one vector partial sum per output, reduced at the end), with the
//! bias and activation fused.

use rayon::prelude::*;

use crate::kernels::{Act, Isa, act};
use crate::tensor::{Feature, SharedMut};

/// Most output channels this path takes; wider layers use the tiled kernels.
pub(crate) const MAX_OUT: usize = 8;

/// A stride-1 convolution (3x3 with zero padding 1, or 1x1) of at most [`MAX_OUT`] outputs.
#[derive(Clone, Debug)]
pub(crate) struct Narrow {
    isa: Isa,
    cin: usize,
    cout: usize,
    /// 1 or 3.
    k: usize,
    act: Act,
    /// `[tap][cout][cin]`.
    weight: Vec<f32>,
    bias: Vec<f32>,
}

impl Narrow {
    /// Whether a layer of `cout` outputs takes this path.
    pub fn applies(cout: usize) -> bool {
        (1..=MAX_OUT).contains(&cout)
    }

    /// Packs PyTorch-layout weights `[cout][cin][k][k]`.
    pub fn new(
        isa: Isa,
        weight: &[f32],
        bias: &[f32],
        cout: usize,
        cin: usize,
        k: usize,
        act: Act,
    ) -> Self {
        debug_assert!(Self::applies(cout));
        let taps = k * k;
        let mut packed = vec![0.0; taps * cout * cin];
        for t in 0..taps {
            for n in 0..cout {
                for ci in 0..cin {
                    packed[(t * cout + n) * cin + ci] = weight[(n * cin + ci) * taps + t];
                }
            }
        }
        Self {
            isa,
            cin,
            cout,
            k,
            act,
            weight: packed,
            bias: bias[..cout].to_vec(),
        }
    }

    /// Writes the convolution of `src` into `dst` (same size, `cout` channels). A 3x3 kernel
    /// needs `src.pad == 1`.
    pub fn run(&self, src: &Feature, dst: &mut Feature) {
        debug_assert_eq!((src.c, dst.c), (self.cin, self.cout));
        debug_assert_eq!((src.h, src.w), (dst.h, dst.w));
        debug_assert!(self.k == 1 || src.pad == 1);
        let taps: Vec<usize> = if self.k == 3 {
            (0..3)
                .flat_map(|ky| (0..3).map(move |kx| (ky, kx)))
                .map(|(ky, kx)| ky * src.row_stride() + kx * src.c)
                .collect()
        } else {
            vec![0]
        };
        let rows: Vec<usize> = (0..dst.h).map(|y| dst.at(y, 0)).collect();
        let out = SharedMut(dst.data.as_mut_ptr());
        let out_len = dst.data.len();
        (0..src.h).into_par_iter().for_each(|y| {
            // First pixel's read at tap (0, 0): padded row y for 3x3, interior row y for 1x1.
            let base = if self.k == 3 {
                y * src.row_stride()
            } else {
                src.at(y, 0)
            };
            debug_assert!(rows[y] + src.w * self.cout <= out_len);
            // SAFETY: row y of dst is written by this item only and holds w * cout floats.
            let row = unsafe {
                std::slice::from_raw_parts_mut(out.get().add(rows[y]), src.w * self.cout)
            };
            let job = Row {
                src: &src.data,
                taps: &taps,
                base,
                step: src.c,
                cin: self.cin,
                weight: &self.weight,
                bias: &self.bias,
                act: self.act,
            };
            // SAFETY: the instruction set was checked when the network was packed.
            unsafe { run_row(self.isa, self.cout, &job, row) };
        });
    }
}

/// One output row's operands.
struct Row<'a> {
    src: &'a [f32],
    taps: &'a [usize],
    /// Index in `src` of pixel 0's read at tap 0.
    base: usize,
    /// Floats between consecutive pixels' reads.
    step: usize,
    cin: usize,
    weight: &'a [f32],
    bias: &'a [f32],
    act: Act,
}

/// Dispatches a row to the instruction set's kernel.
///
/// # Safety
/// `isa` must be supported by the CPU.
unsafe fn run_row(isa: Isa, cout: usize, job: &Row<'_>, out: &mut [f32]) {
    macro_rules! by_width {
        ($f:ident) => {
            match cout {
                1 => $f::<1, 4>(job, out),
                2 => $f::<2, 4>(job, out),
                3 => $f::<3, 4>(job, out),
                4 => $f::<4, 4>(job, out),
                5 => $f::<5, 2>(job, out),
                6 => $f::<6, 2>(job, out),
                7 => $f::<7, 2>(job, out),
                _ => $f::<8, 2>(job, out),
            }
        };
    }
    match isa {
        // SAFETY: forwarded.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { by_width!(row_avx512) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { by_width!(row_avx2) },
        _ => by_width!(row_portable),
    }
}

/// Runs `pixels::<N, P>` over a row, `P` pixels at a time (independent sums hide the FMA
/// latency and share the weight loads), then the last `w % P` one at a time.
macro_rules! in_groups {
    ($pixels:ident, $job:expr, $out:expr) => {{
        let w = $out.len() / N;
        let groups = w / P;
        for g in 0..groups {
            $pixels::<N, P>($job, g * P, &mut $out[g * P * N..(g + 1) * P * N]);
        }
        for x in groups * P..w {
            $pixels::<N, 1>($job, x, &mut $out[x * N..(x + 1) * N]);
        }
    }};
}

/// AVX-512F: one zmm partial sum per output, a masked load for the last `cin % 16` channels.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn row_avx512<const N: usize, const P: usize>(job: &Row<'_>, out: &mut [f32]) {
    // SAFETY: forwarded.
    unsafe { in_groups!(pixels_avx512, job, out) }
}

/// `P` consecutive pixels from `x0` of an AVX-512 row.
// `acc[p][n]` is indexed across both dimensions in the inner loops.
#[allow(clippy::needless_range_loop)]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn pixels_avx512<const N: usize, const P: usize>(job: &Row<'_>, x0: usize, out: &mut [f32]) {
    use std::arch::x86_64::{
        __m512, _mm512_fmadd_ps, _mm512_maskz_loadu_ps, _mm512_reduce_add_ps, _mm512_setzero_ps,
    };
    const L: usize = 16;
    let cin = job.cin;
    let full = cin - cin % L;
    let mask: u16 = ((1u32 << (cin % L)) - 1) as u16;
    let mut acc: [[__m512; N]; P] = [[_mm512_setzero_ps(); N]; P];
    let start = job.base + x0 * job.step;
    for (t, &off) in job.taps.iter().enumerate() {
        // SAFETY: the pixels' reads at every tap lie inside src (the padded geometry), and
        // each tap's weights are N runs of cin floats.
        unsafe {
            let a = job.src.as_ptr().add(start + off);
            let w = job.weight.as_ptr().add(t * N * cin);
            let mut j = 0;
            while j <= cin {
                if j == full && mask == 0 {
                    break;
                }
                let m = if j < full { u16::MAX } else { mask };
                let av: [__m512; P] =
                    std::array::from_fn(|p| _mm512_maskz_loadu_ps(m, a.add(p * job.step + j)));
                for n in 0..N {
                    let wv = _mm512_maskz_loadu_ps(m, w.add(n * cin + j));
                    for p in 0..P {
                        acc[p][n] = _mm512_fmadd_ps(av[p], wv, acc[p][n]);
                    }
                }
                j += L;
            }
        }
    }
    for (p, px) in out.chunks_exact_mut(N).enumerate() {
        let mut vals = [0.0f32; N];
        for ((v, acc), b) in vals.iter_mut().zip(acc[p]).zip(job.bias) {
            *v = _mm512_reduce_add_ps(acc) + b;
        }
        act::apply(job.act, &mut vals);
        px.copy_from_slice(&vals);
    }
}

/// AVX2 with FMA: one ymm partial sum per output, a masked load for the last `cin % 8`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn row_avx2<const N: usize, const P: usize>(job: &Row<'_>, out: &mut [f32]) {
    // SAFETY: forwarded.
    unsafe { in_groups!(pixels_avx2, job, out) }
}

/// `P` consecutive pixels from `x0` of an AVX2 row.
// `acc[p][n]` is indexed across both dimensions in the inner loops.
#[allow(clippy::needless_range_loop)]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn pixels_avx2<const N: usize, const P: usize>(job: &Row<'_>, x0: usize, out: &mut [f32]) {
    use std::arch::x86_64::{
        __m256, _mm256_fmadd_ps, _mm256_loadu_ps, _mm256_maskload_ps, _mm256_setr_epi32,
        _mm256_setzero_ps, _mm256_storeu_ps,
    };
    const L: usize = 8;
    let cin = job.cin;
    let full = cin - cin % L;
    let r = (cin % L) as i32;
    let mask = _mm256_setr_epi32(
        -i32::from(r > 0),
        -i32::from(r > 1),
        -i32::from(r > 2),
        -i32::from(r > 3),
        -i32::from(r > 4),
        -i32::from(r > 5),
        -i32::from(r > 6),
        0,
    );
    let mut acc: [[__m256; N]; P] = [[_mm256_setzero_ps(); N]; P];
    let start = job.base + x0 * job.step;
    for (t, &off) in job.taps.iter().enumerate() {
        // SAFETY: as in the AVX-512 kernel.
        unsafe {
            let a = job.src.as_ptr().add(start + off);
            let w = job.weight.as_ptr().add(t * N * cin);
            let mut j = 0;
            while j < full {
                let av: [__m256; P] =
                    std::array::from_fn(|p| _mm256_loadu_ps(a.add(p * job.step + j)));
                for n in 0..N {
                    let wv = _mm256_loadu_ps(w.add(n * cin + j));
                    for p in 0..P {
                        acc[p][n] = _mm256_fmadd_ps(av[p], wv, acc[p][n]);
                    }
                }
                j += L;
            }
            if r != 0 {
                let av: [__m256; P] =
                    std::array::from_fn(|p| _mm256_maskload_ps(a.add(p * job.step + j), mask));
                for n in 0..N {
                    let wv = _mm256_maskload_ps(w.add(n * cin + j), mask);
                    for p in 0..P {
                        acc[p][n] = _mm256_fmadd_ps(av[p], wv, acc[p][n]);
                    }
                }
            }
        }
    }
    for (p, px) in out.chunks_exact_mut(N).enumerate() {
        let mut vals = [0.0f32; N];
        for ((v, acc), b) in vals.iter_mut().zip(acc[p]).zip(job.bias) {
            let mut lanes = [0.0f32; L];
            // SAFETY: lanes holds 8 floats.
            unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), acc) };
            *v = lanes.iter().sum::<f32>() + b;
        }
        act::apply(job.act, &mut vals);
        px.copy_from_slice(&vals);
    }
}

/// Plain Rust, any target.
fn row_portable<const N: usize, const P: usize>(job: &Row<'_>, out: &mut [f32]) {
    let cin = job.cin;
    for (x, px) in out.chunks_exact_mut(N).enumerate() {
        let mut vals = [0.0f32; N];
        let start = job.base + x * job.step;
        for (t, &off) in job.taps.iter().enumerate() {
            let a = &job.src[start + off..start + off + cin];
            let w = &job.weight[t * N * cin..(t + 1) * N * cin];
            for (v, wn) in vals.iter_mut().zip(w.chunks_exact(cin)) {
                *v += a.iter().zip(wn).map(|(a, b)| a * b).sum::<f32>();
            }
        }
        for (v, b) in vals.iter_mut().zip(job.bias) {
            *v += b;
        }
        act::apply(job.act, &mut vals);
        px.copy_from_slice(&vals);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{self, test_values as values};
    use crate::tensor::Planar;

    #[test]
    fn every_isa_matches_the_reference() {
        // Input widths below, at and between multiples of the lanes (scalar tails), 1x1 and
        // 3x3, odd sizes.
        let cases = [
            (32, 3, 3, 7, 9, Act::Tanh),
            (16, 6, 3, 5, 4, Act::Identity),
            (21, 1, 3, 3, 11, Act::Elu),
            (8, 8, 3, 6, 6, Act::LeakyRelu),
            (40, 5, 1, 4, 13, Act::Tanh),
        ];
        for isa in Isa::supported() {
            for (i, &(cin, cout, k, h, w, a)) in cases.iter().enumerate() {
                let weight = values(i as u64 + 1, cout * cin * k * k, 0.3);
                let bias = values(i as u64 + 40, cout, 0.5);
                let input = Planar {
                    channels: cin,
                    height: h,
                    width: w,
                    data: values(i as u64 + 80, cin * h * w, 1.0),
                };
                let want =
                    reference::activate(a, reference::conv2d(&input, &weight, &bias, cout, k, 1));
                let conv = Narrow::new(isa, &weight, &bias, cout, cin, k, a);
                let src = Feature::from_planar(&input, k / 2);
                let mut dst = Feature::zeros(h, w, cout, 0);
                conv.run(&src, &mut dst);
                let diff = reference::max_abs_diff(&dst.to_planar().data, &want.data);
                assert!(diff < 1e-5, "{isa:?} case {i}: {diff}");
            }
        }
    }
}
