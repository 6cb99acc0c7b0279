//! Generator weights under the authors' PyTorch state-dict keys (released `model/FSU2.py`):
//! safetensors files we write, and the authors' own `torch.save({'G1': state_dict, ...})`
//! checkpoints, whose keys carry the `module.` prefix of DistributedDataParallel.
//!
//! The key scheme, per encoder level `P` in `in_conv_down1`, `down2`, `down3`, `down4`:
//! `P.mpconv.0.{weight,bias}` (stride-2 conv), `P.mpconv.2.conk3.*`, `P.mpconv.2.conk1.*`,
//! `P.mpconv.2.SA.spatial_pool.{0,2}.*`, `P.mpconv.2.CA.channel_map.{0,2}.*` and the unused
//! `P.mpconv.2.norm.{weight,bias}`; per decoder level `upK.up.0.*`; and `out.0.*`.
//!
//! Loading is strict: a missing tensor, a wrong shape, a non-float dtype or a key the network
//! does not have is an error naming the key. Only the unused InstanceNorm keys (`.norm.`) are
//! accepted and ignored. Saved files carry the full key set (norms as weight 1, bias 0, their
//! PyTorch init) so the authors' `load_state_dict` accepts them, and the config as JSON in the
//! safetensors metadata under [`CONFIG_METADATA_KEY`], so a file alone rebuilds the model.

use std::collections::{BTreeMap, HashMap};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use burn::nn::conv::Conv2d;
use burn::store::pytorch::PytorchError;
use burn::store::pytorch::PytorchReader;
use burn::store::pytorch_reader::DType as TorchDType;
use burn::tensor::{Device, Tensor, TensorData};
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::{Deserialize, Serialize};

use crate::config::{ATTENTION_REDUCTION, GeneratorConfig, LEVELS, LightFieldMap};
use crate::error::{ModelError, Result};
use crate::generator::{
    BasicBlock, ChannelAttention, Down, Generator, SpatialAttention, Up, conv_from_tensors,
};

/// Safetensors metadata key holding the [`GeneratorConfig`] as JSON.
pub const CONFIG_METADATA_KEY: &str = "uwnr.config";
/// Conventional metadata key for free-form provenance (what the weights were trained on or
/// converted from).
pub const SOURCE_METADATA_KEY: &str = "uwnr.source";
/// Key of the generator's state dict in the authors' training checkpoints (`train_ddp.py`).
pub const CHECKPOINT_STATE_KEY: &str = "G1";
/// Prefix DistributedDataParallel adds to every key (stripped by the authors' `test.py` with
/// `k[7:]`).
pub const DDP_PREFIX: &str = "module.";
/// Marker of the unused `InstanceNorm2d` keys, accepted on load and ignored.
pub(crate) const UNUSED_NORM_MARKER: &str = ".norm.";
/// Prefixes of the encoder levels in the state dict.
pub(crate) const DOWN_PREFIXES: [&str; LEVELS] = ["in_conv_down1", "down2", "down3", "down4"];
/// Prefixes of the decoder levels in the state dict.
pub(crate) const UP_PREFIXES: [&str; LEVELS] = ["up1", "up2", "up3", "up4"];
/// Zip local-file-header magic: `torch.save` (PyTorch >= 1.6) writes a zip archive.
const ZIP_MAGIC: &[u8; 4] = b"PK\x03\x04";
/// A pickle stream opens with the PROTO opcode: legacy (< 1.6) `torch.save` files.
const PICKLE_PROTO: u8 = 0x80;
/// Length of the little-endian u64 header size that opens a safetensors file.
const SAFETENSORS_LEN_BYTES: usize = 8;
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

/// Loads a generator from a weights file: builds the network from the stored (or inferred)
/// config and assigns every tensor.
pub fn load_generator(
    path: &Path,
    device: &Device,
) -> Result<(Generator, GeneratorConfig, WeightsInfo)> {
    build(read_weights(path)?, device)
}

/// [`load_generator`] for weights held in memory.
pub fn load_generator_from_bytes(
    bytes: &[u8],
    device: &Device,
) -> Result<(Generator, GeneratorConfig, WeightsInfo)> {
    build(read_weights_from_bytes(bytes)?, device)
}

