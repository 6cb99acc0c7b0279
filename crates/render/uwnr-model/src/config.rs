//! `GeneratorConfig`: the widths of the MHB-Unet generator (UWNR, Ye et al., CVPR-W 2022, Sec. 3.3;
//! released `model/FSU2.py`, class `Generator`), with its parameter and multiply-accumulate counts.
//!
//! The released network is fixed at 7 input channels (clean RGB, depth, light field), 3 output
//! channels and widths 64/128/256/512 down the encoder. Here the first width is `base_width`
//! and the others double from it, so a narrow network (width 8) for tests is a config change.

use serde::{Deserialize, Serialize};
pub use uwnr_core::lightfield::LightFieldMap;

use crate::error::{ModelError, Result};
pub use crate::variant::Variant;

/// Input channels of the released network: clean RGB (3), depth (1), light-field map (3).
pub const PAPER_IN_CHANNELS: usize = 7;
/// Output channels: the rendered underwater RGB image.
pub const PAPER_OUT_CHANNELS: usize = 3;
/// Width of the first encoder level in the released network (`downsample(7, 64)`).
pub const PAPER_BASE_WIDTH: usize = 64;
/// Number of stride-2 encoder levels (`in_conv_down1`, `down2`, `down3`, `down4`) and of
/// PixelShuffle decoder levels (`up1` .. `up4`).
pub const LEVELS: usize = 4;
/// Widths must be a multiple of this: the attention bottlenecks use `c / 4` channels and the
/// last decoder level `c / 2`, so a multiple of 8 keeps every bottleneck at 2+ channels.
pub const WIDTH_MULTIPLE: usize = 8;
/// Squeeze factor of the spatial and channel attention (`SpatialAttention(chns, 4)`,
/// `ChannelAttention(chns, 4)` in FSU2.py).
pub const ATTENTION_REDUCTION: usize = 4;
/// Height and width must be multiples of this (four stride-2 levels: 2^4).
pub const SIZE_MULTIPLE: usize = 1 << LEVELS;

/// Widths of the MHB-Unet generator. `Default` is the paper's network (11.57M parameters).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneratorConfig {
    /// Channels of the input tensor (7: clean RGB, depth, light field).
    pub in_channels: usize,
    /// Channels of the output image (3).
    pub out_channels: usize,
    /// Width of the first encoder level; level `k` (0-based) has `base_width << k` channels.
    pub base_width: usize,
    /// The light-field map the network was trained with and must be fed (the released network:
    /// `paper`; files without the field are read as `paper`).
    #[serde(default)]
    pub light_field: LightFieldMap,
    /// What the input and output planes mean (`paper`, the released network, or `anchored`:
    /// [`crate::style`]); files without the field are read as `paper`.
    #[serde(default)]
    pub variant: Variant,
    /// The anchored variant's detail retention ([`crate::style::retain_detail`]): the anchor
    /// takes each channel's share of fine detail from the reference. Files without the field
    /// (every model before it, the paper's) are read as `false`, and a `false` is not written,
    /// so their configs stay byte for byte what they were.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub detail_retention: bool,
    /// What the anchored variant's anchor starts from ([`AnchorKind`]); files without the field
    /// are read as `reinhard`, and `reinhard` is not written, so their configs stay as they were.
    #[serde(default, skip_serializing_if = "AnchorKind::is_reinhard")]
    pub anchor: AnchorKind,
    /// Whether the anchored variant's correction is a network or none ([`Correction`]); files
    /// without the field are read as `network`, and `network` is not written, so their configs
    /// stay as they were.
    #[serde(default, skip_serializing_if = "Correction::is_network")]
    pub correction: Correction,
}

/// What corrects the anchored variant's anchor before the depth stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Correction {
    /// The MHB-Unet: smooth gain and offset fields from the clean image, the reference's light
    /// field and the anchor (weights needed).
    #[default]
    Network,
    /// None: the anchor goes to the depth stage as it is; no network is loaded or run and no
    /// light field is computed (the bundled model).
    None,
}

impl Correction {
    /// Whether this is the default, `network`.
    #[must_use]
    pub fn is_network(&self) -> bool {
        *self == Self::Network
    }
}

