//! Register-blocked micro-kernels: `C[m, n] = act(bias[n] + sum_t sum_k A_t[m, k] B_t[k, n])`
//! for a tile of `m <= MR` rows (output pixels) and `n <= NR` columns (output channels), with
//! one `(A offset, B panel)` pair per tap. A direct 3x3 convolution is nine taps over a
//! channels-last feature map (no im2col copy); a 1x1 convolution or one Winograd product is
//! one tap.
//!
//! `A` rows are `lda` floats apart and each row's `k` values are contiguous; `B` is packed as
//! `[tap][k][NR]`, zero beyond the layer's output channels. Each row of `A` is broadcast and
//! multiplied into `NR / lanes` vector accumulators, so a tile keeps `MR x NR / lanes`
//! accumulators in registers (24 zmm for AVX-512, 12 ymm for AVX2).
//!
//! The instruction set is chosen at run time ([`Isa::best`]); every variant computes the same
//! sums in the same order per output (up to FMA contraction) and is tested against
//! [`crate::reference`].
//!
//! With [`Precision::Bf16`] the heavy products take `A` and `B` as bf16 pairs along `k`
//! ([`bf16`]), accumulated in f32: `vdpbf16ps` where the CPU has AVX512_BF16, an emulation in
//! plain f32 arithmetic elsewhere.

pub mod act;
#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
#[cfg(target_arch = "x86_64")]
mod avx512bf16;
pub(crate) mod bf16;
mod bf16_bits;
mod portable;

/// Largest tile width of any variant.
pub(crate) const MAX_NR: usize = 32;

/// An instruction set the kernels are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// AVX-512F: tiles of 12 pixels x 32 channels in 24 zmm accumulators.
    Avx512,
    /// AVX2 with FMA: tiles of 6 pixels x 16 channels in 12 ymm accumulators.
    Avx2,
    /// Plain Rust that runs anywhere (the compiler's auto-vectorisation for the target).
    Portable,
}

impl Isa {
    /// Every variant, fastest first.
    pub const ALL: [Isa; 3] = [Isa::Avx512, Isa::Avx2, Isa::Portable];

    /// Whether this CPU can run the variant.
    #[must_use]
    pub fn is_supported(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => std::arch::is_x86_feature_detected!("avx512f"),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx512 | Isa::Avx2 => false,
            Isa::Portable => true,
        }
    }

    /// The variants this CPU can run, fastest first.
    #[must_use]
    pub fn supported() -> Vec<Isa> {
        Self::ALL.into_iter().filter(|i| i.is_supported()).collect()
    }

    /// The fastest variant this CPU can run.
    #[must_use]
    pub fn best() -> Isa {
        Self::ALL
            .into_iter()
            .find(|i| i.is_supported())
            .unwrap_or(Isa::Portable)
    }

    /// Output channels per tile (`NR`): weights are packed in panels this wide.
    #[must_use]
    pub fn nr(self) -> usize {
        match self {
            Isa::Avx512 => 32,
            Isa::Avx2 | Isa::Portable => 16,
        }
    }

    /// Output pixels per tile (`MR`).
    #[must_use]
    pub fn mr(self) -> usize {
        match self {
            Isa::Avx512 => 12,
            Isa::Avx2 => 6,
            Isa::Portable => 4,
        }
    }

    /// Lower-case name (`avx512`, `avx2`, `portable`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx512 => "avx512",
            Isa::Avx2 => "avx2",
            Isa::Portable => "portable",
        }
    }
}

/// Arithmetic of the heavy products: the Winograd products of the stride-1 3x3 convolutions and
/// the direct 3x3 convolutions (the stride-2 stems).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Precision {
    /// f32 operands and sums everywhere (the default).
    #[default]
    F32,
    /// Operands of those products rounded to bf16 (round to nearest even), products and sums
    /// in f32; everything else (transforms, epilogues, attention, output layer) in f32. `vdpbf16ps` on CPUs with AVX512_BF16 (with
    /// [`Isa::Avx512`]), an emulation of it in f32 arithmetic elsewhere (same rounding of the
    /// operands, no speed-up).
    Bf16,
}

impl Precision {
    /// Lower-case name (`f32`, `bf16`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::Bf16 => "bf16",
        }
    }
}

/// How one product's dot products are computed: the f32 kernels of the instruction set, or
/// one of the two bf16 kernels. Tiles are `isa.mr() x isa.nr()` in every case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Dot {
    /// f32 operands on the [`Isa`]'s kernel.
    F32,
    /// bf16 pairs on `vdpbf16ps` (AVX512_BF16; only with [`Isa::Avx512`]).
    Bf16Native,
    /// bf16 pairs widened to f32 and multiplied in f32 (any CPU).
    Bf16Emulated,
}

impl Dot {
    /// The kernel for `precision` on `isa`: native bf16 only where the CPU has it.
    pub fn new(isa: Isa, precision: Precision) -> Self {
        match precision {
            Precision::F32 => Self::F32,
            Precision::Bf16 if isa == Isa::Avx512 && bf16::native_supported() => Self::Bf16Native,
            Precision::Bf16 => Self::Bf16Emulated,
        }
    }

    /// Whether the operands are bf16.
    pub fn is_bf16(self) -> bool {
        self != Self::F32
    }
}

/// The activation of a convolution's epilogue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// None.
    Identity,
    /// `max(x, 0.01 x)`.
    LeakyRelu,
    /// `x > 0 ? x : e^x - 1`.
    Elu,
    /// `tanh(x)`.
    Tanh,
}

