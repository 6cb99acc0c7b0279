//! uwnr-model: the UWNR generator (MHB-Unet, Ye et al., "Underwater Light Field Retention:
//! Neural Rendering for Underwater Imaging", CVPR-W 2022) for rendering: its config, weights
//! under the authors' PyTorch keys (safetensors or their `torch.save` checkpoint), the reference
//! style and water, and whole-image inference with tiling for large photos.
//!
//! This crate is in the render wing: it builds without a training framework. A loaded
//! [`Network`] runs on `uwnr-engine` ([`Backend`]); the training wing (`uwnr-train`)
//! holds burn's module of the same network and hands it to a [`Network`] through
//! [`Implementation`] to render with the same tiling code.

pub mod blur;
pub mod bundled;
pub mod config;
pub mod effects;
pub mod error;
pub mod finish;
pub mod infer;
pub mod network;
pub mod style;
mod variant;
pub mod water;
pub mod weights;

pub use bundled::{BUNDLED_MODEL_NAME, bundled_config, bundled_model_bytes, bundled_network};
pub use config::{AnchorKind, Correction, GeneratorConfig, LightFieldMap, gmacs, param_count};
pub use effects::WaterEffects;
pub use error::{ModelError, Result};
pub use finish::{DepthResponse, DepthScale};
pub use infer::{Forward, RenderOptions};
pub use network::{Backend, ENGINE_NAME, Implementation, Network};
pub use style::{ReferenceStyle, Variant, Water};
pub use weights::{
    LoadedWeights, NamedTensor, TensorMap, WeightsDtype, WeightsFormat, WeightsInfo,
    read_tensor_file, read_weights, read_weights_from_bytes, save_weights, write_tensor_file,
};
