//! Generator weights under the authors' PyTorch state-dict keys (released `model/FSU2.py`):
//! safetensors files we write, and the authors' own `torch.save({'G1': state_dict, ...})`
//! checkpoints, whose keys carry the `module.` prefix of DistributedDataParallel.
//!
//! Loading is strict: a missing tensor, a wrong shape, a non-float dtype or a key the network
//! does not have is an error naming the key. Only the unused InstanceNorm keys (`.norm.`) are
//! accepted and ignored. Saved files carry the full key set (norms as weight 1, bias 0, their
//! PyTorch init) so the authors' `load_state_dict` accepts them, and the config as JSON in the
//! safetensors metadata under [`CONFIG_METADATA_KEY`], so a file alone rebuilds the model.
//!
//! By concern: this module holds the types and the entry points; `keys.rs` spells the key
//! scheme (and the metadata and checkpoint keys) once, public so that the training wing maps
//! them to burn's module (`uwnr-train`'s `burn_weights.rs`); `engine_keys.rs` maps them to the
//! engine's weights; `format.rs` reads and
//! writes the containers; `files.rs` writes files atomically and holds checkpoints given as
//! bytes in a temporary file.

mod engine_keys;
mod files;
mod format;
pub mod keys;

use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};

pub use engine_keys::engine_weights;
use files::{TempFile, write_atomic};
use format::{detect_format, read_checkpoint_tensors, read_safetensors_tensors, serialize_tensors};
use keys::infer_config;
pub use keys::{CHECKPOINT_STATE_KEY, CONFIG_METADATA_KEY, DDP_PREFIX, SOURCE_METADATA_KEY};

use crate::config::GeneratorConfig;
use crate::error::{ModelError, Result};

/// Name used in errors for weights given as bytes rather than a file.
const BYTES_SOURCE: &str = "<in-memory weights>";

/// How a weights file was stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum WeightsFormat {
    /// A safetensors file.
    Safetensors,
    /// A PyTorch `torch.save` checkpoint (the authors' `{'G1': ..., 'optimizer_weightG1': ...}`
    /// or a bare state dict).
    TorchCheckpoint,
}

/// Floating-point element type of stored weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum WeightsDtype {
    /// IEEE half precision (halves the file; about 3 significant digits).
    F16,
    /// bfloat16 (the same range as f32 with 8 bits of mantissa).
    Bf16,
    /// IEEE single precision (lossless for the network).
    F32,
    /// IEEE double precision (read only, converted to f32).
    F64,
}

/// One tensor of a state dict, converted to f32.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedTensor {
    /// Extents, outermost first (PyTorch order, e.g. `[out, in, kh, kw]` for a conv weight).
    pub shape: Vec<usize>,
    /// Row-major values.
    pub data: Vec<f32>,
}

/// A state dict: key -> tensor.
pub type TensorMap = BTreeMap<String, NamedTensor>;

/// Facts about a weights file.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightsInfo {
    /// Container format, detected from the content.
    pub format: WeightsFormat,
    /// Element type of the stored tensors (the widest one if they differ).
    pub dtype: WeightsDtype,
    /// Safetensors `__metadata__` entries (empty for PyTorch checkpoints).
    pub metadata: BTreeMap<String, String>,
    /// Keys present in the file but not used by the network (the unused InstanceNorms).
    pub ignored_keys: Vec<String>,
}

/// A weights file read into memory, before the network is built.
#[derive(Clone, Debug)]
pub struct LoadedWeights {
    /// The config stored in the file, or inferred from the tensor shapes.
    pub config: GeneratorConfig,
    /// Every tensor of the file under its state-dict key (prefix `module.` stripped).
    pub tensors: TensorMap,
    /// Format, dtype and metadata (`ignored_keys` is filled when the network is built).
    pub info: WeightsInfo,
}

/// Reads a weights file (safetensors or PyTorch checkpoint, detected from its content).
pub fn read_weights(path: &Path) -> Result<LoadedWeights> {
    let (tensors, info) = read_tensor_file(path)?;
    with_config(tensors, info)
}

