//! The UWNR generator (MHB-Unet, Ye et al., CVPR-W 2022; released `model/FSU2.py`) on the
//! engine's kernels.
//!
//! Per encoder level: `stem = ELU(conv3x3_s2(x))`; the block's `conk1(stem) + conk3(stem) +
//! stem` is one 3x3 convolution whose centre tap holds `conk3 + conk1 + I` (bias `b3 + b1`),
//! with the LeakyReLU in its epilogue (`o`); spatial attention is a 1x1 convolution `c -> c/4`
//! with LeakyReLU in its epilogue followed by a per-pixel dot product and sigmoid (`t = o s`);
//! channel attention pools `t` (or takes a given mean), gates it and adds the residual in
//! place: `x_k = stem + t g`. Per decoder level: conv3x3 `c -> 2c` with ELU in the epilogue,
//! its output channels permuted so each PixelShuffle sub-pixel is a contiguous run, then one
//! pass that scatters the sub-pixels and adds the skip. The output conv has tanh in its
//! epilogue.

use crate::conv::Conv;
use crate::error::{EngineError, Result};
use crate::kernels::{Act, Dot, Isa, Precision};
use crate::narrow::Narrow;
use crate::tensor::{Feature, PassKind, Planar, Pool};
use crate::weights::{ATTENTION_REDUCTION, ConvWeights, GeneratorWeights, LEVELS};
use crate::winograd::{WinoTile, Winograd};

mod level;
use level::{fuse_block, pool_means, shuffle_order, upsample};

pub(crate) mod bench;

/// Height and width of the input must be multiples of this (four stride-2 levels).
pub const SIZE_MULTIPLE: usize = 1 << LEVELS;
/// PixelShuffle factor of the decoder.
const UPSCALE: usize = 2;

/// How the 3x3 stride-1 convolutions are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ConvAlgo {
    /// Winograd F(4x4, 3x3) where it is faster, direct elsewhere (the default).
    #[default]
    Auto,
    /// Direct convolution everywhere.
    Direct,
    /// Winograd F(2x2, 3x3) where `Auto` uses F(4x4, 3x3): transformed weights 16/9 of the
    /// kernel's size instead of 4x, 2.25x fewer multiplies than direct instead of 4x. Slower
    /// than `Auto` at every size on the machine the engine was tuned on (see `docs/speed.md`);
    /// kept for comparison elsewhere.
    WinogradF2,
}

/// Build-time choices of the engine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EngineOptions {
    /// Instruction set of the kernels.
    pub isa: Isa,
    /// Algorithm of the stride-1 3x3 convolutions.
    pub algo: ConvAlgo,
    /// Arithmetic of the Winograd products and direct 3x3 convolutions (the bulk of the work).
    pub precision: Precision,
}

impl EngineOptions {
    /// Whether the bf16 products run on `vdpbf16ps` (AVX512_BF16 with [`Isa::Avx512`]) rather
    /// than its emulation; `false` for [`Precision::F32`].
    #[must_use]
    pub fn native_bf16(&self) -> bool {
        Dot::new(self.isa, self.precision) == Dot::Bf16Native
    }
}

impl Default for EngineOptions {
    fn default() -> Self {
        Self {
            isa: Isa::best(),
            algo: ConvAlgo::Auto,
            precision: Precision::F32,
        }
    }
}

/// A stride-1 3x3 convolution: direct, Winograd, or per-pixel dot products for a few outputs.
#[derive(Clone, Debug)]
enum Conv3 {
    Direct(Conv),
    Winograd(Winograd),
    Narrow(Narrow),
}

impl Conv3 {
    #[allow(clippy::too_many_arguments)]
    fn new(
        opts: EngineOptions,
        weight: &[f32],
        bias: &[f32],
        cout: usize,
        cin: usize,
        act: Act,
        order: Option<&[usize]>,
    ) -> Self {
        if order.is_none() && Narrow::applies(cout) {
            Self::Narrow(Narrow::new(opts.isa, weight, bias, cout, cin, 3, act))
        } else if opts.algo != ConvAlgo::Direct && Winograd::worthwhile(cin, cout) {
            let tile = if opts.algo == ConvAlgo::WinogradF2 {
                WinoTile::F2
            } else {
                WinoTile::F4
            };
            let dot = Dot::new(opts.isa, opts.precision);
            Self::Winograd(Winograd::new(
                opts.isa, dot, tile, weight, bias, cout, cin, act, order,
            ))
        } else {
            Self::Direct(Conv::new(
                opts.isa,
                Dot::new(opts.isa, opts.precision),
                weight,
                bias,
                cout,
                cin,
                3,
                1,
                act,
                order,
            ))
        }
    }

    fn run(&self, src: &Feature, dst: &mut Feature, pool: &mut Pool) {
        match self {
            Self::Direct(c) => c.run(src, dst, pool),
            Self::Winograd(c) => c.run(src, dst, pool),
            Self::Narrow(c) => c.run(src, dst),
        }
    }
}

