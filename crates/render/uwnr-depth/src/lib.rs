//! uwnr-depth: where the depth channel of UWNR's input comes from.
//!
//! # Depth convention (everywhere in uwnr)
//!
//! A depth map is a **1-channel [`uwnr_core::Image`] with values in [0, 1], the same size as the
//! clean image, where larger means FARTHER** (more water between the camera and the object;
//! 0 = nearest, 1 = farthest). The paper's generator learns whatever convention its training
//! depth used (UWNR paper, section on depth; the released code reads precomputed grey maps
//! `/255`). A [`Depth`] also says what its values stand for: a *relative* map (the built-in
//! prior, a monocular network, a normalised map) says only which parts are farther, a *metric*
//! map ([`DepthUnit`]: 16-bit millimetres, float metres) carries the metres that 1 stands for
//! ([`Depth::metric_max`]), so that rendering can put the scene's distances in metres into
//! `t = exp(-beta z)`.
//!
//! # Sources
//!
//! [`DepthSource`] is the one choice used everywhere (rendering and training):
//! - [`DepthSource::Builtin`] (the default): a weight-free prior, a ground-plane ramp modulated
//!   by local contrast, see [`builtin`];
//! - [`DepthSource::Maps`]: maps the user provides (one file, or a directory matched by stem),
//!   see the `maps` module docs;
//! - [`DepthSource::Onnx`]: a monocular depth network the user brings (MiDaS, DPT, Depth
//!   Anything...), run with tract, see the `onnx` module (the `onnx` feature; without it the
//!   source is refused in one line).
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
mod npy;
#[cfg(feature = "onnx")]
pub mod onnx;
mod util;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;

pub use builtin::builtin_depth;
pub use error::{DepthError, Result};
pub use maps::{DepthUnit, beside_maps, fill_holes, partner_map, read_map, read_map_bytes};
pub use npy::{is_npy_path, load_npy};

use maps::MapSource;
#[cfg(feature = "onnx")]
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
        /// Min-max normalise each map to [0, 1] (before inverting), making it relative. Holes
        /// stored as 0 are filled from their neighbours first.
        #[serde(default)]
        normalize: bool,
        /// What the stored values mean; a metric unit keeps the scene's metres (and cannot be
        /// inverted or normalised). Absent in records made before units existed: relative.
        #[serde(default, skip_serializing_if = "is_relative")]
        unit: DepthUnit,
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

fn is_relative(unit: &DepthUnit) -> bool {
    *unit == DepthUnit::Relative
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
    /// For a metric map, the distance in metres that 1 stands for (the map's farthest value):
    /// `map * metric_max` is the scene's depth in metres.
    pub metric_max: Option<f32>,
    /// Whether the map is the built-in prior's guess rather than a measurement or a model the
    /// user chose (rendering trusts the prior less: `uwnr_model`'s depth response).
    pub prior: bool,
}

impl Depth {
    /// The depth read from the map file `path` for a clean image of `clean_size` with `unit`:
    /// metric units keep their metres, relative maps are min-max normalised (holes filled
    /// first), as an RGB-D set's `depth/` folder is read.
    pub fn from_file(
        path: &Path,
        clean_size: (usize, usize),
        unit: DepthUnit,
        limits: &DecodeLimits,
    ) -> Result<Self> {
        let normalize = !unit.is_metric();
        let (map, notes, metric_max) = read_map(path, clean_size, unit, normalize, limits)?;
        Ok(Self {
            map,
            notes,
            relative: metric_max.is_none(),
            metric_max,
            prior: false,
        })
    }
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
    #[cfg(feature = "onnx")]
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
                unit,
            } => Prepared::Maps(MapSource::new(path, *invert, *normalize, *unit, limits)?),
            #[cfg(feature = "onnx")]
            Self::Onnx {
                model,
                invert,
                input_size,
            } => Prepared::Onnx(Box::new(OnnxDepth::new(model, *invert, *input_size)?)),
            #[cfg(not(feature = "onnx"))]
            Self::Onnx { model, .. } => {
                return Err(DepthError::NoOnnx {
                    path: model.clone(),
                });
            }
        };
        Ok(PreparedDepth { inner })
    }
}

impl PreparedDepth {
    /// Whether the maps come from files (a map resized to an image must see the image's own
    /// geometry, before any crop).
    #[must_use]
    pub fn reads_files(&self) -> bool {
        matches!(self.inner, Prepared::Maps(_))
    }

    /// The depth map of `clean` (1 or 3 channels, values in [0, 1]) in uwnr's convention, at
    /// the clean image's size. `clean_path` is where the clean image was read from; it is
    /// needed only by a directory of maps (to find the partner by file stem).
    pub fn depth_for(&self, clean: &Image, clean_path: Option<&Path>) -> Result<Depth> {
        let (map, notes, metric_max, relative) = match &self.inner {
            Prepared::Builtin => (builtin_depth(clean)?, Vec::new(), None, true),
            Prepared::Maps(maps) => {
                let (map, notes, metric) = maps.depth_for(clean, clean_path)?;
                (map, notes, metric, maps.normalizes())
            }
            #[cfg(feature = "onnx")]
            Prepared::Onnx(model) => {
                let (map, notes) = model.depth_for(clean)?;
                (map, notes, None, true)
            }
        };
        Ok(Depth {
            map,
            notes,
            relative,
            metric_max,
            prior: matches!(self.inner, Prepared::Builtin),
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