fn build(
    loaded: LoadedWeights,
    device: &Device,
) -> Result<(Generator, GeneratorConfig, WeightsInfo)> {
    let LoadedWeights {
        config,
        tensors,
        mut info,
    } = loaded;
    let (generator, ignored) = generator_from_tensors(&config, tensors, device)?;
    info.ignored_keys = ignored;
    Ok((generator, config, info))
}

/// Builds a generator for `config` from a state dict. Returns it with the keys that were
/// present but unused (the `.norm.` keys). Every other key must be consumed exactly.
pub fn generator_from_tensors(
    config: &GeneratorConfig,
    tensors: TensorMap,
    device: &Device,
) -> Result<(Generator, Vec<String>)> {
    config.validate()?;
    let mut src = TensorSource {
        map: tensors,
        device: device.clone(),
    };
    let mut cin = config.in_channels;
    let mut downs = Vec::with_capacity(LEVELS);
    for (level, prefix) in DOWN_PREFIXES.iter().enumerate() {
        let c = config.level_width(level);
        downs.push(load_down(&mut src, prefix, cin, c)?);
        cin = c;
    }
    let mut ups = Vec::with_capacity(LEVELS);
    for (i, prefix) in UP_PREFIXES.iter().enumerate() {
        ups.push(load_up(
            &mut src,
            prefix,
            config.level_width(LEVELS - 1 - i),
        )?);
    }
    let out = src.conv(
        "out.0",
        config.decoder_out_width(),
        config.out_channels,
        3,
        1,
    )?;
    let ignored = src.finish()?;
    let [in_conv_down1, down2, down3, down4] = into_levels(downs)?;
    let [up1, up2, up3, up4] = into_levels(ups)?;
    let generator = Generator {
        in_conv_down1,
        down2,
        down3,
        down4,
        up1,
        up2,
        up3,
        up4,
        out,
    };
    Ok((generator, ignored))
}

fn into_levels<T>(items: Vec<T>) -> Result<[T; LEVELS]> {
    let n = items.len();
    items
        .try_into()
        .map_err(|_| ModelError::InvalidOptions(format!("{n} levels built, expected {LEVELS}")))
}

/// The generator's tensors under the authors' keys, including the unused norms (weight 1,
/// bias 0). Fails with [`ModelError::ShapeMismatch`] when `generator` was not built for
/// `config`.
pub fn generator_to_tensors(generator: &Generator, config: &GeneratorConfig) -> Result<TensorMap> {
    config.validate()?;
    let mut sink = TensorMap::new();
    let downs = [
        &generator.in_conv_down1,
        &generator.down2,
        &generator.down3,
        &generator.down4,
    ];
    let mut cin = config.in_channels;
    for (level, (down, prefix)) in downs.into_iter().zip(DOWN_PREFIXES).enumerate() {
        let c = config.level_width(level);
        save_down(&mut sink, prefix, down, cin, c)?;
        cin = c;
    }
    let ups = [
        &generator.up1,
        &generator.up2,
        &generator.up3,
        &generator.up4,
    ];
    for (i, (up, prefix)) in ups.into_iter().zip(UP_PREFIXES).enumerate() {
        let c = config.level_width(LEVELS - 1 - i);
        put_conv(
            &mut sink,
            &format!("{prefix}.up.0"),
            &up.conv,
            [2 * c, c, 3, 3],
        )?;
    }
    let shape = [config.out_channels, config.decoder_out_width(), 3, 3];
    put_conv(&mut sink, "out.0", &generator.out, shape)?;
    Ok(sink)
}

/// Saves a generator as safetensors under the authors' keys, with `config` as JSON under
/// [`CONFIG_METADATA_KEY`] and `metadata` beside it (e.g. [`SOURCE_METADATA_KEY`]). The file
/// is written to a temporary name in the same directory and renamed into place, so a reader
/// never sees a partial file.
pub fn save_generator(
    generator: &Generator,
    config: &GeneratorConfig,
    path: &Path,
    dtype: WeightsDtype,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    let tensors = generator_to_tensors(generator, config)?;
    let bytes = serialize_safetensors(&tensors, config, dtype, metadata, path)?;
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
        reason: e.to_string(),
    })?;
    info.insert(CONFIG_METADATA_KEY.into(), config_json);
    serialize_tensors(tensors, dtype, &info, path)
}

