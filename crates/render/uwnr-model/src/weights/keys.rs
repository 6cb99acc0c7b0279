//! The names in a weights file, spelled once: the authors' PyTorch state-dict keys (released
//! `model/FSU2.py`) with the shapes a [`GeneratorConfig`] gives their tensors, the checkpoint's
//! nesting and prefix, and uwnr's metadata keys. Both mappings of the keys, to burn's module
//! (`burn_keys.rs`) and to the engine's weights (`engine_keys.rs`), take the names from here.
//!
//! The key scheme, per encoder level `P` in `in_conv_down1`, `down2`, `down3`, `down4`:
//! `P.mpconv.0.{weight,bias}` (stride-2 conv), `P.mpconv.2.conk3.*`, `P.mpconv.2.conk1.*`,
//! `P.mpconv.2.SA.spatial_pool.{0,2}.*`, `P.mpconv.2.CA.channel_map.{0,2}.*` and the unused
//! `P.mpconv.2.norm.{weight,bias}`; per decoder level `upK.up.0.*`; and `out.0.*`.

use super::{NamedTensor, TensorMap};
use crate::config::{ATTENTION_REDUCTION, GeneratorConfig, LEVELS, LightFieldMap};
use crate::error::{ModelError, Result};
use crate::variant::Variant;

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
const UNUSED_NORM_MARKER: &str = ".norm.";
/// Prefixes of the encoder levels in the state dict.
const DOWN_PREFIXES: [&str; LEVELS] = ["in_conv_down1", "down2", "down3", "down4"];
/// Prefixes of the decoder levels in the state dict.
const UP_PREFIXES: [&str; LEVELS] = ["up1", "up2", "up3", "up4"];
/// Prefix of the output convolution (`out.1` is the tanh).
const OUT_PREFIX: &str = "out.0";

/// `prefix.weight`.
fn weight_key(prefix: &str) -> String {
    format!("{prefix}.weight")
}

/// `prefix.bias`.
fn bias_key(prefix: &str) -> String {
    format!("{prefix}.bias")
}

/// The stride-2 conv of encoder level `level_prefix`.
fn stem_prefix(level_prefix: &str) -> String {
    format!("{level_prefix}.mpconv.0")
}

/// A convolution's two keys, `prefix.weight` `[cout, cin, k, k]` and `prefix.bias` `[cout]`.
pub struct ConvKey {
    /// The key without `.weight` / `.bias`.
    pub prefix: String,
    /// Input channels.
    pub cin: usize,
    /// Output channels.
    pub cout: usize,
    /// Kernel side.
    pub k: usize,
}

impl ConvKey {
    fn new(prefix: String, cin: usize, cout: usize, k: usize) -> Self {
        Self {
            prefix,
            cin,
            cout,
            k,
        }
    }

    /// Key of the weight.
    pub fn weight(&self) -> String {
        weight_key(&self.prefix)
    }

    /// Key of the bias.
    pub fn bias(&self) -> String {
        bias_key(&self.prefix)
    }

    /// Shape of the weight, PyTorch order.
    pub fn weight_shape(&self) -> [usize; 4] {
        [self.cout, self.cin, self.k, self.k]
    }
}

/// The unused affine `InstanceNorm2d(width)` of a block: `prefix.weight` and `prefix.bias`,
/// both `[width]`.
pub struct NormKey {
    /// The key without `.weight` / `.bias`.
    pub prefix: String,
    /// Channels.
    pub width: usize,
}

impl NormKey {
    /// Key of the weight.
    pub fn weight(&self) -> String {
        weight_key(&self.prefix)
    }

    /// Key of the bias.
    pub fn bias(&self) -> String {
        bias_key(&self.prefix)
    }
}

