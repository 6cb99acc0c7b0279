//! The state-dict keys ([`super::keys`]) mapped to uwnr-engine's [`GeneratorWeights`]: the
//! engine takes the tensors in PyTorch layout as they are. burn's mapping of the same keys is
//! `burn_keys.rs`, beside this one.

use uwnr_engine::{BlockWeights, ConvWeights, DownWeights, GeneratorWeights};

use super::TensorMap;
use super::keys::{ConvKey, KeySource, down_keys, map_levels, out_key, up_keys};
use crate::config::GeneratorConfig;
use crate::error::Result;

/// The engine's weights for `config` from a state dict; every key but the unused norms must
/// be consumed, with the shapes the config implies.
pub fn engine_weights(
    config: &GeneratorConfig,
    tensors: TensorMap,
) -> Result<(GeneratorWeights, Vec<String>)> {
    config.validate()?;
    let mut src = KeySource::new(tensors);
    let downs = map_levels(down_keys(config), |keys| {
        Ok(DownWeights {
            conv: conv(&mut src, &keys.stem)?,
            block: BlockWeights {
                conk3: conv(&mut src, &keys.conk3)?,
                conk1: conv(&mut src, &keys.conk1)?,
                sa_reduce: conv(&mut src, &keys.sa_reduce)?,
                sa_expand: conv(&mut src, &keys.sa_expand)?,
                ca_reduce: conv(&mut src, &keys.ca_reduce)?,
                ca_expand: conv(&mut src, &keys.ca_expand)?,
            },
        })
    })?;
    let ups = map_levels(up_keys(config), |key| conv(&mut src, &key))?;
    let out = conv(&mut src, &out_key(config))?;
    let ignored = src.finish()?;
    let weights = GeneratorWeights { downs, ups, out };
    Ok((weights, ignored))
}

/// The conv under `key`.
fn conv(src: &mut KeySource, key: &ConvKey) -> Result<ConvWeights> {
    let (weight, bias) = src.conv(key)?;
    Ok(ConvWeights {
        cout: key.cout,
        cin: key.cin,
        k: key.k,
        weight,
        bias,
    })
}
