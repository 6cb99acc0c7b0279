//! uwnr-model: the UWNR generator (MHB-Unet, Ye et al., "Underwater Light Field Retention:
//! Neural Rendering for Underwater Imaging", CVPR-W 2022) in burn: its config, weights under
//! the authors' PyTorch keys, and whole-image inference with tiling for large photos.
//!
//! The implementation is chosen once at the edge ([`backend_from_name`]: the dedicated
//! `uwnr-engine` by default, or burn on a device from [`device_from_name`]) and a loaded
//! [`Network`] renders with it.

pub mod bundled;
pub mod config;
pub mod error;
pub mod generator;
pub mod infer;
pub mod network;
pub mod style;
mod variant;
pub mod water;
pub mod weights;

pub use bundled::{BUNDLED_MODEL_NAME, bundled_weights};
pub use burn::tensor::Device;
pub use config::{AnchorKind, GeneratorConfig, LightFieldMap, gmacs, param_count};
pub use error::{ModelError, Result};
pub use generator::{ChannelMeans, Generator};
pub use infer::{RenderOptions, render};
pub use network::{Backend, ENGINE_NAME, Network, backend_from_name, backend_names};
pub use style::{DepthResponse, DepthScale, ReferenceStyle, Variant, Water};
pub use weights::{
    LoadedWeights, NamedTensor, TensorMap, WeightsDtype, WeightsFormat, WeightsInfo,
    load_generator, load_generator_from_bytes, read_tensor, read_tensor_file, read_weights,
    read_weights_from_bytes, save_generator, write_tensor_file,
};

/// Names [`device_from_name`] accepts in this build.
#[must_use]
pub fn device_names() -> &'static [&'static str] {
    #[cfg(feature = "tch")]
    {
        &["flex", "tch"]
    }
    #[cfg(not(feature = "tch"))]
    {
        &["flex"]
    }
}

/// The compute device called `name`: `"flex"` (burn's pure-Rust multi-threaded CPU backend)
/// or, with the `tch` feature, `"tch"` (libtorch on the CPU).
pub fn device_from_name(name: &str) -> Result<Device> {
    match name {
        "flex" => Ok(Device::flex()),
        // burn 0.22 deprecates its libtorch backend; it stays here as an optional reference
        // backend for speed and parity comparisons.
        #[cfg(feature = "tch")]
        #[allow(deprecated)]
        "tch" => Ok(Device::libtorch()),
        _ => Err(ModelError::UnknownDevice {
            name: name.to_string(),
            available: device_names().join(", "),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_names_resolve() {
        for name in device_names() {
            device_from_name(name).unwrap();
        }
        let err = device_from_name("cuda").unwrap_err();
        assert!(err.to_string().contains("flex"), "{err}");
    }
}