/// One tile's operands. Raw pointers because tiles of one output are written from several
/// threads; the caller guarantees the ranges are valid and disjoint.
///
/// `E` is the element of `A` and `B`: `f32`, or `u16` holding bf16 bits for the bf16 products,
/// where `k` and `lda` are even and `B` is packed `[tap][k / 2][NR][2]` (see [`bf16`]).
#[derive(Clone, Copy)]
pub(crate) struct Tile<'a, E = f32> {
    /// `A` at row 0, before the tap offset.
    pub a: *const E,
    /// Floats between consecutive rows of `A`.
    pub lda: usize,
    /// Offset of each tap's `A` from `a`, in floats.
    pub taps: &'a [isize],
    /// Reduction length per tap.
    pub k: usize,
    /// Packed `B` panel, `[taps][k][NR]`.
    pub b: *const E,
    /// `NR` biases (zero-padded).
    pub bias: *const f32,
    /// Output row 0.
    pub c: *mut f32,
    /// Floats between consecutive output rows.
    pub ldc: usize,
    /// Rows to compute (`1..=MR`).
    pub m: usize,
    /// Columns to store (`1..=NR`).
    pub n: usize,
    /// Epilogue activation.
    pub act: Act,
    /// Add the sums to the values `C` holds instead of overwriting them (a later block of a
    /// split reduction; then the bias should be zero and the activation the identity).
    pub accumulate: bool,
}

impl<'a, E> Tile<'a, E> {
    /// The same tile on operands `a` and `b` of another element type (f32 and bf16 products
    /// share everything else).
    pub fn with_operands<F>(&self, a: *const F, b: *const F) -> Tile<'a, F> {
        Tile {
            a,
            lda: self.lda,
            taps: self.taps,
            k: self.k,
            b,
            bias: self.bias,
            c: self.c,
            ldc: self.ldc,
            m: self.m,
            n: self.n,
            act: self.act,
            accumulate: self.accumulate,
        }
    }
}

/// Runs one tile on `isa`.
///
/// # Safety
/// `isa` must be supported by the CPU; every pointer in `t` must be valid for the ranges the
/// tile reads (`a + taps[i] + m' * lda + [0, k)`, `b + [0, taps * k * NR)`, `bias + [0, NR)`)
/// and writes (`c + m' * ldc + [0, n)`), for `m' < m`.
pub(crate) unsafe fn run_tile(isa: Isa, t: &Tile<'_>) {
    debug_assert!(t.m >= 1 && t.m <= isa.mr() && t.n >= 1 && t.n <= isa.nr());
    match isa {
        // SAFETY: forwarded contract; the variant is supported.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { avx512::tile(t) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { avx2::tile(t) },
        #[cfg(not(target_arch = "x86_64"))]
        Isa::Avx512 | Isa::Avx2 => unsafe { portable::tile(t) },
        Isa::Portable => unsafe { portable::tile(t) },
    }
}

/// Adds the bias, applies the activation and stores `m x n` of the `MR x NR` sums in `buf`.
///
/// # Safety
/// As [`run_tile`] for `t.c`.
#[inline(always)]
pub(crate) unsafe fn epilogue<const NR: usize, E>(t: &Tile<'_, E>, buf: &mut [[f32; NR]]) {
    for (row, vals) in buf.iter_mut().enumerate().take(t.m) {
        if t.accumulate {
            for (n, v) in vals.iter_mut().enumerate().take(t.n) {
                // SAFETY: row < m, n < t.n: inside the caller's output range.
                *v += unsafe { *t.c.add(row * t.ldc + n) };
            }
        }
        for (n, v) in vals.iter_mut().enumerate() {
            // SAFETY: bias holds NR values.
            *v += unsafe { *t.bias.add(n) };
        }
        act::apply(t.act, vals);
        // SAFETY: row < m, n <= NR: inside the caller's output range.
        unsafe {
            let dst = t.c.add(row * t.ldc);
            if t.n == NR {
                // A copy of constant length becomes vector stores, not a call to memcpy.
                std::ptr::copy_nonoverlapping(vals.as_ptr(), dst, NR);
            } else {
                for (n, &v) in vals.iter().enumerate().take(t.n) {
                    *dst.add(n) = v;
                }
            }
        }
    }
}

/// Runs one tile of bf16 operands with kernel `dot` (a bf16 one) for `isa`'s tile shape.
///
/// # Safety
/// As [`run_tile`], with `k` and `lda` even and the ranges counted in bf16 elements; `dot`
/// must be [`Dot::Bf16Native`] only where [`bf16::native_supported`] and `isa` is AVX-512.
pub(crate) unsafe fn run_tile_bf16(isa: Isa, dot: Dot, t: &Tile<'_, u16>) {
    debug_assert!(t.m >= 1 && t.m <= isa.mr() && t.n >= 1 && t.n <= isa.nr());
    debug_assert!(t.k.is_multiple_of(2) && t.lda.is_multiple_of(2));
    match dot {
        // SAFETY: forwarded contract; the CPU has AVX512_BF16 and the tile is 12 x 32.
        #[cfg(target_arch = "x86_64")]
        Dot::Bf16Native => unsafe { avx512bf16::tile(t) },
        // SAFETY: forwarded contract.
        _ => unsafe { bf16::emulated_tile(isa, t) },
    }
}
