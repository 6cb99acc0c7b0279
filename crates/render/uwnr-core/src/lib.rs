//! uwnr-core: the image type, decoding and encoding with limits, filters, the UWNR
//! light-field map, the dark channel and depth-map handling. No ML framework lives here.

pub mod color;
pub mod dark_channel;
pub mod error;
pub mod gaussian;
pub mod image;
pub mod index;
pub mod io;
pub mod lightfield;
pub mod resize;
pub mod seed;
pub mod sheet;

pub use error::{CoreError, Result};
pub use image::{Image, Plane};
