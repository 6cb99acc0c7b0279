//! uwnr-train: the UWNR generator (Ye et al., "Underwater Light Field Retention: Neural
//! Rendering for Underwater Imaging", CVPR-W 2022) in burn and its training, as a task of
//! uwnr-run's training loop. The training wing: rendering (`uwnr-model`) needs none of it.
//!
//! - [`generator`]: the MHB-Unet as burn's module ([`GeneratorInit::init`] builds it from
//!   `uwnr_model`'s config); [`burn_weights`]: it loaded from and saved to the authors' keys;
//!   [`burn_render`]: it rendering through `uwnr_model`'s tiling ([`network_from_generator`]);
//!   [`burn_style`]: the render's blur and finish on tensors, for the losses;
//! - [`config::TrainConfig`]: the run's settings; `Default` is the paper's recipe;
//! - [`data`]: paired folders with depth, computed once;
//! - [`augment`], [`loader`]: crops, flips, rotations, colour casts and the light field of each
//!   sample, a pure function of `(seed, epoch, position)`;
//! - [`losses`], [`vgg`]: L1, VGG19 perceptual (or an SSIM stand-in), underwater dark channel,
//!   light-field consistency;
//! - [`adversarial`]: the anchored variant's correction trained against real underwater photos
//!   with a discriminator (`config.adversarial`) instead of paired targets;
//! - [`trainer::train`]: UWNR's task (step, validation, `generator.safetensors`) on
//!   [`uwnr_run::train`], which owns the loop, logs, curves, checkpoints and exact resume.
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use uwnr_train::{TrainConfig, TrainOptions, train};
//! # fn main() -> Result<(), uwnr_train::TrainError> {
//! let cfg = TrainConfig::default();
//! let opts = TrainOptions::new(vec!["data/uieb".into()], "runs/uieb".into(), uwnr_train::Device::flex());
//! let summary = train(&cfg, &opts, &AtomicBool::new(false), &mut |_event| {})?;
//! println!("{} steps", summary.step);
//! # Ok(())
//! # }
//! ```

pub mod adversarial;
pub mod augment;
pub mod burn_render;
pub mod burn_style;
pub mod burn_weights;
pub mod config;
pub mod data;
pub mod error;
pub mod generator;
pub mod loader;
pub mod losses;
pub mod trainer;
pub mod vgg;

pub use adversarial::{ADVERSARIAL_TERMS, Critic, adversarial_step, through_stages};
pub use burn_render::{BurnForward, RenderOn, network_from_generator};
pub use burn_weights::{
    generator_from_tensors, generator_to_tensors, load_generator, load_generator_from_bytes,
    read_tensor, save_generator,
};
pub use config::{
    AdversarialConfig, AugmentConfig, ColorCast, LightFieldLoss, LossWeights, PerceptualFallback,
    RenderStages, SmallImagePolicy, TrainConfig,
};
pub use error::{Result, TrainError};
pub use generator::{ChannelMeans, Generator, GeneratorInit};
pub use losses::{Criterion, LossValues};
pub use trainer::{GENERATOR_FILE, TrainOptions, TrainSummary, train, train_step};
pub use uwnr_run::{
    Device, Event, RunSettings, ValResult, device_from_name, device_names, init_seeded,
};
pub use vgg::Vgg19Features;
