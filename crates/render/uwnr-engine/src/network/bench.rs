//! [`LayerBench`]: one layer of the generator on random weights and input, for per-kernel
//! benchmarks at the network's real shapes (`benches/kernels.rs`, `examples/engine_time.rs`).

use super::{Conv3, EngineOptions, Generator, Level, pool_means};
use crate::error::{EngineError, Result};
use crate::tensor::{Feature, Pool};
use crate::weights::{GeneratorWeights, LEVELS};

/// One layer of the generator on random weights and input, for per-kernel benchmarks at the
/// network's real shapes.
#[derive(Debug)]
pub struct LayerBench {
    kind: LayerKind,
    level: Level,
    up: Option<Conv3>,
    input: Feature,
    output: Feature,
    pool: Pool,
}

/// Which layer [`LayerBench`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerKind {
    /// The encoder's stride-2 conv3x3 `cin -> c`.
    Stride2,
    /// The block's fused 3x3 (`conk3 + conk1 + id`), direct or Winograd per the options.
    Block3x3,
    /// The spatial-attention 1x1 `c -> c/4` with its per-pixel gate.
    SpatialAttention,
    /// Pooling, channel gate and residual add of channel attention.
    ChannelAttention,
    /// The decoder's conv3x3 `c -> 2c` with PixelShuffle.
    Up,
}

impl LayerBench {
    /// Encoder level `level` of a network of `base_width` at input size `size` (decoder level
    /// at the same width for [`LayerKind::Up`]).
    pub fn new(
        kind: LayerKind,
        opts: EngineOptions,
        base_width: usize,
        level: usize,
        size: usize,
    ) -> Result<Self> {
        let weights = GeneratorWeights::random(7, 3, base_width, 1);
        let g = Generator::with_options(&weights, opts)?;
        let l = g
            .levels
            .get(level)
            .cloned()
            .ok_or_else(|| EngineError::Input(format!("no level {level}")))?;
        let c = l.c;
        let side = size >> (level + 1);
        let cin = if level == 0 { 7 } else { c / 2 };
        let (input, output, up) = match kind {
            LayerKind::Stride2 => (
                random_feature(2 * side, 2 * side, cin, 1),
                Feature::zeros(side, side, c, 1),
                None,
            ),
            LayerKind::Block3x3 => (
                random_feature(side, side, c, 1),
                Feature::zeros(side, side, c, 0),
                None,
            ),
            LayerKind::SpatialAttention | LayerKind::ChannelAttention => (
                random_feature(side, side, c, 1),
                random_feature(side, side, c, 0),
                None,
            ),
            LayerKind::Up => {
                let up = g.ups.get(LEVELS - 1 - level).cloned();
                (
                    random_feature(side, side, c, 1),
                    Feature::zeros(side, side, 2 * c, 0),
                    up,
                )
            }
        };
        Ok(Self {
            kind,
            level: l,
            up,
            input,
            output,
            pool: Pool::default(),
        })
    }

    /// Multiply-accumulates of one run (0 for the pooling and gating passes).
    #[must_use]
    pub fn macs(&self) -> u64 {
        let px = (self.output.h * self.output.w) as u64;
        let c = self.level.c as u64;
        match self.kind {
            LayerKind::Stride2 => px * c * self.input.c as u64 * 9,
            LayerKind::Block3x3 => px * c * c * 9,
            LayerKind::SpatialAttention => px * c * (c / 4) + px * (c / 4),
            LayerKind::ChannelAttention => 0,
            LayerKind::Up => px * c * 2 * c * 9,
        }
    }

    /// Runs the layer once.
    pub fn run(&mut self) {
        match self.kind {
            LayerKind::Stride2 => {
                self.level
                    .stem
                    .run(&self.input, &mut self.output, &mut self.pool);
            }
            LayerKind::Block3x3 => {
                self.level
                    .body
                    .run(&self.input, &mut self.output, &mut self.pool);
            }
            LayerKind::SpatialAttention => self
                .level
                .spatial_attention(&mut self.output, &mut self.pool),
            LayerKind::ChannelAttention => {
                let mean = pool_means(&self.output);
                let stem = std::mem::replace(&mut self.input, Feature::zeros(0, 0, 0, 0));
                self.input = self.level.finish(stem, &self.output, &mean);
            }
            LayerKind::Up => {
                if let Some(up) = &self.up {
                    up.run(&self.input, &mut self.output, &mut self.pool);
                }
            }
        }
    }
}

fn random_feature(h: usize, w: usize, c: usize, pad: usize) -> Feature {
    let mut f = Feature::zeros(h, w, c, pad);
    for y in 0..h {
        for (i, v) in f.row_mut(y).iter_mut().enumerate() {
            *v = ((i * 7919 + y * 104_729) % 1000) as f32 / 1000.0 - 0.5;
        }
    }
    f
}