/// Serializes tensors to safetensors bytes with `metadata`.
fn serialize_tensors(
    tensors: &TensorMap,
    dtype: WeightsDtype,
    metadata: &BTreeMap<String, String>,
    path: &Path,
) -> Result<Vec<u8>> {
    let name = path.display().to_string();
    let st_err = |reason: String| ModelError::Safetensors {
        source_name: name.clone(),
        reason,
    };
    let (st_dtype, to_bytes): (Dtype, fn(f32) -> Vec<u8>) = match dtype {
        WeightsDtype::F32 => (Dtype::F32, |v| v.to_le_bytes().to_vec()),
        WeightsDtype::F16 => (Dtype::F16, |v| {
            half::f16::from_f32(v).to_le_bytes().to_vec()
        }),
        WeightsDtype::Bf16 => (Dtype::BF16, |v| {
            half::bf16::from_f32(v).to_le_bytes().to_vec()
        }),
        WeightsDtype::F64 => return Err(st_err("saving as f64 is not supported".into())),
    };
    let encoded: Vec<_> = tensors
        .iter()
        .map(|(k, t)| {
            (
                k,
                t,
                t.data
                    .iter()
                    .flat_map(|&v| to_bytes(v))
                    .collect::<Vec<u8>>(),
            )
        })
        .collect();
    let mut views = Vec::with_capacity(encoded.len());
    for (key, tensor, bytes) in &encoded {
        let view = TensorView::new(st_dtype, tensor.shape.clone(), bytes)
            .map_err(|e| st_err(format!("{key}: {e}")))?;
        views.push((key.as_str(), view));
    }
    let mut info: HashMap<String, String> = metadata.clone().into_iter().collect();
    // The convention of Hugging Face tools for tensors in PyTorch layout.
    info.entry("format".into()).or_insert_with(|| "pt".into());
    safetensors::serialize(views, Some(info)).map_err(|e| st_err(e.to_string()))
}

