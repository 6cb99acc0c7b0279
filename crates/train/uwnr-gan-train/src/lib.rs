//! uwnr-gan-train: training of the GAN baseline in the manner of UWGAN (Wang et al. 2019) and
//! WaterGAN (Li et al. 2017) in burn: the parameter generator as burn's module ([`model`]), the
//! differentiable imaging layer `I = k · V(r) · (J t + B (1 − t))`, `t = exp(−β d)`
//! ([`imaging`]), a PatchGAN discriminator, and unpaired adversarial training
//! ([`train::train`]). The weights it writes render without burn through `uwnr-gan`, whose
//! config and constants these modules share.

mod data;
pub mod error;
pub mod imaging;
pub mod infer;
pub mod model;
pub mod train;
pub mod weights;

pub use error::{GanError, Result};
pub use imaging::WaterParams;
pub use infer::{WaterValues, render, render_with_values};
pub use model::{
    Discriminator, DiscriminatorConfig, Gan, GanConfig, Generator, GeneratorConfig, GeneratorInit,
    sample_z,
};
pub use train::{GanLoss, GanTrainConfig, GanTrainSummary, train};
pub use uwnr_gan::ImagingConfig;
pub use uwnr_run::{Event, RunSettings, TrainOptions};
pub use weights::{
    BUNDLED_GAN_NAME, GENERATOR_FILE, bundled_gan_weights, generator_or_bundled, load_generator,
    load_generator_from_bytes, save_generator,
};