/// What the anchored variant's anchor starts from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AnchorKind {
    /// A Reinhard transfer to the reference's lαβ statistics, then the reference's light field
    /// (the models up to v4): the reference's colours and layout replace the photo's.
    #[default]
    Reinhard,
    /// The reference's water predicted from its statistics ([`crate::water`]) applied to the
    /// photo's own colours, with no light-field retention (real pairs differ by a global
    /// per-channel gain and offset, not by a layout).
    Water,
}

impl AnchorKind {
    /// Whether this is the default, `reinhard`.
    #[must_use]
    pub fn is_reinhard(&self) -> bool {
        *self == Self::Reinhard
    }
}

impl Default for GeneratorConfig {
    fn default() -> Self {
        Self {
            in_channels: PAPER_IN_CHANNELS,
            out_channels: PAPER_OUT_CHANNELS,
            base_width: PAPER_BASE_WIDTH,
            light_field: LightFieldMap::Paper,
            variant: Variant::Paper,
            detail_retention: false,
            anchor: AnchorKind::Reinhard,
            correction: Correction::Network,
        }
    }
}

impl GeneratorConfig {
    /// The paper's config with another first-level width (e.g. 8 for fast tests).
    #[must_use]
    pub fn with_base_width(base_width: usize) -> Self {
        Self {
            base_width,
            ..Self::default()
        }
    }

    /// The anchored variant ([`crate::style`]) at `base_width`, fed the `absolute` light field.
    #[must_use]
    pub fn anchored(base_width: usize) -> Self {
        let (in_channels, out_channels) = Variant::Anchored.channels();
        Self {
            in_channels,
            out_channels,
            base_width,
            light_field: LightFieldMap::Absolute,
            variant: Variant::Anchored,
            detail_retention: false,
            anchor: AnchorKind::Reinhard,
            correction: Correction::Network,
        }
    }

    /// Whether a network runs (weights are needed): every config but an anchored one whose
    /// correction is none.
    #[must_use]
    pub fn runs_network(&self) -> bool {
        self.variant == Variant::Paper || self.correction == Correction::Network
    }

    /// Whether renders read the reference's light field: the network's input, or the Reinhard
    /// anchor's light-field retention.
    #[must_use]
    pub fn reads_light_field(&self) -> bool {
        self.runs_network() || self.anchor == AnchorKind::Reinhard
    }

    /// Checks that every width is usable: non-zero channel counts and a base width that is a
    /// positive multiple of [`WIDTH_MULTIPLE`].
    pub fn validate(&self) -> Result<()> {
        if self.detail_retention && self.variant != Variant::Anchored {
            return Err(ModelError::InvalidConfig {
                field: "detail_retention",
                value: 1,
                reason: "only the anchored variant has an anchor to retain detail in".into(),
            });
        }
        if self.anchor != AnchorKind::Reinhard && self.variant != Variant::Anchored {
            return Err(ModelError::InvalidConfig {
                field: "anchor",
                value: 1,
                reason: "only the anchored variant has an anchor".into(),
            });
        }
        if self.correction == Correction::None && self.variant != Variant::Anchored {
            return Err(ModelError::InvalidConfig {
                field: "correction",
                value: 0,
                reason: "only the anchored variant can render without a network".into(),
            });
        }
        if self.variant == Variant::Anchored {
            let (cin, cout) = Variant::Anchored.channels();
            for (field, value, want) in [
                ("in_channels", self.in_channels, cin),
                ("out_channels", self.out_channels, cout),
            ] {
                if value != want {
                    return Err(ModelError::InvalidConfig {
                        field,
                        value,
                        reason: format!("the anchored variant has {want}"),
                    });
                }
            }
            let global_ok =
                self.light_field == LightFieldMap::Global && self.anchor != AnchorKind::Reinhard;
            if self.light_field != LightFieldMap::Absolute && !global_ok {
                return Err(ModelError::InvalidConfig {
                    field: "light_field",
                    value: 0,
                    reason: "the anchored variant reads the absolute map (its light-field retention compares absolute maps), or with the water anchor the global one".into(),
                });
            }
        }
        if self.in_channels == 0 {
            return Err(ModelError::InvalidConfig {
                field: "in_channels",
                value: 0,
                reason: "must be at least 1".into(),
            });
        }
        if self.out_channels == 0 {
            return Err(ModelError::InvalidConfig {
                field: "out_channels",
                value: 0,
                reason: "must be at least 1".into(),
            });
        }
        if self.base_width == 0 || !self.base_width.is_multiple_of(WIDTH_MULTIPLE) {
            return Err(ModelError::InvalidConfig {
                field: "base_width",
                value: self.base_width,
                reason: format!(
                    "must be a positive multiple of {WIDTH_MULTIPLE} (attention uses c/4, the last decoder level c/2)"
                ),
            });
        }
        Ok(())
    }