/// Identifies the container from the first bytes.
fn detect_format(head: &[u8], name: &str) -> Result<WeightsFormat> {
    if head.starts_with(ZIP_MAGIC) {
        return Ok(WeightsFormat::TorchCheckpoint);
    }
    // Before the pickle test: a safetensors header length whose low byte is 0x80 (e.g. 7,552)
    // starts the file with the pickle protocol byte. A pickle never has `{` at offset 8 (the
    // legacy format there holds the magic number's bytes).
    if head.len() > SAFETENSORS_LEN_BYTES && head[SAFETENSORS_LEN_BYTES] == b'{' {
        return Ok(WeightsFormat::Safetensors);
    }
    if head.first() == Some(&PICKLE_PROTO) {
        return Ok(WeightsFormat::TorchCheckpoint);
    }
    Err(ModelError::UnknownFormat {
        source_name: name.to_string(),
        reason: if head.len() <= SAFETENSORS_LEN_BYTES {
            format!("only {} bytes", head.len())
        } else {
            "neither a safetensors header, a zip archive nor a pickle".into()
        },
    })
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
                    reason: e.to_string(),
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

/// Every tensor of a safetensors file (any network), with the file's facts.
fn read_safetensors_tensors(bytes: &[u8], name: &str) -> Result<(TensorMap, WeightsInfo)> {
    let st_err = |reason: String| ModelError::Safetensors {
        source_name: name.to_string(),
        reason,
    };
    let (_, header) = SafeTensors::read_metadata(bytes).map_err(|e| st_err(e.to_string()))?;
    let metadata: BTreeMap<String, String> = header
        .metadata()
        .clone()
        .unwrap_or_default()
        .into_iter()
        .collect();
    let st = SafeTensors::deserialize(bytes).map_err(|e| st_err(e.to_string()))?;
    let mut tensors = TensorMap::new();
    let mut widest: Option<WeightsDtype> = None;
    for (key, view) in st.iter() {
        let (data, dtype) = decode_safetensors(key, &view)?;
        widest = widest.max(Some(dtype));
        tensors.insert(
            strip_prefix(key),
            NamedTensor {
                shape: view.shape().to_vec(),
                data,
            },
        );
    }
    Ok((
        tensors,
        WeightsInfo {
            format: WeightsFormat::Safetensors,
            dtype: widest.unwrap_or(WeightsDtype::F32),
            metadata,
            ignored_keys: Vec::new(),
        },
    ))
}

fn decode_safetensors(key: &str, view: &TensorView<'_>) -> Result<(Vec<f32>, WeightsDtype)> {
    let bytes = view.data();
    Ok(match view.dtype() {
        Dtype::F32 => (decode_le::<4>(bytes, f32::from_le_bytes), WeightsDtype::F32),
        Dtype::F16 => (
            decode_le::<2>(bytes, |b| half::f16::from_le_bytes(b).to_f32()),
            WeightsDtype::F16,
        ),
        Dtype::BF16 => (
            decode_le::<2>(bytes, |b| half::bf16::from_le_bytes(b).to_f32()),
            WeightsDtype::Bf16,
        ),
        Dtype::F64 => (
            decode_le::<8>(bytes, |b| f64::from_le_bytes(b) as f32),
            WeightsDtype::F64,
        ),
        other => {
            return Err(ModelError::UnsupportedDtype {
                key: key.to_string(),
                dtype: format!("{other:?}"),
            });
        }
    })
}

fn decode_le<const N: usize>(bytes: &[u8], f: impl Fn([u8; N]) -> f32) -> Vec<f32> {
    bytes
        .chunks_exact(N)
        .map(|c| {
            let mut a = [0u8; N];
            a.copy_from_slice(c);
            f(a)
        })
        .collect()
}

fn read_checkpoint(path: &Path, name: &str) -> Result<LoadedWeights> {
    let (tensors, info) = read_checkpoint_tensors(path, name)?;
    with_config(tensors, info)
}

/// Every tensor of a PyTorch checkpoint (a state dict, or one nested under `G1`).
fn read_checkpoint_tensors(path: &Path, name: &str) -> Result<(TensorMap, WeightsInfo)> {
    let ck_err = |e: PytorchError| ModelError::Checkpoint {
        source_name: name.to_string(),
        reason: e.to_string(),
    };
    // The authors' checkpoints nest the state dict under "G1"; a bare state dict has none.
    let reader = match PytorchReader::with_top_level_key(path, CHECKPOINT_STATE_KEY) {
        Ok(reader) => reader,
        Err(PytorchError::KeyNotFound(_)) => PytorchReader::new(path).map_err(ck_err)?,
        Err(e) => return Err(ck_err(e)),
    };
    let mut tensors = TensorMap::new();
    let mut widest: Option<WeightsDtype> = None;
    for (key, tensor) in reader.into_tensors() {
        let bytes = tensor.read().map_err(|e| ModelError::Checkpoint {
            source_name: name.to_string(),
            reason: e.to_string(),
        })?;
        let (data, dtype) = match tensor.dtype() {
            TorchDType::F32 => (
                decode_le::<4>(&bytes, f32::from_ne_bytes),
                WeightsDtype::F32,
            ),
            TorchDType::F16 => (
                decode_le::<2>(&bytes, |b| half::f16::from_ne_bytes(b).to_f32()),
                WeightsDtype::F16,
            ),
            TorchDType::BF16 => (
                decode_le::<2>(&bytes, |b| half::bf16::from_ne_bytes(b).to_f32()),
                WeightsDtype::Bf16,
            ),
            TorchDType::F64 => (
                decode_le::<8>(&bytes, |b| f64::from_ne_bytes(b) as f32),
                WeightsDtype::F64,
            ),
            other => {
                return Err(ModelError::UnsupportedDtype {
                    key,
                    dtype: format!("{other:?}"),
                });
            }
        };
        widest = widest.max(Some(dtype));
        tensors.insert(
            strip_prefix(&key),
            NamedTensor {
                shape: tensor.shape().to_vec(),
                data,
            },
        );
    }
    if tensors.is_empty() {
        return Err(ModelError::Checkpoint {
            source_name: name.to_string(),
            reason: "no tensors found".into(),
        });
    }
    Ok((
        tensors,
        WeightsInfo {
            format: WeightsFormat::TorchCheckpoint,
            dtype: widest.unwrap_or(WeightsDtype::F32),
            metadata: BTreeMap::new(),
            ignored_keys: Vec::new(),
        },
    ))
}

fn strip_prefix(key: &str) -> String {
    key.strip_prefix(DDP_PREFIX).unwrap_or(key).to_string()
}

/// The config implied by the shapes of the first and last convs (files without metadata,
/// e.g. the authors' checkpoints).
fn infer_config(tensors: &TensorMap) -> Result<GeneratorConfig> {
    let first = "in_conv_down1.mpconv.0.weight";
    let last = "out.0.weight";
    let get = |key: &str| {
        let t = tensors.get(key).ok_or_else(|| ModelError::MissingKey {
            key: key.to_string(),
        })?;
        match t.shape.as_slice() {
            &[cout, cin, _, _] => Ok((cout, cin)),
            _ => Err(ModelError::ShapeMismatch {
                key: key.to_string(),
                expected: vec![0, 0, 3, 3],
                got: t.shape.clone(),
            }),
        }
    };
    let (base_width, in_channels) = get(first)?;
    let (out_channels, _) = get(last)?;
    let config = GeneratorConfig {
        in_channels,
        out_channels,
        base_width,
        light_field: LightFieldMap::Paper,
        variant: crate::style::Variant::Paper,
        detail_retention: false,
    };
    config.validate()?;
    Ok(config)
}

/// Hands out the tensors of a state dict to the module builders, checking each key and
/// shape, and remembers what was used.
struct TensorSource {
    map: TensorMap,
    device: Device,
}

impl TensorSource {
    fn take(&mut self, key: &str, expected: &[usize]) -> Result<TensorData> {
        let t = self.map.remove(key).ok_or_else(|| ModelError::MissingKey {
            key: key.to_string(),
        })?;
        if t.shape != expected {
            return Err(ModelError::ShapeMismatch {
                key: key.to_string(),
                expected: expected.to_vec(),
                got: t.shape,
            });
        }
        Ok(TensorData::new(t.data, t.shape))
    }

    /// `prefix.weight` `[cout, cin, k, k]` and `prefix.bias` `[cout]`.
    fn conv(
        &mut self,
        prefix: &str,
        cin: usize,
        cout: usize,
        kernel: usize,
        stride: usize,
    ) -> Result<Conv2d> {
        let w = self.take(&format!("{prefix}.weight"), &[cout, cin, kernel, kernel])?;
        let b = self.take(&format!("{prefix}.bias"), &[cout])?;
        Ok(conv_from_tensors(
            Tensor::<4>::from_data(w, &self.device),
            Tensor::<1>::from_data(b, &self.device),
            stride,
        ))
    }

    /// Keys left over: the unused norms are returned, anything else is an error.
    fn finish(self) -> Result<Vec<String>> {
        let mut ignored = Vec::new();
        for key in self.map.into_keys() {
            if key.contains(UNUSED_NORM_MARKER) {
                ignored.push(key);
            } else {
                return Err(ModelError::UnexpectedKey { key });
            }
        }
        Ok(ignored)
    }
}

fn load_down(src: &mut TensorSource, prefix: &str, cin: usize, c: usize) -> Result<Down> {
    Ok(Down {
        conv: src.conv(&format!("{prefix}.mpconv.0"), cin, c, 3, 2)?,
        block: load_block(src, &format!("{prefix}.mpconv.2"), c)?,
    })
}

fn load_block(src: &mut TensorSource, prefix: &str, c: usize) -> Result<BasicBlock> {
    let r = c / ATTENTION_REDUCTION;
    Ok(BasicBlock {
        conk3: src.conv(&format!("{prefix}.conk3"), c, c, 3, 1)?,
        conk1: src.conv(&format!("{prefix}.conk1"), c, c, 1, 1)?,
        sa: SpatialAttention {
            reduce: src.conv(&format!("{prefix}.SA.spatial_pool.0"), c, r, 1, 1)?,
            expand: src.conv(&format!("{prefix}.SA.spatial_pool.2"), r, 1, 1, 1)?,
        },
        ca: ChannelAttention {
            reduce: src.conv(&format!("{prefix}.CA.channel_map.0"), c, r, 1, 1)?,
            expand: src.conv(&format!("{prefix}.CA.channel_map.2"), r, c, 1, 1)?,
        },
    })
}

fn load_up(src: &mut TensorSource, prefix: &str, c: usize) -> Result<Up> {
    Ok(Up::from_conv(src.conv(
        &format!("{prefix}.up.0"),
        c,
        2 * c,
        3,
        1,
    )?))
}

fn save_down(sink: &mut TensorMap, prefix: &str, down: &Down, cin: usize, c: usize) -> Result<()> {
    put_conv(
        sink,
        &format!("{prefix}.mpconv.0"),
        &down.conv,
        [c, cin, 3, 3],
    )?;
    let p = format!("{prefix}.mpconv.2");
    let b = &down.block;
    let r = c / ATTENTION_REDUCTION;
    put_conv(sink, &format!("{p}.conk3"), &b.conk3, [c, c, 3, 3])?;
    put_conv(sink, &format!("{p}.conk1"), &b.conk1, [c, c, 1, 1])?;
    put_conv(
        sink,
        &format!("{p}.SA.spatial_pool.0"),
        &b.sa.reduce,
        [r, c, 1, 1],
    )?;
    put_conv(
        sink,
        &format!("{p}.SA.spatial_pool.2"),
        &b.sa.expand,
        [1, r, 1, 1],
    )?;
    put_conv(
        sink,
        &format!("{p}.CA.channel_map.0"),
        &b.ca.reduce,
        [r, c, 1, 1],
    )?;
    put_conv(
        sink,
        &format!("{p}.CA.channel_map.2"),
        &b.ca.expand,
        [c, r, 1, 1],
    )?;
    // The unused InstanceNorm2d(c/2, affine=True), at PyTorch's init (weight 1, bias 0).
    let n = c / 2;
    sink.insert(
        format!("{p}.norm.weight"),
        NamedTensor {
            shape: vec![n],
            data: vec![1.0; n],
        },
    );
    sink.insert(
        format!("{p}.norm.bias"),
        NamedTensor {
            shape: vec![n],
            data: vec![0.0; n],
        },
    );
    Ok(())
}

fn put_conv(sink: &mut TensorMap, prefix: &str, conv: &Conv2d, shape: [usize; 4]) -> Result<()> {
    let weight = conv.weight.val();
    let key = format!("{prefix}.weight");
    if weight.dims() != shape {
        return Err(ModelError::ShapeMismatch {
            key,
            expected: shape.to_vec(),
            got: weight.dims().to_vec(),
        });
    }
    sink.insert(key, read_tensor(weight)?);
    let key = format!("{prefix}.bias");
    let bias = conv
        .bias
        .as_ref()
        .ok_or_else(|| ModelError::MissingKey { key: key.clone() })?
        .val();
    if bias.dims() != [shape[0]] {
        return Err(ModelError::ShapeMismatch {
            key,
            expected: vec![shape[0]],
            got: bias.dims().to_vec(),
        });
    }
    sink.insert(key, read_tensor(bias)?);
    Ok(())
}

/// Copies a tensor back to the host as f32.
pub fn read_tensor<const D: usize>(t: Tensor<D>) -> Result<NamedTensor> {
    let shape = t.dims().to_vec();
    let data = t
        .try_into_data()
        .map_err(|e| ModelError::Backend(e.to_string()))?
        .convert_dtype_checked()?;
    Ok(NamedTensor { shape, data })
}

/// Converts tensor data of any float dtype to a `Vec<f32>`.
trait ToF32Vec {
    fn convert_dtype_checked(self) -> Result<Vec<f32>>;
}

impl ToF32Vec for TensorData {
    fn convert_dtype_checked(self) -> Result<Vec<f32>> {
        self.try_cast_as::<f32>()
            .and_then(|d| d.try_into_vec::<f32>())
            .map_err(|e| ModelError::Backend(e.to_string()))
    }
}

/// Writes `bytes` to `path` by uwnr-core's atomic, durable rule ([`uwnr_core::io::write_atomic`]:
/// a synced temporary file in the same directory renamed into place).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    uwnr_core::io::write_atomic_bytes(path, bytes).map_err(|e| match e {
        uwnr_core::CoreError::Io { path, source } => ModelError::Io { path, source },
        other => ModelError::Core(other),
    })
}

