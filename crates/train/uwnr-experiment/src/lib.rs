//! uwnr-experiment: the UWNR paper's downstream experiment (its Table 1), for any data.
//!
//! The paper shows its synthetic data is worth having by training an underwater enhancement
//! network, Shallow-UWnet, on each synthetic dataset and scoring it on real underwater images.
//! [`run_downstream`] does the same for a set of rendering methods:
//!
//! 1. one training set per method, rendered from the same clean images with the same reference
//!    assignment (the dataset pipeline draws references from the seed and the image's index, so
//!    every method sees the same clean/reference pairs);
//! 2. Shallow-UWnet trained on each (and on any real paired folders given as reference rows) with
//!    the same config, seed and budget of training samples;
//! 3. every network, and the unenhanced input ("no enhancement"), scored on each real paired test
//!    set: PSNR and SSIM against the clean reference, UIQM and UCIQE of the output alone;
//! 4. `results.json`, `results.md` (the table) and `examples.png` (example enhancements).
//!
//! Every stage is resumable: datasets and training runs continue where they stopped, and each
//! score is cached in the output folder, so running the same command again finishes the job.

pub mod error;
pub mod report;
pub mod run;

pub use error::{ExperimentError, Result};
pub use report::{Results, Row, RowKind, Scores, TestSet, write_markdown};
pub use run::{DownstreamSpec, Event, TrainingSet, run_downstream};
/// The enhancer crate (its training config is part of a [`DownstreamSpec`]).
pub use uwnr_enhance as enhance;