    /// Channels of encoder level `level` (0-based): `base_width * 2^level`.
    #[must_use]
    pub fn level_width(&self, level: usize) -> usize {
        self.base_width << level
    }

    /// Channels entering the output convolution: the last PixelShuffle halves `base_width`.
    #[must_use]
    pub fn decoder_out_width(&self) -> usize {
        self.base_width / 2
    }
}

/// Number of parameters of the generator `config` describes.
///
/// `include_unused_norm` adds the affine `InstanceNorm2d(c/2)` each released `BasicBlock`
/// owns but never calls (2 x c/2 per block, 4 blocks; 960 at the paper's width). The released
/// network has 11,569,271 parameters without them and 11,570,231 with them; both round to
/// the paper's 11.57M. The burn module does not hold the unused norms.
#[must_use]
pub fn param_count(config: &GeneratorConfig, include_unused_norm: bool) -> usize {
    let conv = |cin: usize, cout: usize, k: usize| cout * cin * k * k + cout;
    let mut total = 0;
    let mut cin = config.in_channels;
    for level in 0..LEVELS {
        let c = config.level_width(level);
        let r = c / ATTENTION_REDUCTION;
        total += conv(cin, c, 3); // mpconv.0
        total += conv(c, c, 3) + conv(c, c, 1); // conk3, conk1
        total += conv(c, r, 1) + conv(r, 1, 1); // SA.spatial_pool.{0,2}
        total += conv(c, r, 1) + conv(r, c, 1); // CA.channel_map.{0,2}
        if include_unused_norm {
            total += 2 * (c / 2); // norm.{weight,bias}
        }
        cin = c;
    }
    for level in (0..LEVELS).rev() {
        let c = config.level_width(level);
        total += conv(c, 2 * c, 3); // up.0
    }
    total + conv(config.decoder_out_width(), config.out_channels, 3)
}