#[derive(Clone, Debug)]
struct Level {
    c: usize,
    stem: Conv,
    body: Conv3,
    sa_reduce: Conv,
    sa_expand: Vec<f32>,
    sa_expand_bias: f32,
    ca_reduce: ConvWeights,
    ca_expand: ConvWeights,
}

/// What the channel attention of each block pools.
#[derive(Clone, Copy, Debug)]
pub enum Means<'a> {
    /// Its own input (the released forward).
    Own,
    /// These means, one per block (`base_width << k` values each), e.g. of a whole image of
    /// which the input is a tile.
    Given(&'a [Vec<f32>]),
}

/// The generator, packed for one instruction set. Immutable: share it between threads.
#[derive(Debug)]
pub struct Generator {
    opts: EngineOptions,
    /// Buffers of earlier passes, reused by the next one.
    pool: std::sync::Mutex<Pool>,
    in_channels: usize,
    out_channels: usize,
    base_width: usize,
    levels: Vec<Level>,
    ups: Vec<Conv3>,
    out: Conv3,
}

impl Generator {
    /// Packs `weights` for the fastest kernels this CPU runs.
    pub fn new(weights: &GeneratorWeights) -> Result<Self> {
        Self::with_options(weights, EngineOptions::default())
    }

    /// Packs `weights` with explicit options (a particular instruction set, e.g. in tests).
    pub fn with_options(weights: &GeneratorWeights, opts: EngineOptions) -> Result<Self> {
        weights.validate()?;
        if !opts.isa.is_supported() {
            return Err(EngineError::UnsupportedIsa(opts.isa));
        }
        let isa = opts.isa;
        let levels = weights
            .downs
            .iter()
            .map(|d| {
                let c = d.conv.cout;
                let b = &d.block;
                let (fused_w, fused_b) = fuse_block(&b.conk3, &b.conk1);
                Level {
                    c,
                    stem: Conv::new(
                        isa,
                        Dot::new(isa, opts.precision),
                        &d.conv.weight,
                        &d.conv.bias,
                        c,
                        d.conv.cin,
                        3,
                        2,
                        Act::Elu,
                        None,
                    ),
                    body: Conv3::new(opts, &fused_w, &fused_b, c, c, Act::LeakyRelu, None),
                    // The 1x1 is small (c -> c / 4) and its input is read once: a bf16 copy
                    // would cost about what it saves.
                    sa_reduce: Conv::new(
                        isa,
                        Dot::F32,
                        &b.sa_reduce.weight,
                        &b.sa_reduce.bias,
                        c / ATTENTION_REDUCTION,
                        c,
                        1,
                        1,
                        Act::LeakyRelu,
                        None,
                    ),
                    sa_expand: b.sa_expand.weight.clone(),
                    sa_expand_bias: b.sa_expand.bias[0],
                    ca_reduce: b.ca_reduce.clone(),
                    ca_expand: b.ca_expand.clone(),
                }
            })
            .collect();
        let ups = weights
            .ups
            .iter()
            .map(|u| {
                let order = shuffle_order(u.cout);
                Conv3::new(
                    opts,
                    &u.weight,
                    &u.bias,
                    u.cout,
                    u.cin,
                    Act::Elu,
                    Some(&order),
                )
            })
            .collect();
        let o = &weights.out;
        Ok(Self {
            opts,
            pool: std::sync::Mutex::new(Pool::default()),
            in_channels: weights.in_channels(),
            out_channels: weights.out_channels(),
            base_width: weights.base_width(),
            levels,
            ups,
            out: Conv3::new(opts, &o.weight, &o.bias, o.cout, o.cin, Act::Tanh, None),
        })
    }

    /// The options the generator was packed with.
    #[must_use]
    pub fn options(&self) -> EngineOptions {
        self.opts
    }

    /// Input channels.
    #[must_use]
    pub fn in_channels(&self) -> usize {
        self.in_channels
    }

    /// Output channels.
    #[must_use]
    pub fn out_channels(&self) -> usize {
        self.out_channels
    }

    /// First-level width.
    #[must_use]
    pub fn base_width(&self) -> usize {
        self.base_width
    }

    fn check(&self, x: &Planar, means: Means<'_>) -> Result<()> {
        if x.channels != self.in_channels {
            return Err(EngineError::Input(format!(
                "{} channels, the network takes {}",
                x.channels, self.in_channels
            )));
        }
        if x.height == 0
            || x.width == 0
            || !x.height.is_multiple_of(SIZE_MULTIPLE)
            || !x.width.is_multiple_of(SIZE_MULTIPLE)
        {
            return Err(EngineError::Input(format!(
                "size {}x{} must be a positive multiple of {SIZE_MULTIPLE} in both directions",
                x.width, x.height
            )));
        }
        if x.data.len() != x.channels * x.height * x.width {
            return Err(EngineError::Input(format!(
                "{} values for {}x{}x{}",
                x.data.len(),
                x.channels,
                x.height,
                x.width
            )));
        }
        if let Means::Given(m) = means {
            if m.len() < LEVELS {
                return Err(EngineError::Input(format!(
                    "{} means, expected {LEVELS}",
                    m.len()
                )));
            }
            for (k, (m, l)) in m.iter().zip(&self.levels).enumerate() {
                if m.len() != l.c {
                    return Err(EngineError::Input(format!(
                        "mean {k} has {} values, block {k} has {} channels",
                        m.len(),
                        l.c
                    )));
                }
            }
        }
        Ok(())
    }

