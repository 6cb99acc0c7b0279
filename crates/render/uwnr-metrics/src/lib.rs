//! uwnr-metrics: the image quality and distribution metrics of the underwater imaging field,
//! each replicating a named reference implementation.
//!
//! | metric | function | follows |
//! |---|---|---|
//! | PSNR (dB) | [`psnr`], [`psnr_gray`] | `skimage.metrics.peak_signal_noise_ratio`; luma = ITU-R BT.601 `0.299 R + 0.587 G + 0.114 B` |
//! | SSIM | [`ssim`], [`ssim_gray`], [`ssim_with`] | `skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False)`, mean over channels; [`SsimOptions::skimage_default`] for the 7x7 uniform variant |
//! | UIQM | [`uiqm`], [`uiqm_with`] | Panetta et al. 2016, as coded in FUnIE-GAN's `Evaluation/uqim_utils.py` (10x10 tiles, RGB); preset [`UiqmConfig::shallow_uwnet`] (8x8, BGR) |
//! | UCIQE | [`uciqe`], [`uciqe_components`] | Yang & Sowmya 2015, as coded in xueleichen/PSNR-SSIM-UCIQE-UIQM-Python `nevaluate.py` (skimage Lab units) |
//! | Fréchet distance | [`frechet_distance`], [`frechet_distance_from_stats`] | pytorch-fid's formula, through symmetric eigendecompositions (exact for n < d) |
//! | depth effect | [`depth_effect`] | uwnr's own: far/near contrast kept with a real depth map over the same with a constant one (1 = distance does nothing) |
//! | KID | [`kid`] | Bińkowski et al. 2018; cubic polynomial kernel, unbiased MMD², subsets as torch-fidelity / clean-fid |
//!
//! Features for the two distances ([`FeatureExtractor`]): [`OnnxInception`] (a user's
//! InceptionV3 ONNX, pool3, pytorch-fid preprocessing: FD on it is **FID**) and
//! [`ColorTextureFeatures`] (built in, no weights, 155-d: FD on it is **FD-ct**, not FID).
//!
//! Conventions:
//! - images are [`uwnr_core::Image`]: planar RGB f32 in [0, 1], widened to f64 for all
//!   arithmetic. An 8-bit file is therefore measured as u8 / 255, and `data_range` is 1.0
//!   ([`DEFAULT_DATA_RANGE`]); PSNR and SSIM then equal skimage on the u8 arrays with
//!   `data_range=255`;
//! - full-reference metrics take `(pred, target)` of the same shape and are symmetric;
//!   identical images give PSNR `+inf` and SSIM 1;
//! - SSIM needs at least 11x11 pixels (7x7 for the uniform window) and ignores a border of
//!   `(win - 1) / 2` pixels of its map, as skimage does;
//! - UIQM quantises to 8 bits first (the reference scripts read 8-bit files); UCIQE measures
//!   the values as given. Neither resizes: the FUnIE-GAN and Shallow-UWnet scripts resize to
//!   256x256 first, so do that before comparing with numbers from those papers;
//! - every metric is finite on flat images (where the UIQM reference returns NaN);
//! - all functions are pure; large images use rayon internally.

mod depth;
mod error;
mod features;
mod filter;
mod frechet;
mod kid;
mod linalg;
mod psnr;
mod resize;
mod ssim;
mod uciqe;
mod uiqm;

pub use depth::{DEPTH_BLOCK, FLAT_BLOCK_STD, depth_effect, far_near_contrast};
pub use error::{MetricsError, Result};
pub use features::{
    COLOR_TEXTURE_DIM, COLOR_TEXTURE_WORKING_SIZE, ColorTextureFeatures, FeatureExtractor,
    extract_all,
};
#[cfg(feature = "onnx")]
pub use features::{
    INCEPTION_INPUT_SIDE, INCEPTION_POOL3_DIM, InceptionInputRange, OnnxInception,
    OnnxInceptionOptions,
};
pub use frechet::{FeatureStats, frechet_distance, frechet_distance_from_stats};
pub use kid::{KID_SUBSET_SIZE, KID_SUBSETS, kid};
pub use psnr::{DEFAULT_DATA_RANGE, LUMA_BT601, mse, psnr, psnr_gray};
pub use resize::resize_bilinear_torch;
pub use ssim::{SsimOptions, SsimWindow, ssim, ssim_gray, ssim_gray_with, ssim_with};
pub use uciqe::{UCIQE_WEIGHTS, UciqeComponents, uciqe, uciqe_components};
pub use uiqm::{ChannelOrder, UIQM_WEIGHTS, UiqmComponents, UiqmConfig, uiqm, uiqm_with};