/// Multiply-accumulates (in units of 10^9) of one forward pass at `height x width`, counting
/// the convolution kernels only (no bias additions, activations, pooling or shuffles).
///
/// This is the convention of the figures in the paper and the notes: 8.61 GMac at 256x256 and
/// 137.80 GMac at 1024x1024 for the default config. (The released README's "corrected"
/// 138.13 GMac at 1024x1024 is what ptflops reports: it also counts biases and activations.)
/// Sizes that are not multiples of 16 are counted as the network would see them after padding
/// up to the next multiple.
#[must_use]
pub fn gmacs(config: &GeneratorConfig, height: usize, width: usize) -> f64 {
    let (mut h, mut w) = (
        height.div_ceil(SIZE_MULTIPLE) * SIZE_MULTIPLE,
        width.div_ceil(SIZE_MULTIPLE) * SIZE_MULTIPLE,
    );
    // Kernel MACs of a conv at `pixels` output positions.
    let conv =
        |cin: usize, cout: usize, k: usize, pixels: usize| (cin * cout * k * k * pixels) as f64;
    let mut total = 0.0;
    let mut cin = config.in_channels;
    for level in 0..LEVELS {
        let c = config.level_width(level);
        let r = c / ATTENTION_REDUCTION;
        h /= 2;
        w /= 2;
        let px = h * w;
        total += conv(cin, c, 3, px) + conv(c, c, 3, px) + conv(c, c, 1, px);
        total += conv(c, r, 1, px) + conv(r, 1, 1, px); // spatial attention, per pixel
        total += conv(c, r, 1, 1) + conv(r, c, 1, 1); // channel attention, on the pooled vector
        cin = c;
    }
    for level in (0..LEVELS).rev() {
        let c = config.level_width(level);
        total += conv(c, 2 * c, 3, h * w);
        h *= 2;
        w *= 2;
    }
    total += conv(config.decoder_out_width(), config.out_channels, 3, h * w);
    total / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_parameter_count() {
        let cfg = GeneratorConfig::default();
        // Without the unused InstanceNorm parameters: the number PyTorch reports for the
        // parameters the forward pass uses.
        assert_eq!(param_count(&cfg, false), 11_569_271);
        // With them: what `sum(p.numel() for p in Generator().parameters())` reports.
        assert_eq!(param_count(&cfg, true), 11_570_231);
    }

    #[test]
    fn paper_gmacs() {
        let cfg = GeneratorConfig::default();
        assert_eq!(format!("{:.2}", gmacs(&cfg, 256, 256)), "8.61");
        assert_eq!(format!("{:.2}", gmacs(&cfg, 1024, 1024)), "137.80");
        // Convolutions dominate and scale with the pixel count, up to the pooled CA vectors.
        let ratio = gmacs(&cfg, 512, 512) / gmacs(&cfg, 256, 256);
        assert!((ratio - 4.0).abs() < 1e-3, "{ratio}");
        // Padding to a multiple of 16 is counted.
        assert_eq!(gmacs(&cfg, 250, 256), gmacs(&cfg, 256, 256));
    }

    #[test]
    fn width_must_be_a_multiple_of_8() {
        for bad in [0, 4, 12, 100] {
            let err = GeneratorConfig::with_base_width(bad)
                .validate()
                .unwrap_err();
            assert!(
                matches!(err, ModelError::InvalidConfig { field: "base_width", value, .. } if value == bad),
                "{err}"
            );
        }
        GeneratorConfig::with_base_width(8).validate().unwrap();
        GeneratorConfig::with_base_width(24).validate().unwrap();
    }

    #[test]
    fn config_json_round_trip_rejects_unknown_fields() {
        let cfg = GeneratorConfig::with_base_width(16);
        let json = serde_json::to_string(&cfg).unwrap();
        assert_eq!(serde_json::from_str::<GeneratorConfig>(&json).unwrap(), cfg);
        assert!(
            serde_json::from_str::<GeneratorConfig>(
                r#"{"in_channels":7,"out_channels":3,"base_width":8,"depth":4}"#
            )
            .is_err()
        );
    }

    #[test]
    fn light_field_map_is_recorded_and_defaults_to_the_papers() {
        // Files written before the field existed (and the authors' checkpoint) mean `paper`.
        let old: GeneratorConfig =
            serde_json::from_str(r#"{"in_channels":7,"out_channels":3,"base_width":64}"#).unwrap();
        assert_eq!(old.light_field, LightFieldMap::Paper);
        let cfg = GeneratorConfig {
            light_field: LightFieldMap::Absolute,
            ..GeneratorConfig::with_base_width(8)
        };
        let json = serde_json::to_string(&cfg).unwrap();
        assert!(json.contains(r#""light_field":"absolute""#), "{json}");
        assert_eq!(serde_json::from_str::<GeneratorConfig>(&json).unwrap(), cfg);
        assert!(
            serde_json::from_str::<GeneratorConfig>(
                r#"{"in_channels":7,"out_channels":3,"base_width":64,"light_field":"bright"}"#
            )
            .is_err()
        );
    }

    #[test]
    fn the_global_map_needs_the_water_anchor() {
        // The Reinhard anchor's light-field retention compares absolute maps; the water anchor
        // reads the map only through the network, which may be fed the global one.
        let water = GeneratorConfig {
            light_field: LightFieldMap::Global,
            anchor: AnchorKind::Water,
            ..GeneratorConfig::anchored(8)
        };
        water.validate().unwrap();
        let reinhard = GeneratorConfig {
            anchor: AnchorKind::Reinhard,
            ..water
        };
        let e = reinhard.validate().unwrap_err().to_string();
        assert!(e.contains("light_field"), "{e}");
    }
}
