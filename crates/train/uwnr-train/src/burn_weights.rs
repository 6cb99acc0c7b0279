//! The state-dict keys (`uwnr_model::weights::keys`) mapped to burn's [`Generator`], both ways:
//! a state dict assigned to a new module, and a module's tensors read back under the authors'
//! keys; and the generator loaded from and saved to a weights file. The engine's mapping of the
//! same keys is `uwnr-model`'s `engine_keys.rs`.

use std::collections::BTreeMap;
use std::path::Path;

use burn::nn::conv::Conv2d;
use burn::tensor::{Device, Tensor, TensorData};
use uwnr_model::weights::keys::{
    ConvKey, DownKeys, KeySource, down_keys, map_levels, out_key, up_keys,
};
use uwnr_model::{
    GeneratorConfig, LoadedWeights, ModelError, NamedTensor, Result, TensorMap, WeightsDtype,
    WeightsInfo, read_weights, read_weights_from_bytes, save_weights,
};

use crate::generator::{
    BasicBlock, ChannelAttention, Down, Generator, SpatialAttention, Up, conv_from_tensors,
};

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

/// Saves a generator as safetensors under the authors' keys, with `config` as JSON in the
/// metadata and `metadata` beside it ([`uwnr_model::save_weights`]: written atomically).
pub fn save_generator(
    generator: &Generator,
    config: &GeneratorConfig,
    path: &Path,
    dtype: WeightsDtype,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    save_weights(
        &generator_to_tensors(generator, config)?,
        config,
        path,
        dtype,
        metadata,
    )
}

/// Builds a generator for `config` from a state dict. Returns it with the keys that were
/// present but unused (the `.norm.` keys). Every other key must be consumed exactly.
pub fn generator_from_tensors(
    config: &GeneratorConfig,
    tensors: TensorMap,
    device: &Device,
) -> Result<(Generator, Vec<String>)> {
    config.validate()?;
    let mut src = KeySource::new(tensors);
    let [in_conv_down1, down2, down3, down4] =
        map_levels(down_keys(config), |keys| load_down(&mut src, &keys, device))?;
    let [up1, up2, up3, up4] = map_levels(up_keys(config), |key| {
        Ok(Up::from_conv(load_conv(&mut src, &key, 1, device)?))
    })?;
    let out = load_conv(&mut src, &out_key(config), 1, device)?;
    let ignored = src.finish()?;
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
    for (down, keys) in downs.into_iter().zip(down_keys(config)) {
        save_down(&mut sink, &keys, down)?;
    }
    let ups = [
        &generator.up1,
        &generator.up2,
        &generator.up3,
        &generator.up4,
    ];
    for (up, key) in ups.into_iter().zip(up_keys(config)) {
        put_conv(&mut sink, &key, &up.conv)?;
    }
    put_conv(&mut sink, &out_key(config), &generator.out)?;
    Ok(sink)
}

/// The conv under `key` with `stride`.
fn load_conv(src: &mut KeySource, key: &ConvKey, stride: usize, device: &Device) -> Result<Conv2d> {
    let (w, b) = src.conv(key)?;
    Ok(conv_from_tensors(
        Tensor::<4>::from_data(TensorData::new(w, key.weight_shape()), device),
        Tensor::<1>::from_data(TensorData::new(b, [key.cout]), device),
        stride,
    ))
}

fn load_down(src: &mut KeySource, keys: &DownKeys, device: &Device) -> Result<Down> {
    Ok(Down {
        conv: load_conv(src, &keys.stem, 2, device)?,
        block: BasicBlock {
            conk3: load_conv(src, &keys.conk3, 1, device)?,
            conk1: load_conv(src, &keys.conk1, 1, device)?,
            sa: SpatialAttention {
                reduce: load_conv(src, &keys.sa_reduce, 1, device)?,
                expand: load_conv(src, &keys.sa_expand, 1, device)?,
            },
            ca: ChannelAttention {
                reduce: load_conv(src, &keys.ca_reduce, 1, device)?,
                expand: load_conv(src, &keys.ca_expand, 1, device)?,
            },
        },
    })
}

fn save_down(sink: &mut TensorMap, keys: &DownKeys, down: &Down) -> Result<()> {
    put_conv(sink, &keys.stem, &down.conv)?;
    let b = &down.block;
    put_conv(sink, &keys.conk3, &b.conk3)?;
    put_conv(sink, &keys.conk1, &b.conk1)?;
    put_conv(sink, &keys.sa_reduce, &b.sa.reduce)?;
    put_conv(sink, &keys.sa_expand, &b.sa.expand)?;
    put_conv(sink, &keys.ca_reduce, &b.ca.reduce)?;
    put_conv(sink, &keys.ca_expand, &b.ca.expand)?;
    // The unused InstanceNorm2d(c/2, affine=True), at PyTorch's init (weight 1, bias 0).
    let n = keys.norm.width;
    sink.insert(
        keys.norm.weight(),
        NamedTensor {
            shape: vec![n],
            data: vec![1.0; n],
        },
    );
    sink.insert(
        keys.norm.bias(),
        NamedTensor {
            shape: vec![n],
            data: vec![0.0; n],
        },
    );
    Ok(())
}

fn put_conv(sink: &mut TensorMap, key: &ConvKey, conv: &Conv2d) -> Result<()> {
    let shape = key.weight_shape();
    let weight = conv.weight.val();
    let name = key.weight();
    if weight.dims() != shape {
        return Err(ModelError::ShapeMismatch {
            key: name,
            expected: shape.to_vec(),
            got: weight.dims().to_vec(),
        });
    }
    sink.insert(name, read_tensor(weight)?);
    let name = key.bias();
    let bias = conv
        .bias
        .as_ref()
        .ok_or_else(|| ModelError::MissingKey { key: name.clone() })?
        .val();
    if bias.dims() != [shape[0]] {
        return Err(ModelError::ShapeMismatch {
            key: name,
            expected: vec![shape[0]],
            got: bias.dims().to_vec(),
        });
    }
    sink.insert(name, read_tensor(bias)?);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generator::GeneratorInit;

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
        assert_eq!(total, uwnr_model::param_count(&cfg, true));
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
}
