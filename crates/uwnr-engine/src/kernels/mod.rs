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

pub mod act;
#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
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
#[derive(Clone, Copy)]
pub(crate) struct Tile<'a> {
    /// `A` at row 0, before the tap offset.
    pub a: *const f32,
    /// Floats between consecutive rows of `A`.
    pub lda: usize,
    /// Offset of each tap's `A` from `a`, in floats.
    pub taps: &'a [isize],
    /// Reduction length per tap.
    pub k: usize,
    /// Packed `B` panel, `[taps][k][NR]`.
    pub b: *const f32,
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
pub(crate) unsafe fn epilogue<const NR: usize>(t: &Tile<'_>, buf: &mut [[f32; NR]]) {
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
