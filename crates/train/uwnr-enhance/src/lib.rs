//! uwnr-enhance: Shallow-UWnet, the compact underwater enhancement network the UWNR paper trains
//! on each synthetic dataset to show what the data is worth (its Table 1): the model, its
//! weights in the released key names, inference, training ([`train::train`]) and scoring on a
//! paired test folder ([`eval::evaluate_dir`]).

mod data;
pub mod error;
pub mod eval;
pub mod infer;
pub mod model;
pub mod train;
pub mod weights;

pub use error::{EnhanceError, Result};
pub use eval::{EvalReport, ImageScore, evaluate_dir};
pub use infer::enhance;
pub use model::{Dropout, ShallowUwnet, ShallowUwnetConfig};
pub use train::{EnhanceTrainConfig, EnhanceTrainOptions, EnhanceTrainSummary, train};
pub use uwnr_run::{Event, RunSettings};