    /// The forward pass. Returns the output (`out_channels x h x w`, in (-1, 1)) and the
    /// channel-attention mean each block used.
    ///
    /// # Shapes
    /// - `x`: `in_channels x h x w` with `h`, `w` multiples of 16.
    pub fn forward(&self, x: &Planar, means: Means<'_>) -> Result<(Planar, Vec<Vec<f32>>)> {
        self.forward_probed(x, means, &mut |_| {})
    }

    /// Wall time of each stage of one forward pass (`Means::Own`), in order, for profiling:
    /// names like `level0.stem`, `up3.conv`, `out`.
    pub fn profile(&self, x: &Planar) -> Result<Vec<(String, std::time::Duration)>> {
        let mut stages = Vec::new();
        let mut last = std::time::Instant::now();
        self.forward_probed(x, Means::Own, &mut |name| {
            let now = std::time::Instant::now();
            stages.push((name.to_string(), now - last));
            last = now;
        })?;
        Ok(stages)
    }

    /// [`Self::forward`], calling `probe` with the name of each stage as it ends.
    fn forward_probed(
        &self,
        x: &Planar,
        means: Means<'_>,
        probe: &mut dyn FnMut(&str),
    ) -> Result<(Planar, Vec<Vec<f32>>)> {
        self.check(x, means)?;
        let mut pool = self.take_pool((x.channels, x.height, x.width, LEVELS));
        let mut skips: Vec<Feature> = Vec::with_capacity(LEVELS);
        let mut used = Vec::with_capacity(LEVELS);
        let input = Feature::from_planar(x, 1);
        probe("input");
        for (k, level) in self.levels.iter().enumerate() {
            let h = skips.last().unwrap_or(&input);
            let (stem, attended) = level.attention_input_probed(h, &mut pool, &mut |s| {
                probe(&format!("level{k}.{s}"));
            });
            let mean = match means {
                Means::Own => pool_means(&attended),
                Means::Given(m) => m[k].clone(),
            };
            skips.push(level.finish(stem, &attended, &mean));
            pool.give(attended);
            used.push(mean);
            probe(&format!("level{k}.channel_attention"));
        }
        let mut h = skips.pop().unwrap_or(input);
        for (i, up) in self.ups.iter().enumerate() {
            let skip = skips.pop();
            let next = upsample(up, &h, skip.as_ref(), &mut pool, &mut |s| {
                probe(&format!("up{i}.{s}"));
            });
            pool.give(std::mem::replace(&mut h, next));
            if let Some(s) = skip {
                pool.give(s);
            }
        }
        let mut y = Feature::output_in(&mut pool, h.h, h.w, self.out_channels, 0);
        self.out.run(&h, &mut y, &mut pool);
        probe("out");
        let out = y.to_planar();
        pool.give(h);
        pool.give(y);
        self.return_pool(pool);
        probe("output");
        Ok((out, used))
    }

    /// The buffers of earlier passes, for a pass of `kind` (see [`Pool::begin`]).
    fn take_pool(&self, kind: PassKind) -> Pool {
        let mut pool = self
            .pool
            .lock()
            .map(|mut p| std::mem::take(&mut *p))
            .unwrap_or_default();
        pool.begin(kind);
        pool
    }

    fn return_pool(&self, pool: Pool) {
        if let Ok(mut p) = self.pool.lock() {
            p.absorb(pool);
        }
    }

    /// Runs the encoder up to block `k = known.len()` and returns that block's
    /// channel-attention input (before pooling); blocks before `k` gate with `known`.
    ///
    /// # Shapes
    /// - output: `(base_width << k) x h / 2^(k+1) x w / 2^(k+1)`.
    pub fn channel_attention_input(&self, x: &Planar, known: &[Vec<f32>]) -> Result<Planar> {
        let k = known.len();
        if k >= LEVELS {
            return Err(EngineError::Input(format!(
                "{k} means given, the encoder has only {LEVELS} blocks"
            )));
        }
        let mut padded = known.to_vec();
        padded.extend(self.levels[k..].iter().map(|l| vec![0.0; l.c]));
        self.check(x, Means::Given(&padded))?;
        let mut pool = self.take_pool((x.channels, x.height, x.width, k));
        let mut h = Feature::from_planar(x, 1);
        for (level, l) in self.levels.iter().enumerate() {
            let (stem, attended) = l.attention_input(&h, &mut pool);
            if level == k {
                let out = attended.to_planar();
                pool.give(attended);
                pool.give(stem);
                pool.give(h);
                self.return_pool(pool);
                return Ok(out);
            }
            let next = l.finish(stem, &attended, &known[level]);
            pool.give(attended);
            pool.give(std::mem::replace(&mut h, next));
        }
        Err(EngineError::Input(format!("block {k} not reached")))
    }
}
