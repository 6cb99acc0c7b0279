//! Per-image feature vectors for the distribution distances ([`crate::frechet_distance`],
//! [`crate::kid`]):
//! - [`OnnxInception`]: a user-supplied InceptionV3 ONNX network (pool3, 2048-d) run with
//!   pytorch-fid's preprocessing; the Fréchet distance on these features is FID;
//! - [`ColorTextureFeatures`]: a fixed, weight-free 155-d colour-texture descriptor; the
//!   Fréchet distance on it is reported as FD-ct, never as FID.

mod color_texture;
#[cfg(feature = "onnx")]
mod inception;

use rayon::prelude::*;
use uwnr_core::Image;

use crate::error::Result;

pub use color_texture::{COLOR_TEXTURE_DIM, COLOR_TEXTURE_WORKING_SIZE, ColorTextureFeatures};
#[cfg(feature = "onnx")]
pub use inception::{
    INCEPTION_INPUT_SIDE, INCEPTION_POOL3_DIM, InceptionInputRange, OnnxInception,
    OnnxInceptionOptions,
};

/// Maps an image to a fixed-length feature vector.
pub trait FeatureExtractor: Send + Sync {
    /// Length of every vector [`FeatureExtractor::extract`] returns.
    fn dim(&self) -> usize;
    /// A short stable name for reports (e.g. `"inception-pool3"`, `"color-texture-v1"`).
    fn name(&self) -> &str;
    /// The feature vector of one RGB image in [0, 1].
    fn extract(&self, img: &Image) -> Result<Vec<f64>>;
}

/// Features of many images, in order, extracted in parallel.
pub fn extract_all(extractor: &dyn FeatureExtractor, images: &[Image]) -> Result<Vec<Vec<f64>>> {
    images
        .par_iter()
        .map(|img| extractor.extract(img))
        .collect()
}
