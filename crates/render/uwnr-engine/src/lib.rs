//! uwnr-engine: a dedicated CPU inference engine for the UWNR generator (MHB-Unet, Ye et al.,
//! "Underwater Light Field Retention: Neural Rendering for Underwater Imaging", CVPR-W 2022).
//!
//! Feature maps are channels-last with a zero border; stride-1 3x3 convolutions run as
//! Winograd F(4x4, 3x3) ([`winograd`](crate::winograd); F(2x2, 3x3) as an option), the stride-2
//! ones and those with under 16 channels as direct convolutions without im2col
//! ([`conv`](crate::conv)), all on register-blocked micro-kernels chosen at run time ([`Isa`]:
//! AVX-512F, AVX2+FMA or portable Rust); the output layer's few channels are per-pixel dot
//! products ([`narrow`](crate::narrow)). The block's `conk1`,
//! `conk3` and identity branches are folded into one 3x3 kernel; bias, activation and the
//! PixelShuffle channel order are fused into the convolutions. Every operation has a plain
//! reference implementation in [`reference`] that the kernels are tested against.
//!
//! [`Precision::Bf16`] (off by default) rounds the operands of the Winograd products and of the
//! stride-2 convolutions to bf16 and sums in f32: `vdpbf16ps` where the CPU has AVX512_BF16, an
//! emulation with the same rounding elsewhere.
//!
//! The crate knows nothing of files or of any ML framework: weights come in as
//! [`GeneratorWeights`] (PyTorch layout), images as [`Planar`] tensors.

mod conv;
pub mod error;
mod kernels;
mod narrow;
mod network;
pub mod reference;
mod tensor;
pub mod weights;
mod winograd;

pub use error::{EngineError, Result};
pub use kernels::{Act, Isa, Precision};
pub use network::bench::{LayerBench, LayerKind};
pub use network::{ConvAlgo, EngineOptions, Generator, Means, SIZE_MULTIPLE};
pub use tensor::Planar;
pub use weights::{BlockWeights, ConvWeights, DownWeights, GeneratorWeights, LEVELS};
