//! The generator's weights in PyTorch layout (`[cout][cin][k][k]` and `[cout]` per
//! convolution), level by level as the released `Generator` of FSU2.py holds them; the unused
//! `InstanceNorm2d` of each block is not part of it.

use crate::error::{EngineError, Result};

/// Encoder and decoder levels.
pub const LEVELS: usize = 4;
/// Squeeze factor of the spatial and channel attention.
pub const ATTENTION_REDUCTION: usize = 4;

/// One convolution.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvWeights {
    /// Output channels.
    pub cout: usize,
    /// Input channels.
    pub cin: usize,
    /// Kernel side (1 or 3).
    pub k: usize,
    /// `cout * cin * k * k` values, `[cout][cin][k][k]`.
    pub weight: Vec<f32>,
    /// `cout` values.
    pub bias: Vec<f32>,
}

impl ConvWeights {
    fn check(&self, layer: &str, cout: usize, cin: usize, k: usize) -> Result<()> {
        if (self.cout, self.cin, self.k) != (cout, cin, k) {
            return Err(EngineError::InvalidWidths(format!(
                "{layer}: conv is {}x{}x{k}x{k}, expected {cout}x{cin}x{k}x{k}",
                self.cout, self.cin
            )));
        }
        for (what, len, expected) in [
            ("weight", self.weight.len(), cout * cin * k * k),
            ("bias", self.bias.len(), cout),
        ] {
            if len != expected {
                return Err(EngineError::WeightLength {
                    layer: format!("{layer}.{what}"),
                    expected,
                    got: len,
                });
            }
        }
        Ok(())
    }
}

/// `BasicBlock(c)`.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockWeights {
    /// conv3x3 `c -> c`.
    pub conk3: ConvWeights,
    /// conv1x1 `c -> c`.
    pub conk1: ConvWeights,
    /// Spatial attention, conv1x1 `c -> c/4`.
    pub sa_reduce: ConvWeights,
    /// Spatial attention, conv1x1 `c/4 -> 1`.
    pub sa_expand: ConvWeights,
    /// Channel attention, conv1x1 `c -> c/4`.
    pub ca_reduce: ConvWeights,
    /// Channel attention, conv1x1 `c/4 -> c`.
    pub ca_expand: ConvWeights,
}

/// An encoder level: the stride-2 conv3x3 (then ELU) and its block.
#[derive(Clone, Debug, PartialEq)]
pub struct DownWeights {
    /// conv3x3 stride 2, `in -> out`.
    pub conv: ConvWeights,
    /// `BasicBlock(out)`.
    pub block: BlockWeights,
}

/// The whole generator: `downs[k]` has `base_width << k` channels, `ups[i]` is the conv3x3
/// `c -> 2c` of decoder level `i` (`c = base_width << (3 - i)`), `out` the final conv3x3.
#[derive(Clone, Debug, PartialEq)]
pub struct GeneratorWeights {
    /// Encoder levels.
    pub downs: [DownWeights; LEVELS],
    /// Decoder convs.
    pub ups: [ConvWeights; LEVELS],
    /// conv3x3 `base_width / 2 -> out_channels`.
    pub out: ConvWeights,
}

impl GeneratorWeights {
    /// Input channels.
    #[must_use]
    pub fn in_channels(&self) -> usize {
        self.downs[0].conv.cin
    }

    /// Output channels.
    #[must_use]
    pub fn out_channels(&self) -> usize {
        self.out.cout
    }

    /// First-level width.
    #[must_use]
    pub fn base_width(&self) -> usize {
        self.downs[0].conv.cout
    }

    /// Checks every shape against the widths of the first level.
    pub fn validate(&self) -> Result<()> {
        let base = self.base_width();
        if base < 2 * ATTENTION_REDUCTION || !base.is_multiple_of(2 * ATTENTION_REDUCTION) {
            return Err(EngineError::InvalidWidths(format!(
                "base width {base} must be a positive multiple of {}",
                2 * ATTENTION_REDUCTION
            )));
        }
        let mut cin = self.in_channels();
        if cin == 0 || self.out_channels() == 0 {
            return Err(EngineError::InvalidWidths(
                "input and output channels must be at least 1".into(),
            ));
        }
        for (level, d) in self.downs.iter().enumerate() {
            let c = base << level;
            let r = c / ATTENTION_REDUCTION;
            let name = |s: &str| format!("down{}.{s}", level + 1);
            d.conv.check(&name("conv"), c, cin, 3)?;
            let b = &d.block;
            b.conk3.check(&name("conk3"), c, c, 3)?;
            b.conk1.check(&name("conk1"), c, c, 1)?;
            b.sa_reduce.check(&name("sa.reduce"), r, c, 1)?;
            b.sa_expand.check(&name("sa.expand"), 1, r, 1)?;
            b.ca_reduce.check(&name("ca.reduce"), r, c, 1)?;
            b.ca_expand.check(&name("ca.expand"), c, r, 1)?;
            cin = c;
        }
        for (i, up) in self.ups.iter().enumerate() {
            let c = base << (LEVELS - 1 - i);
            up.check(&format!("up{}", i + 1), 2 * c, c, 3)?;
        }
        self.out.check("out", self.out_channels(), base / 2, 3)
    }

    /// Seeded random weights (uniform, scaled by `1/sqrt(fan_in)` so activations stay of order
    /// one at any width), for tests and benchmarks.
    #[must_use]
    pub fn random(in_channels: usize, out_channels: usize, base_width: usize, seed: u64) -> Self {
        let mut state = seed ^ 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        let mut conv = |cout: usize, cin: usize, k: usize| {
            let scale = 1.5 / ((cin * k * k) as f32).sqrt();
            ConvWeights {
                cout,
                cin,
                k,
                weight: (0..cout * cin * k * k).map(|_| next() * scale).collect(),
                bias: (0..cout).map(|_| next() * 0.1).collect(),
            }
        };
        let mut cin = in_channels;
        let downs = std::array::from_fn(|level| {
            let c = base_width << level;
            let r = c / ATTENTION_REDUCTION;
            let d = DownWeights {
                conv: conv(c, cin, 3),
                block: BlockWeights {
                    conk3: conv(c, c, 3),
                    conk1: conv(c, c, 1),
                    sa_reduce: conv(r, c, 1),
                    sa_expand: conv(1, r, 1),
                    ca_reduce: conv(r, c, 1),
                    ca_expand: conv(c, r, 1),
                },
            };
            cin = c;
            d
        });
        let ups = std::array::from_fn(|i| {
            let c = base_width << (LEVELS - 1 - i);
            conv(2 * c, c, 3)
        });
        let out = conv(out_channels, base_width / 2, 3);
        Self { downs, ups, out }
    }
}