/// The keys of one encoder level `P` of width `c` (`r = c / 4`): the stride-2 conv
/// `P.mpconv.0` and the block `P.mpconv.2`.
pub struct DownKeys {
    /// `P.mpconv.0`: conv3x3 stride 2, `cin -> c`.
    pub stem: ConvKey,
    /// `P.mpconv.2.conk3`: conv3x3 `c -> c`.
    pub conk3: ConvKey,
    /// `P.mpconv.2.conk1`: conv1x1 `c -> c`.
    pub conk1: ConvKey,
    /// `P.mpconv.2.SA.spatial_pool.0`: conv1x1 `c -> r`.
    pub sa_reduce: ConvKey,
    /// `P.mpconv.2.SA.spatial_pool.2`: conv1x1 `r -> 1`.
    pub sa_expand: ConvKey,
    /// `P.mpconv.2.CA.channel_map.0`: conv1x1 `c -> r`.
    pub ca_reduce: ConvKey,
    /// `P.mpconv.2.CA.channel_map.2`: conv1x1 `r -> c`.
    pub ca_expand: ConvKey,
    /// `P.mpconv.2.norm`: the unused `InstanceNorm2d(c / 2)`.
    pub norm: NormKey,
}

/// The keys of the encoder levels of `config`, in order.
pub fn down_keys(config: &GeneratorConfig) -> [DownKeys; LEVELS] {
    std::array::from_fn(|level| {
        let prefix = DOWN_PREFIXES[level];
        let cin = match level {
            0 => config.in_channels,
            _ => config.level_width(level - 1),
        };
        let c = config.level_width(level);
        let r = c / ATTENTION_REDUCTION;
        let b = format!("{prefix}.mpconv.2");
        DownKeys {
            stem: ConvKey::new(stem_prefix(prefix), cin, c, 3),
            conk3: ConvKey::new(format!("{b}.conk3"), c, c, 3),
            conk1: ConvKey::new(format!("{b}.conk1"), c, c, 1),
            sa_reduce: ConvKey::new(format!("{b}.SA.spatial_pool.0"), c, r, 1),
            sa_expand: ConvKey::new(format!("{b}.SA.spatial_pool.2"), r, 1, 1),
            ca_reduce: ConvKey::new(format!("{b}.CA.channel_map.0"), c, r, 1),
            ca_expand: ConvKey::new(format!("{b}.CA.channel_map.2"), r, c, 1),
            norm: NormKey {
                prefix: format!("{b}.norm"),
                width: c / 2,
            },
        }
    })
}

/// The keys of the decoder levels of `config`, in order: `upK.up.0`, conv3x3 `c -> 2c` at the
/// width `c` of encoder level `LEVELS - K`.
pub fn up_keys(config: &GeneratorConfig) -> [ConvKey; LEVELS] {
    std::array::from_fn(|i| {
        let c = config.level_width(LEVELS - 1 - i);
        ConvKey::new(format!("{}.up.0", UP_PREFIXES[i]), c, 2 * c, 3)
    })
}

/// The output conv `out.0`: conv3x3 `c / 2 -> out_channels`.
pub fn out_key(config: &GeneratorConfig) -> ConvKey {
    ConvKey::new(
        OUT_PREFIX.to_string(),
        config.decoder_out_width(),
        config.out_channels,
        3,
    )
}

/// `key` without the DistributedDataParallel prefix.
pub fn strip_prefix(key: &str) -> String {
    key.strip_prefix(DDP_PREFIX).unwrap_or(key).to_string()
}

/// `f` applied to each level's item in order, stopping at the first error.
pub fn map_levels<T, U>(items: [T; LEVELS], f: impl FnMut(T) -> Result<U>) -> Result<[U; LEVELS]> {
    let built = items.into_iter().map(f).collect::<Result<Vec<U>>>()?;
    let n = built.len();
    built
        .try_into()
        .map_err(|_| ModelError::InvalidOptions(format!("{n} levels built, expected {LEVELS}")))
}

/// Hands out the tensors of a state dict to a mapping, checking each key and shape; what is
/// left at the end may only be the unused norms.
pub struct KeySource(TensorMap);

impl KeySource {
    pub fn new(tensors: TensorMap) -> Self {
        Self(tensors)
    }

    /// The values under `key`, which must have shape `expected`.
    pub fn take(&mut self, key: &str, expected: &[usize]) -> Result<Vec<f32>> {
        let NamedTensor { shape, data } =
            self.0.remove(key).ok_or_else(|| ModelError::MissingKey {
                key: key.to_string(),
            })?;
        if shape != expected {
            return Err(ModelError::ShapeMismatch {
                key: key.to_string(),
                expected: expected.to_vec(),
                got: shape,
            });
        }
        Ok(data)
    }

