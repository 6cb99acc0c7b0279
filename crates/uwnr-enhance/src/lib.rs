//! uwnr-enhance: Shallow-UWnet, the compact underwater enhancement network the UWNR paper trains
//! on each synthetic dataset to show what the data is worth (its Table 1): the model, its
//! weights in the released key names, and inference.

pub mod error;
pub mod infer;
pub mod model;
pub mod weights;

pub use error::{EnhanceError, Result};
pub use infer::enhance;
pub use model::{Dropout, ShallowUwnet, ShallowUwnetConfig};
