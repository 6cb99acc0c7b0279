//! uwnr-gan: the GAN baseline in the manner of UWGAN (Wang et al. 2019, "UWGAN: Underwater GAN
//! for real-world underwater color restoration and dehazing") and WaterGAN (Li et al. 2017), for
//! rendering: a small generator predicts the underwater image-formation parameters of a clean
//! in-air image from the image, its depth and a water code `z` ([`generator`]), and the imaging
//! layer renders `I = k · V(r) · (J t + B (1 − t))`, `t = exp(−β d)` ([`imaging`]). Trained
//! weights ([`weights::load_generator`]) render any clean image with a seed ([`infer::render`]).
//!
//! This crate is in the render wing: it needs no training framework. Training (the
//! differentiable layer, the PatchGAN discriminator, the loop) is `uwnr-gan-train`.

pub mod config;
pub mod error;
pub mod generator;
pub mod imaging;
pub mod infer;
pub mod weights;

pub use config::{GeneratorConfig, ImagingConfig};
pub use error::{GanError, Result};
pub use generator::Generator;
pub use imaging::WaterValues;
pub use infer::{render, render_with_values, water_code};
pub use weights::{
    BUNDLED_GAN_NAME, GENERATOR_FILE, bundled_gan_weights, generator_or_bundled, load_generator,
    load_generator_from_bytes, weights_or_bundled,
};
