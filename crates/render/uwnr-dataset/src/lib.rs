//! uwnr-dataset: mass production of paired underwater data (the paper's LNRUD recipe: every
//! clean image rendered after K real underwater references drawn without replacement).
//!
//! - [`plan`]: the deterministic plan (inputs, names, reference draws, seeds, shards);
//! - [`run`]: the crash-safe, resumable, parallel generation ([`generate`]);
//! - [`manifest`]: the folder's settings, manifest and failure files;
//! - [`verify`] and [`merge`]: checking a folder, joining shards;
//! - [`target`]: the strength of a water-anchored model's pairs, calibrated to real pairs;
//! - [`gallery`]: `preview.png` and `index.html`.
//!
//! A dataset folder:
//! ```text
//! OUT/dataset.json         settings and inputs (compared on every resume)
//! OUT/manifest.jsonl       one line per complete pair
//! OUT/underwater/NAME_k.png, OUT/clean/NAME_k.png   the pair
//! OUT/depth/NAME_k.png     16-bit depth the render used, bright = far (optional; the pair's
//!                          `params.depth` in the manifest says what 1 stands for)
//! OUT/lightfield/NAME_k.png  the light field the network saw (optional)
//! OUT/labels/NAME_k.json|txt, OUT/masks/NAME_k.png, OUT/coco.json   labels (see [`labels`])
//! OUT/webdataset/uwnr-NNNNNN.tar, index.json   WebDataset shards (see [`webdataset`])
//! OUT/failed.jsonl         what the last run could not make (absent when nothing failed)
//! OUT/preview.png, OUT/index.html, OUT/gallery/   a look at the result
//! ```

pub mod error;
pub mod gallery;
pub mod labels;
pub mod manifest;
pub mod merge;
pub mod plan;
pub mod renderer;
pub mod run;
pub mod target;
pub mod verify;
pub mod webdataset;

pub use error::{DatasetError, Result};
pub use labels::LabelInputs;
pub use manifest::{Failure, Record, Settings};
pub use merge::{MergeReport, merge};
pub use plan::{Shard, Size};
pub use renderer::Renderer;
pub use run::{Event, RunOptions, Spec, Summary, calibrates, generate};
pub use target::{PairWater, StrengthSummary, TargetKind, WaterTarget};
pub use uwnr_render::{DATASET_PRIOR_TRUST, DATASET_SCENE_SCALE_M};
pub use verify::{Report, verify};
pub use webdataset::{ExportReport, export};