/// A temporary file removed on drop (for checkpoints given as bytes).
struct TempFile {
    path: PathBuf,
}

impl TempFile {
    fn write(bytes: &[u8]) -> Result<Self> {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path =
            std::env::temp_dir().join(format!("uwnr-weights-{}-{n}.pth.tmp", std::process::id()));
        let file = Self { path };
        let mut f = std::fs::File::create(&file.path).map_err(|source| ModelError::Io {
            path: file.path.clone(),
            source,
        })?;
        f.write_all(bytes).map_err(|source| ModelError::Io {
            path: file.path.clone(),
            source,
        })?;
        Ok(file)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> (Generator, GeneratorConfig, Device) {
        let device = Device::flex();
        device.seed(3);
        let cfg = GeneratorConfig::with_base_width(8);
        (cfg.init(&device).unwrap(), cfg, device)
    }

    #[test]
    fn key_set_matches_the_released_state_dict() {
        let (g, cfg, _) = tiny();
        let map = generator_to_tensors(&g, &cfg).unwrap();
        // 4 levels x (7 convs x 2 + norm x 2) + 4 ups x 2 + out x 2.
        assert_eq!(map.len(), 4 * 16 + 4 * 2 + 2);
        for key in [
            "in_conv_down1.mpconv.0.weight",
            "in_conv_down1.mpconv.2.conk3.weight",
            "down2.mpconv.2.conk1.bias",
            "down3.mpconv.2.SA.spatial_pool.0.weight",
            "down4.mpconv.2.SA.spatial_pool.2.bias",
            "down4.mpconv.2.CA.channel_map.2.bias",
            "down4.mpconv.2.norm.weight",
            "up1.up.0.weight",
            "up4.up.0.bias",
            "out.0.weight",
        ] {
            assert!(map.contains_key(key), "{key}");
        }
        assert_eq!(
            map["down4.mpconv.2.CA.channel_map.2.weight"].shape,
            [64, 16, 1, 1]
        );
        assert_eq!(map["out.0.weight"].shape, [3, 4, 3, 3]);
        let total: usize = map.values().map(|t| t.data.len()).sum();
        assert_eq!(total, crate::config::param_count(&cfg, true));
    }

    #[test]
    fn errors_name_the_key() {
        let (g, cfg, device) = tiny();
        let map = generator_to_tensors(&g, &cfg).unwrap();

        let mut missing = map.clone();
        missing.remove("down3.mpconv.2.CA.channel_map.0.bias");
        let err = generator_from_tensors(&cfg, missing, &device).unwrap_err();
        assert!(
            matches!(&err, ModelError::MissingKey { key } if key == "down3.mpconv.2.CA.channel_map.0.bias"),
            "{err}"
        );

        let mut extra = map.clone();
        extra.insert(
            "down3.mpconv.2.extra.weight".into(),
            NamedTensor {
                shape: vec![1],
                data: vec![0.0],
            },
        );
        let err = generator_from_tensors(&cfg, extra, &device).unwrap_err();
        assert!(
            matches!(&err, ModelError::UnexpectedKey { key } if key == "down3.mpconv.2.extra.weight"),
            "{err}"
        );

        let (_, ignored) = generator_from_tensors(&cfg, map, &device).unwrap();
        assert_eq!(ignored.len(), 8);
        assert!(ignored.iter().all(|k| k.contains(".norm.")));
    }

    #[test]
    fn detects_formats_by_content() {
        assert_eq!(
            detect_format(b"PK\x03\x04rest", "x").unwrap(),
            WeightsFormat::TorchCheckpoint
        );
        assert_eq!(
            detect_format(b"\x10\x00\x00\x00\x00\x00\x00\x00{\"a\":1}", "x").unwrap(),
            WeightsFormat::Safetensors
        );
        // A header of 7,552 bytes: the first byte is 0x80, the pickle protocol byte.
        assert_eq!(
            detect_format(b"\x80\x1d\x00\x00\x00\x00\x00\x00{\"a\":1}", "x").unwrap(),
            WeightsFormat::Safetensors
        );
        assert_eq!(
            detect_format(b"\x80\x02\x8a\x0a\x6c\xfc\x9c\x46\xf9\x20\x6a", "x").unwrap(),
            WeightsFormat::TorchCheckpoint
        );
        let err = detect_format(b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR", "photo.png").unwrap_err();
        assert!(err.to_string().contains("photo.png"), "{err}");
    }
}
