//! uwnr-depth: where the depth channel of UWNR's input comes from.
//!
//! # Depth convention (everywhere in uwnr)
//!
//! A depth map is a **1-channel [`uwnr_core::Image`] with values in [0, 1], the same size as the
//! clean image, where larger means FARTHER** (more water between the camera and the object;
//! 0 = nearest, 1 = farthest). It is a *relative* depth: only the ordering and rough proportions
//! matter, not metres. The generator learns whatever convention its training depth used, so
//! training and rendering must use the same [`DepthSource`] (UWNR paper, section on depth;
//! the released code reads precomputed grey maps `/255`).
//!
//! # Sources
//!
//! [`DepthSource`] is the one choice used everywhere (rendering and training):
//! - [`DepthSource::Builtin`] (the default): a weight-free prior, a ground-plane ramp modulated
//!   by local contrast, see [`builtin`];
//! - [`DepthSource::Maps`]: maps the user provides (one file, or a directory matched by stem),
//!   see the `maps` module docs;
//! - [`DepthSource::Onnx`]: a monocular depth network the user brings (MiDaS, DPT, Depth
//!   Anything...), run with tract, see [`onnx`].
//!
//! ```
//! use uwnr_depth::DepthSource;
//! # fn main() -> Result<(), uwnr_depth::DepthError> {
//! let clean = uwnr_core::Image::filled(64, 48, 3, 0.5);
//! let prepared = DepthSource::default().prepare()?; // once; shareable across threads
//! let depth = prepared.depth_for(&clean, None)?;
//! assert_eq!(depth.map.size(), clean.size());
//! # Ok(())
//! # }
//! ```

pub mod builtin;
pub mod error;
mod maps;
pub mod onnx;
mod util;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;

pub use builtin::builtin_depth;
pub use error::{DepthError, Result};

use maps::MapSource;
use onnx::OnnxDepth;

/// Where depth maps come from. Serialised with a `type` tag, e.g. `{"type": "Builtin"}` or
/// `{"type": "Maps", "path": "depth/", "invert": false, "normalize": true}`. All produce maps in
/// uwnr's convention (see the crate docs: [0, 1], larger = farther).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type")]
pub enum DepthSource {
    /// The built-in prior ([`builtin`]): needs no weights or files.
    #[default]
    Builtin,
    /// Depth maps from files: grey images read as code / max code (8-bit `/255`, 16-bit
    /// `/65535`) and resized to the clean image.
    Maps {
        /// One map used for every image, or a directory searched for the map whose file stem
        /// equals the clean image's (`a.jpg` -> `a.png`).
        path: PathBuf,
        /// Use `1 - d`: for maps where near is bright (e.g. disparity maps).
        #[serde(default)]
        invert: bool,
        /// Min-max normalise each map to [0, 1] (before inverting): for metric depth, e.g.
        /// NYU's 16-bit millimetres whose raw `/65535` values span only about 0..0.1. Holes
        /// stored as 0 stay at the nearest value.
        #[serde(default)]
        normalize: bool,
    },
    /// A monocular depth model in ONNX format that outputs relative inverse depth (disparity)
    /// as `[1, H, W]` or `[1, 1, H, W]` (see [`onnx`]).
    Onnx {
        /// The `.onnx` file.
        model: PathBuf,
        /// Set for models whose output is depth (far = large) rather than disparity.
        #[serde(default)]
        invert: bool,
        /// `(width, height)` of the model input when the model's own is dynamic; ignored (with
        /// a note) when the model fixes its input size. Default: short side 384, aspect kept,
        /// multiples of 32 (MiDaS). Depth Anything wants multiples of 14, e.g. `(518, 518)`.
        #[serde(default)]
        input_size: Option<(usize, usize)>,
    },
}

/// A depth map and what was done to produce it.
#[derive(Clone, Debug, PartialEq)]
pub struct Depth {
    /// 1 channel, the clean image's size, values in [0, 1], larger = farther.
    pub map: Image,
    /// Human-readable remarks worth showing the user, e.g.
    /// `"depth map d/a.png 640x480 resized to 481x321"`.
    pub notes: Vec<String>,
    /// Whether the map is relative: normalised per image (the built-in prior, a monocular
    /// network, maps read with `normalize`), so its level says nothing about how far the scene
    /// is; otherwise its values are absolute depths in uwnr's [0, 1] range (maps as stored).
    pub relative: bool,
}

/// A [`DepthSource`] ready to produce maps: files indexed or decoded, the model loaded and
/// optimised. `Send + Sync`: prepare once and share it between threads.
#[derive(Debug)]
pub struct PreparedDepth {
    inner: Prepared,
}

#[derive(Debug)]
enum Prepared {
    Builtin,
    Maps(MapSource),
    Onnx(Box<OnnxDepth>),
}

impl DepthSource {
    /// Prepares the source with the default decoding limits (see [`Self::prepare_with_limits`]).
    pub fn prepare(&self) -> Result<PreparedDepth> {
        self.prepare_with_limits(DecodeLimits::default())
    }

    /// Prepares the source: decodes a single map or indexes a directory of maps (applying
    /// `limits` to every map decoded), or loads and optimises the ONNX model. Fails early on a
    /// missing path, an unreadable model or a model whose input or output is unusable.
    pub fn prepare_with_limits(&self, limits: DecodeLimits) -> Result<PreparedDepth> {
        let inner = match self {
            Self::Builtin => Prepared::Builtin,
            Self::Maps {
                path,
                invert,
                normalize,
            } => Prepared::Maps(MapSource::new(path, *invert, *normalize, limits)?),
            Self::Onnx {
                model,
                invert,
                input_size,
            } => Prepared::Onnx(Box::new(OnnxDepth::new(model, *invert, *input_size)?)),
        };
        Ok(PreparedDepth { inner })
    }
}

impl PreparedDepth {
    /// The depth map of `clean` (1 or 3 channels, values in [0, 1]) in uwnr's convention, at
    /// the clean image's size. `clean_path` is where the clean image was read from; it is
    /// needed only by a directory of maps (to find the partner by file stem).
    pub fn depth_for(&self, clean: &Image, clean_path: Option<&Path>) -> Result<Depth> {
        let ((map, notes), relative) = match &self.inner {
            Prepared::Builtin => ((builtin_depth(clean)?, Vec::new()), true),
            Prepared::Maps(maps) => (maps.depth_for(clean, clean_path)?, maps.normalizes()),
            Prepared::Onnx(model) => (model.depth_for(clean)?, true),
        };
        Ok(Depth {
            map,
            notes,
            relative,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prepared_depth_is_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<PreparedDepth>();
    }
}