/// Reads weights held in memory (e.g. embedded in a binary). A PyTorch checkpoint is written
/// to a temporary file first, because its reader needs a seekable file.
pub fn read_weights_from_bytes(bytes: &[u8]) -> Result<LoadedWeights> {
    match detect_format(bytes, BYTES_SOURCE)? {
        WeightsFormat::Safetensors => read_safetensors(bytes, BYTES_SOURCE),
        WeightsFormat::TorchCheckpoint => {
            let temp = TempFile::write(bytes)?;
            read_checkpoint(&temp.path, BYTES_SOURCE)
        }
    }
}

/// Reads every tensor of a weights file of any network (safetensors or a PyTorch state dict /
/// checkpoint, detected from the content), with `module.` prefixes stripped. Other networks'
/// loaders (the enhancer's, for one) build on this.
pub fn read_tensor_file(path: &Path) -> Result<(TensorMap, WeightsInfo)> {
    let io_err = |source| ModelError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut head = Vec::with_capacity(16);
    std::fs::File::open(path)
        .map_err(io_err)?
        .take(16)
        .read_to_end(&mut head)
        .map_err(io_err)?;
    let name = path.display().to_string();
    match detect_format(&head, &name)? {
        WeightsFormat::Safetensors => {
            let bytes = std::fs::read(path).map_err(io_err)?;
            read_safetensors_tensors(&bytes, &name)
        }
        WeightsFormat::TorchCheckpoint => read_checkpoint_tensors(path, &name),
    }
}

/// Writes tensors as a safetensors file, atomically, in `dtype`, with `metadata`.
pub fn write_tensor_file(
    path: &Path,
    tensors: &TensorMap,
    dtype: WeightsDtype,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    let bytes = serialize_tensors(tensors, dtype, metadata, path)?;
    write_atomic(path, &bytes)
}

/// Saves a state dict under the authors' keys as safetensors, with `config` as JSON under
/// [`CONFIG_METADATA_KEY`] and `metadata` beside it (e.g. [`SOURCE_METADATA_KEY`]). The file
/// is written to a temporary name in the same directory and renamed into place, so a reader
/// never sees a partial file.
pub fn save_weights(
    tensors: &TensorMap,
    config: &GeneratorConfig,
    path: &Path,
    dtype: WeightsDtype,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    let bytes = serialize_safetensors(tensors, config, dtype, metadata, path)?;
    write_atomic(path, &bytes)
}

/// Serializes a state dict to safetensors bytes with the config and `metadata`.
fn serialize_safetensors(
    tensors: &TensorMap,
    config: &GeneratorConfig,
    dtype: WeightsDtype,
    metadata: &BTreeMap<String, String>,
    path: &Path,
) -> Result<Vec<u8>> {
    let mut info = metadata.clone();
    let config_json = serde_json::to_string(config).map_err(|e| ModelError::Metadata {
        key: CONFIG_METADATA_KEY.into(),
        source: e,
    })?;
    info.insert(CONFIG_METADATA_KEY.into(), config_json);
    serialize_tensors(tensors, dtype, &info, path)
}

fn read_safetensors(bytes: &[u8], name: &str) -> Result<LoadedWeights> {
    let (tensors, info) = read_safetensors_tensors(bytes, name)?;
    with_config(tensors, info)
}

/// The generator config stored in the metadata, or inferred from the tensor shapes.
fn with_config(tensors: TensorMap, info: WeightsInfo) -> Result<LoadedWeights> {
    let config = match info.metadata.get(CONFIG_METADATA_KEY) {
        Some(json) => {
            let config: GeneratorConfig =
                serde_json::from_str(json).map_err(|e| ModelError::Metadata {
                    key: CONFIG_METADATA_KEY.into(),
                    source: e,
                })?;
            config.validate()?;
            config
        }
        None => infer_config(&tensors)?,
    };
    Ok(LoadedWeights {
        config,
        tensors,
        info,
    })
}

fn read_checkpoint(path: &Path, name: &str) -> Result<LoadedWeights> {
    let (tensors, info) = read_checkpoint_tensors(path, name)?;
    with_config(tensors, info)
}
