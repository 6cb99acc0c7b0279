//! Shallow-UWnet weights as safetensors under the released model's state-dict keys
//! (`input.weight`, `blocks.0.conv.weight`, `blocks.0.conv1.weight`, ..., `output.weight`),
//! with the config in the metadata. PyTorch state dicts (`torch.save(model.state_dict())`) load
//! too; the released training script pickles whole modules, which need re-saving as a state
//! dict first.

use std::collections::BTreeMap;
use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use uwnr_model::{TensorMap, WeightsDtype, WeightsInfo, read_tensor_file, write_tensor_file};
use uwnr_train::read_tensor;

use crate::error::{EnhanceError, Result};
use crate::model::{IMAGE_CHANNELS, KERNEL, ShallowUwnet, ShallowUwnetConfig, conv_from_weight};

/// Safetensors metadata key of the [`ShallowUwnetConfig`] (JSON).
pub const CONFIG_METADATA_KEY: &str = "uwnr.enhance.config";

/// The state-dict keys and shapes of a network of `config`, in order.
#[must_use]
pub fn expected_tensors(config: &ShallowUwnetConfig) -> Vec<(String, [usize; 4])> {
    let (w, k) = (config.width, KERNEL);
    let mut out = vec![("input.weight".to_string(), [w, IMAGE_CHANNELS, k, k])];
    for i in 0..config.blocks {
        out.push((format!("blocks.{i}.conv.weight"), [w, w, k, k]));
        out.push((
            format!("blocks.{i}.conv1.weight"),
            [w - IMAGE_CHANNELS, w, k, k],
        ));
    }
    out.push(("output.weight".to_string(), [IMAGE_CHANNELS, w, k, k]));
    out
}

/// The config stored in the metadata, or read off the tensor shapes.
fn config_of(tensors: &TensorMap, info: &WeightsInfo, name: &str) -> Result<ShallowUwnetConfig> {
    if let Some(json) = info.metadata.get(CONFIG_METADATA_KEY) {
        let c: ShallowUwnetConfig = serde_json::from_str(json).map_err(|e| {
            EnhanceError::InvalidConfig(format!("{name}: metadata {CONFIG_METADATA_KEY}: {e}"))
        })?;
        c.validate()?;
        return Ok(c);
    }
    let input = tensors
        .get("input.weight")
        .ok_or_else(|| EnhanceError::MissingKey {
            source_name: name.into(),
            key: "input.weight".into(),
        })?;
    let blocks = (0..)
        .take_while(|i| tensors.contains_key(&format!("blocks.{i}.conv.weight")))
        .count();
    let c = ShallowUwnetConfig {
        width: input.shape.first().copied().unwrap_or(0),
        blocks,
        ..ShallowUwnetConfig::default()
    };
    c.validate()?;
    Ok(c)
}

/// Builds the network from a state dict, checking every key and shape.
pub fn from_tensors(
    tensors: &TensorMap,
    config: &ShallowUwnetConfig,
    name: &str,
    device: &Device,
) -> Result<ShallowUwnet> {
    let expected = expected_tensors(config);
    for key in tensors.keys() {
        if !expected.iter().any(|(k, _)| k == key) {
            return Err(EnhanceError::UnexpectedKey {
                source_name: name.into(),
                key: key.clone(),
            });
        }
    }
    let mut convs = Vec::with_capacity(expected.len());
    for (key, shape) in &expected {
        let t = tensors.get(key).ok_or_else(|| EnhanceError::MissingKey {
            source_name: name.into(),
            key: key.clone(),
        })?;
        if t.shape != shape {
            return Err(EnhanceError::ShapeMismatch {
                source_name: name.into(),
                key: key.clone(),
                expected: shape.to_vec(),
                got: t.shape.clone(),
            });
        }
        let weight = Tensor::<4>::from_data(TensorData::new(t.data.clone(), *shape), device);
        convs.push(conv_from_weight(weight));
    }
    let output = convs
        .pop()
        .ok_or_else(|| EnhanceError::InvalidConfig("no tensors".into()))?;
    let mut it = convs.into_iter();
    let input = it
        .next()
        .ok_or_else(|| EnhanceError::InvalidConfig("no tensors".into()))?;
    let mut blocks = Vec::with_capacity(config.blocks);
    while let (Some(conv), Some(conv1)) = (it.next(), it.next()) {
        blocks.push(crate::model::Block { conv, conv1 });
    }
    Ok(ShallowUwnet {
        input,
        blocks,
        output,
    })
}

/// Loads Shallow-UWnet weights (safetensors or a PyTorch state dict).
pub fn load(path: &Path, device: &Device) -> Result<(ShallowUwnet, ShallowUwnetConfig)> {
    let (tensors, info) = read_tensor_file(path)?;
    let name = path.display().to_string();
    let config = config_of(&tensors, &info, &name)?;
    Ok((from_tensors(&tensors, &config, &name, device)?, config))
}

/// The network's state dict under the released keys.
pub fn to_tensors(net: &ShallowUwnet, config: &ShallowUwnetConfig) -> Result<TensorMap> {
    let mut out = TensorMap::new();
    let mut convs = vec![&net.input];
    for b in &net.blocks {
        convs.push(&b.conv);
        convs.push(&b.conv1);
    }
    convs.push(&net.output);
    for ((key, _), conv) in expected_tensors(config).into_iter().zip(convs) {
        out.insert(key, read_tensor(conv.weight.val())?);
    }
    Ok(out)
}

/// Saves the network as safetensors (f32) with its config and `metadata`.
pub fn save(
    net: &ShallowUwnet,
    config: &ShallowUwnetConfig,
    path: &Path,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    let mut meta = metadata.clone();
    meta.insert(
        CONFIG_METADATA_KEY.into(),
        serde_json::to_string(config).map_err(|e| EnhanceError::InvalidConfig(e.to_string()))?,
    );
    write_tensor_file(path, &to_tensors(net, config)?, WeightsDtype::F32, &meta)?;
    Ok(())
}