    /// A convolution's weight and bias.
    pub fn conv(&mut self, conv: &ConvKey) -> Result<(Vec<f32>, Vec<f32>)> {
        let weight = self.take(&conv.weight(), &conv.weight_shape())?;
        let bias = self.take(&conv.bias(), &[conv.cout])?;
        Ok((weight, bias))
    }

    /// Keys left over: the unused norms are returned, anything else is an error.
    pub fn finish(self) -> Result<Vec<String>> {
        let mut ignored = Vec::new();
        for key in self.0.into_keys() {
            if key.contains(UNUSED_NORM_MARKER) {
                ignored.push(key);
            } else {
                return Err(ModelError::UnexpectedKey { key });
            }
        }
        Ok(ignored)
    }
}

/// The config implied by the shapes of the first and last convs (files without metadata,
/// e.g. the authors' checkpoints).
pub fn infer_config(tensors: &TensorMap) -> Result<GeneratorConfig> {
    let first = weight_key(&stem_prefix(DOWN_PREFIXES[0]));
    let last = weight_key(OUT_PREFIX);
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
    let (base_width, in_channels) = get(&first)?;
    let (out_channels, _) = get(&last)?;
    let config = GeneratorConfig {
        in_channels,
        out_channels,
        base_width,
        light_field: LightFieldMap::Paper,
        variant: Variant::Paper,
        detail_retention: false,
        anchor: crate::config::AnchorKind::Reinhard,
        correction: crate::config::Correction::Network,
    };
    config.validate()?;
    Ok(config)
}

/// Every conv key of `config`, encoder levels first.
fn conv_keys(config: &GeneratorConfig) -> Vec<ConvKey> {
    let mut keys = Vec::new();
    for d in down_keys(config) {
        keys.extend([
            d.stem,
            d.conk3,
            d.conk1,
            d.sa_reduce,
            d.sa_expand,
            d.ca_reduce,
            d.ca_expand,
        ]);
    }
    keys.extend(up_keys(config));
    keys.push(out_key(config));
    keys
}

/// A state dict of `config` with small seeded pseudo-random weights (uniform, scaled by
/// `1/sqrt(fan_in)`, no training framework needed): networks for tests and benchmarks that
/// need some weights, not trained ones. As a freshly initialised module does, the anchored
/// variant's output conv is zero (the network starts at its anchor). The unused norms are left
/// out.
#[must_use]
pub fn seeded_tensors(config: &GeneratorConfig, seed: u64) -> TensorMap {
    // SplitMix64: a fixed, dependency-free stream.
    let mut state = seed;
    let mut next = move || {
        let z = uwnr_core::seed::mix(state);
        state = state.wrapping_add(uwnr_core::seed::GAMMA);
        (z >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    let mut map = TensorMap::new();
    let out = out_key(config).prefix;
    for key in conv_keys(config) {
        let shape = key.weight_shape();
        let scale = if config.variant == Variant::Anchored && key.prefix == out {
            0.0
        } else {
            1.0 / ((key.cin * key.k * key.k) as f32).sqrt()
        };
        let n: usize = shape.iter().product();
        let weight = (0..n).map(|_| next() * scale).collect();
        let bias = (0..key.cout).map(|_| next() * scale).collect();
        map.insert(
            key.weight(),
            NamedTensor {
                shape: shape.to_vec(),
                data: weight,
            },
        );
        map.insert(
            key.bias(),
            NamedTensor {
                shape: vec![key.cout],
                data: bias,
            },
        );
    }
    map
}

/// Adds the unused InstanceNorm keys that `tensors` lacks, at PyTorch's init (weight 1, bias
/// 0), so that a saved file carries the authors' full key set.
pub fn add_unused_norms(config: &GeneratorConfig, tensors: &mut TensorMap) {
    for d in down_keys(config) {
        let n = d.norm.width;
        for (key, value) in [(d.norm.weight(), 1.0), (d.norm.bias(), 0.0)] {
            tensors.entry(key).or_insert_with(|| NamedTensor {
                shape: vec![n],
                data: vec![value; n],
            });
        }
    }
}
