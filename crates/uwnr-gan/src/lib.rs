//! uwnr-gan: a GAN baseline in the manner of UWGAN (Wang et al. 2019, "UWGAN: Underwater GAN
//! for real-world underwater color restoration and dehazing") and WaterGAN (Li et al. 2017):
//! a small generator predicts the underwater image-formation parameters of a clean in-air image
//! from the image, its depth and a water code `z`; a differentiable imaging layer renders
//! `I = k · V(r) · (J t + B (1 − t))`, `t = exp(−β d)` ([`imaging`]); a PatchGAN discriminator
//! learns real underwater images from the renders ([`model`]). Training is unpaired
//! ([`train::train`]); trained weights ([`weights::load_generator`]) render any clean image
//! with a seed ([`infer::render`]).

mod data;
pub mod error;
pub mod imaging;
pub mod infer;
pub mod model;
pub mod train;
pub mod weights;

pub use error::{GanError, Result};
pub use imaging::{ImagingConfig, WaterParams};
pub use infer::{WaterValues, render, render_with_values};
pub use model::{
    Discriminator, DiscriminatorConfig, Gan, GanConfig, Generator, GeneratorConfig, sample_z,
};
pub use train::{GanLoss, GanTrainConfig, GanTrainSummary, train};
pub use uwnr_run::{Event, RunSettings, TrainOptions};
pub use weights::{
    BUNDLED_GAN_NAME, GENERATOR_FILE, bundled_gan_weights, generator_or_bundled, load_generator,
    load_generator_from_bytes, save_generator,
};
