//! The containers weights come in, read and written: safetensors (any float dtype, with its
//! `__metadata__`) and PyTorch `torch.save` checkpoints (zip or legacy pickle, read through
//! the `pytorch-reader` crate, which needs neither PyTorch nor burn; the state dict bare or
//! nested under the authors' `G1`), told apart by their first bytes. Every tensor is decoded to f32 under its key, the DDP `module.` prefix stripped.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use pytorch_reader::DType as TorchDType;
use pytorch_reader::{PytorchError, PytorchReader};
use safetensors::{Dtype, SafeTensors, tensor::TensorView};

use super::keys::{CHECKPOINT_STATE_KEY, strip_prefix};
use super::{NamedTensor, TensorMap, WeightsDtype, WeightsFormat, WeightsInfo};
use crate::error::{ModelError, Result};

/// Zip local-file-header magic: `torch.save` (PyTorch >= 1.6) writes a zip archive.
const ZIP_MAGIC: &[u8; 4] = b"PK\x03\x04";
/// A pickle stream opens with the PROTO opcode: legacy (< 1.6) `torch.save` files.
const PICKLE_PROTO: u8 = 0x80;
/// Length of the little-endian u64 header size that opens a safetensors file.
const SAFETENSORS_LEN_BYTES: usize = 8;
/// Serializes tensors to safetensors bytes with `metadata`.
pub(super) fn serialize_tensors(
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
pub(super) fn detect_format(head: &[u8], name: &str) -> Result<WeightsFormat> {
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

/// Every tensor of a safetensors file (any network), with the file's facts.
pub(super) fn read_safetensors_tensors(
    bytes: &[u8],
    name: &str,
) -> Result<(TensorMap, WeightsInfo)> {
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

/// Every tensor of a PyTorch checkpoint (a state dict, or one nested under `G1`).
pub(super) fn read_checkpoint_tensors(path: &Path, name: &str) -> Result<(TensorMap, WeightsInfo)> {
    let ck_err = |e: PytorchError| ModelError::Checkpoint {
        source_name: name.to_string(),
        source: e.into(),
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
            source: e.into(),
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
            source: "no tensors found".into(),
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

#[cfg(test)]
mod tests {
    use super::*;

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
