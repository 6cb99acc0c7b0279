//! The MHB-Unet generator of UWNR (Ye et al., CVPR-W 2022, Sec. 3.3 and Fig. 3), as the
//! released `model/FSU2.py` builds it:
//!
//! - `BasicBlock(c)`: `y = conv1x1(x) + conv3x3(x) + x`, `o = LeakyReLU(y)`,
//!   `out = CA(SA(o)) + x`, with `SA(t) = t * sigmoid(conv1x1(LeakyReLU(conv1x1(t))))`
//!   (`c -> c/4 -> 1`) and `CA(t) = t * sigmoid(conv1x1(LeakyReLU(conv1x1(mean_hw(t)))))`
//!   (`c -> c/4 -> c` on the global average pool);
//! - `down(in, out)`: conv3x3 stride 2 + ELU + `BasicBlock(out)`;
//! - `up(c)`: conv3x3 `c -> 2c` + ELU + PixelShuffle(2), giving `c/2` channels at twice the size;
//! - `x2..x16` = four downs, `y8 = up(x16) + x8`, `y4 = up(y8) + x4`, `y2 = up(y4) + x2`,
//!   `out = tanh(conv3x3(up(y2)))`.
//!
//! Field names follow the PyTorch state-dict keys (`in_conv_down1.mpconv.2.conk3.weight`);
//! [`crate::burn_weights`] maps them. Channel attention pools over the whole input: besides
//! [`Generator::forward`] there are variants that take the pooled means from outside
//! ([`Generator::forward_with_channel_means`]) or return them
//! ([`Generator::forward_returning_channel_means`]), which tiled inference uses to keep the
//! pooling global.

use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Initializer, PaddingConfig2d, PixelShuffle, PixelShuffleConfig};
use burn::tensor::activation::{elu, leaky_relu, sigmoid};
use burn::tensor::{Device, Tensor};

use uwnr_model::config::{ATTENTION_REDUCTION, GeneratorConfig, LEVELS};
use uwnr_model::{ModelError, Result, Variant};

/// Negative slope of every LeakyReLU: FSU2.py calls `nn.LeakyReLU()` without an argument,
/// i.e. PyTorch's default 0.01.
pub const LEAKY_RELU_SLOPE: f64 = 0.01;
/// `alpha` of every ELU (`nn.ELU()` default).
pub const ELU_ALPHA: f64 = 1.0;
/// Standard deviation of the conv weight initialisation (`weights_init_normal` in the
/// released `myutils/utils.py`: `normal_(m.weight, 0.0, 0.02)`).
pub const INIT_WEIGHT_STD: f64 = 0.02;
/// Upscale factor of every decoder level (`nn.PixelShuffle(2)`).
const UPSCALE: usize = 2;

/// A conv with bias and symmetric zero padding, initialised like the released training:
/// weights N(0, 0.02); biases as PyTorch's default `Conv2d` init, U(-1/sqrt(fan_in),
/// 1/sqrt(fan_in)), which `weights_init_normal` leaves in place.
fn conv(cin: usize, cout: usize, kernel: usize, stride: usize, device: &Device) -> Conv2d {
    let pad = kernel / 2;
    let mut layer = Conv2dConfig::new([cin, cout], [kernel, kernel])
        .with_stride([stride, stride])
        .with_padding(PaddingConfig2d::Explicit(pad, pad, pad, pad))
        .with_initializer(Initializer::Normal {
            mean: 0.0,
            std: INIT_WEIGHT_STD,
        })
        .init(device);
    let bound = 1.0 / ((cin * kernel * kernel) as f64).sqrt();
    layer.bias = Some(
        Initializer::Uniform {
            min: -bound,
            max: bound,
        }
        .init([cout], device),
    );
    layer
}

/// Builds a conv from known weights (used by the weights loader). `weight` is
/// `[cout, cin, k, k]`, `bias` is `[cout]`; the caller has checked the shapes.
pub(crate) fn conv_from_tensors(weight: Tensor<4>, bias: Tensor<1>, stride: usize) -> Conv2d {
    let [_, _, kh, kw] = weight.dims();
    let pad = kh / 2;
    Conv2d {
        weight: Param::from_tensor(weight),
        bias: Some(Param::from_tensor(bias)),
        stride: [stride, stride],
        kernel_size: [kh, kw],
        dilation: [1, 1],
        groups: 1,
        padding: PaddingConfig2d::Explicit(pad, pad, pad, pad),
    }
}

/// Spatial attention (`SpatialAttention(c, 4)` in FSU2.py): a per-pixel gate in (0, 1).
#[derive(Module, Debug)]
pub struct SpatialAttention {
    /// `spatial_pool.0`: conv1x1 `c -> c/4`.
    pub reduce: Conv2d,
    /// `spatial_pool.2`: conv1x1 `c/4 -> 1`.
    pub expand: Conv2d,
}

impl SpatialAttention {
    /// `x * sigmoid(expand(LeakyReLU(reduce(x))))`.
    ///
    /// # Shapes
    /// - `x`: `[b, c, h, w]`; output: `[b, c, h, w]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let hidden = leaky_relu(self.reduce.forward(x.clone()), LEAKY_RELU_SLOPE);
        let gate = sigmoid(self.expand.forward(hidden)); // [b, 1, h, w]
        x * gate
    }
}

/// Channel attention (`ChannelAttention(c, 4)` in FSU2.py): a per-channel gate computed from
/// the global average of its input.
#[derive(Module, Debug)]
pub struct ChannelAttention {
    /// `channel_map.0`: conv1x1 `c -> c/4` on the pooled vector.
    pub reduce: Conv2d,
    /// `channel_map.2`: conv1x1 `c/4 -> c`.
    pub expand: Conv2d,
}

impl ChannelAttention {
    /// `x * sigmoid(expand(LeakyReLU(reduce(mean_hw(x)))))`.
    ///
    /// # Shapes
    /// - `x`: `[b, c, h, w]`; output: `[b, c, h, w]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mean = global_mean(x.clone());
        self.forward_with_mean(x, mean)
    }

    /// The same gate computed from a given pooled mean instead of the mean of `x` (for tiles
    /// of a larger image whose global mean is known).
    ///
    /// # Shapes
    /// - `x`: `[b, c, h, w]`, `mean`: `[b, c, 1, 1]`; output: `[b, c, h, w]`
    pub fn forward_with_mean(&self, x: Tensor<4>, mean: Tensor<4>) -> Tensor<4> {
        let hidden = leaky_relu(self.reduce.forward(mean), LEAKY_RELU_SLOPE); // [b, c/4, 1, 1]
        let gate = sigmoid(self.expand.forward(hidden)); // [b, c, 1, 1]
        x * gate
    }
}

/// Mean over height and width (`nn.AdaptiveAvgPool2d(1)`).
///
/// # Shapes
/// - `x`: `[b, c, h, w]`; output: `[b, c, 1, 1]`
pub fn global_mean(x: Tensor<4>) -> Tensor<4> {
    x.mean_dim(2).mean_dim(3)
}

/// The multi-branch residual block (`BasicBlock(c)` in FSU2.py). The released block also owns
/// an `InstanceNorm2d(c/2, affine=True)` (`norm`) that its forward never calls; it is left out.
#[derive(Module, Debug)]
pub struct BasicBlock {
    /// `conk3`: conv3x3 `c -> c`, padding 1.
    pub conk3: Conv2d,
    /// `conk1`: conv1x1 `c -> c`.
    pub conk1: Conv2d,
    /// `SA`.
    pub sa: SpatialAttention,
    /// `CA`.
    pub ca: ChannelAttention,
}

impl BasicBlock {
    fn init(c: usize, device: &Device) -> Self {
        let r = c / ATTENTION_REDUCTION;
        Self {
            conk3: conv(c, c, 3, 1, device),
            conk1: conv(c, c, 1, 1, device),
            sa: SpatialAttention {
                reduce: conv(c, r, 1, 1, device),
                expand: conv(r, 1, 1, 1, device),
            },
            ca: ChannelAttention {
                reduce: conv(c, r, 1, 1, device),
                expand: conv(r, c, 1, 1, device),
            },
        }
    }

    /// `CA(SA(LeakyReLU(conk1(x) + conk3(x) + x))) + x`.
    ///
    /// # Shapes
    /// - `x`: `[b, c, h, w]`; output: `[b, c, h, w]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let attended = self.channel_attention_input(x.clone());
        let mean = global_mean(attended.clone());
        self.finish(attended, x, mean)
    }

    /// The input of the channel attention, `SA(LeakyReLU(conk1(x) + conk3(x) + x))`, whose
    /// global mean drives the channel gate.
    ///
    /// # Shapes
    /// - `x`: `[b, c, h, w]`; output: `[b, c, h, w]`
    pub fn channel_attention_input(&self, x: Tensor<4>) -> Tensor<4> {
        let y = self.conk1.forward(x.clone()) + self.conk3.forward(x.clone()) + x;
        self.sa.forward(leaky_relu(y, LEAKY_RELU_SLOPE))
    }

    /// `CA(attended) + residual` with the channel gate computed from `mean` (`[b, c, 1, 1]`).
    fn finish(&self, attended: Tensor<4>, residual: Tensor<4>, mean: Tensor<4>) -> Tensor<4> {
        self.ca.forward_with_mean(attended, mean) + residual
    }
}

/// An encoder level (`downsample(in, out)` in FSU2.py, Sequential `mpconv`).
#[derive(Module, Debug)]
pub struct Down {
    /// `mpconv.0`: conv3x3 stride 2, padding 1, `in -> out`.
    pub conv: Conv2d,
    /// `mpconv.2`: `BasicBlock(out)` (`mpconv.1` is the ELU).
    pub block: BasicBlock,
}

impl Down {
    fn init(cin: usize, cout: usize, device: &Device) -> Self {
        Self {
            conv: conv(cin, cout, 3, 2, device),
            block: BasicBlock::init(cout, device),
        }
    }

    /// ELU of the stride-2 conv: the block's input and residual.
    ///
    /// # Shapes
    /// - `x`: `[b, in, h, w]`; output: `[b, out, h/2, w/2]`
    fn stem(&self, x: Tensor<4>) -> Tensor<4> {
        elu(self.conv.forward(x), ELU_ALPHA)
    }

    /// `block(ELU(conv(x)))`.
    ///
    /// # Shapes
    /// - `x`: `[b, in, h, w]`; output: `[b, out, h/2, w/2]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        self.block.forward(self.stem(x))
    }
}

/// A decoder level (`upsample(c)` in FSU2.py, Sequential `up`).
#[derive(Module, Debug)]
pub struct Up {
    /// `up.0`: conv3x3 `c -> 2c`, padding 1 (`up.1` is the ELU, `up.2` the PixelShuffle).
    pub conv: Conv2d,
    /// `up.2`: PixelShuffle(2).
    pub shuffle: PixelShuffle,
}

impl Up {
    fn init(c: usize, device: &Device) -> Self {
        Self {
            conv: conv(c, 2 * c, 3, 1, device),
            shuffle: PixelShuffleConfig::new(UPSCALE).init(),
        }
    }

    pub(crate) fn from_conv(conv: Conv2d) -> Self {
        Self {
            conv,
            shuffle: PixelShuffleConfig::new(UPSCALE).init(),
        }
    }

    /// `PixelShuffle(ELU(conv(x)))`.
    ///
    /// # Shapes
    /// - `x`: `[b, c, h, w]`; output: `[b, c/2, 2h, 2w]`
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let y = elu(self.conv.forward(x), ELU_ALPHA); // [b, 2c, h, w]
        self.shuffle.forward(y) // [b, 2c/4, 2h, 2w]
    }
}

/// The pooled channel-attention inputs of the four encoder blocks: `means[k]` is the global
/// average of block `k`'s channel-attention input, `[b, base_width * 2^k, 1, 1]`.
pub type ChannelMeans = [Tensor<4>; LEVELS];

/// The UWNR generator (MHB-Unet). Build it with [`GeneratorInit::init`] or load it with
/// [`crate::load_generator`].
#[derive(Module, Debug)]
pub struct Generator {
    /// `in_conv_down1`: `down(in_channels, c)`.
    pub in_conv_down1: Down,
    /// `down2`: `down(c, 2c)`.
    pub down2: Down,
    /// `down3`: `down(2c, 4c)`.
    pub down3: Down,
    /// `down4`: `down(4c, 8c)`.
    pub down4: Down,
    /// `up1`: `up(8c)`.
    pub up1: Up,
    /// `up2`: `up(4c)`.
    pub up2: Up,
    /// `up3`: `up(2c)`.
    pub up3: Up,
    /// `up4`: `up(c)`.
    pub up4: Up,
    /// `out.0`: conv3x3 `c/2 -> out_channels` (`out.1` is the tanh).
    pub out: Conv2d,
}

/// How the encoder obtains each block's channel-attention mean.
enum MeanSource<'a> {
    /// Pool the block's own input (the released forward).
    Own,
    /// Use these means (one per block) instead.
    Given(&'a ChannelMeans),
}

/// Builds burn's module from a generator config (the config lives in the render wing,
/// `uwnr-model`, which renders without burn; the module lives here, with its training).
pub trait GeneratorInit {
    /// Builds a generator with the released training script's initialisation: conv weights
    /// N(0, 0.02) (`weights_init_normal` in `myutils/utils.py`), biases left at PyTorch's
    /// default U(-1/sqrt(fan_in), 1/sqrt(fan_in)) because that function does not touch them.
    /// Seed the device (`device.seed(..)`) first for reproducible weights.
    fn init(&self, device: &Device) -> Result<Generator>;
}

impl GeneratorInit for GeneratorConfig {
    fn init(&self, device: &Device) -> Result<Generator> {
        self.validate()?;
        Ok(Generator::init(self, device))
    }
}

impl Generator {
    pub(crate) fn init(config: &GeneratorConfig, device: &Device) -> Self {
        let w = |level| config.level_width(level);
        Self {
            in_conv_down1: Down::init(config.in_channels, w(0), device),
            down2: Down::init(w(0), w(1), device),
            down3: Down::init(w(1), w(2), device),
            down4: Down::init(w(2), w(3), device),
            up1: Up::init(w(3), device),
            up2: Up::init(w(2), device),
            up3: Up::init(w(1), device),
            up4: Up::init(w(0), device),
            out: match config.variant {
                Variant::Paper => conv(
                    config.decoder_out_width(),
                    config.out_channels,
                    3,
                    1,
                    device,
                ),
                // Zero output: the anchored variant starts exactly at its anchor.
                Variant::Anchored => conv_from_tensors(
                    Tensor::zeros(
                        [config.out_channels, config.decoder_out_width(), 3, 3],
                        device,
                    ),
                    Tensor::zeros([config.out_channels], device),
                    1,
                ),
            },
        }
    }

    /// The encoder levels in order.
    fn downs(&self) -> [&Down; LEVELS] {
        [&self.in_conv_down1, &self.down2, &self.down3, &self.down4]
    }

    /// The released forward pass.
    ///
    /// # Shapes
    /// - `x`: `[b, in_channels, h, w]` with `h` and `w` multiples of 16 (channels: clean RGB,
    ///   depth, light field, all in [0, 1])
    /// - output: `[b, out_channels, h, w]`, in (-1, 1) from the tanh (useful range [0, 1])
    ///
    /// # Panics
    /// In burn's shape checks when `h` or `w` is not a multiple of 16 (a skip connection and
    /// its upsampled partner then differ by a pixel). [`crate::burn_render::render`] pads any size.
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        self.run(x, MeanSource::Own).0
    }

    /// The forward pass with every block's channel attention driven by `means` instead of
    /// the mean of its own input. With the means of the whole image this renders a tile of it
    /// as the whole-image network would (away from the tile's borders).
    ///
    /// # Shapes
    /// - `x`: `[b, in_channels, h, w]`; `means[k]`: `[b, base_width * 2^k, 1, 1]`
    /// - output: `[b, out_channels, h, w]`
    pub fn forward_with_channel_means(&self, x: Tensor<4>, means: &ChannelMeans) -> Tensor<4> {
        self.run(x, MeanSource::Given(means)).0
    }

    /// The released forward pass, also returning the pooled channel-attention input of each
    /// encoder block.
    ///
    /// # Shapes
    /// - `x`: `[b, in_channels, h, w]`
    /// - output: `[b, out_channels, h, w]` and `means[k]`: `[b, base_width * 2^k, 1, 1]`
    pub fn forward_returning_channel_means(&self, x: Tensor<4>) -> (Tensor<4>, ChannelMeans) {
        self.run(x, MeanSource::Own)
    }

    /// Runs the encoder up to block `k = known.len()` and returns that block's channel-attention
    /// input (before pooling). Blocks before `k` gate their channels with `known[i]`.
    ///
    /// Tiled inference calls this once per block to accumulate each global mean over tiles.
    /// Fails when `known` already holds all four means.
    ///
    /// # Shapes
    /// - `x`: `[b, in_channels, h, w]`; `known[i]`: `[b, base_width * 2^i, 1, 1]`
    /// - output: `[b, base_width * 2^k, h / 2^(k+1), w / 2^(k+1)]`
    pub fn channel_attention_input(&self, x: Tensor<4>, known: &[Tensor<4>]) -> Result<Tensor<4>> {
        let k = known.len();
        if k >= LEVELS {
            return Err(ModelError::InvalidOptions(format!(
                "channel_attention_input: {k} means given, the encoder has only {LEVELS} blocks"
            )));
        }
        let mut h = x;
        for (level, down) in self.downs().into_iter().enumerate() {
            let stem = down.stem(h);
            let attended = down.block.channel_attention_input(stem.clone());
            if level == k {
                return Ok(attended);
            }
            h = down.block.finish(attended, stem, known[level].clone());
        }
        // Unreachable: k < LEVELS returns inside the loop.
        Err(ModelError::InvalidOptions(format!("block {k} not reached")))
    }

    fn run(&self, x: Tensor<4>, source: MeanSource<'_>) -> (Tensor<4>, ChannelMeans) {
        let mean_of = |level: usize| match &source {
            MeanSource::Own => None,
            MeanSource::Given(given) => Some(given[level].clone()),
        };
        let (x2, m0) = encode_level(&self.in_conv_down1, x, mean_of(0)); // [b, c, h/2, w/2]
        let (x4, m1) = encode_level(&self.down2, x2.clone(), mean_of(1)); // [b, 2c, h/4, w/4]
        let (x8, m2) = encode_level(&self.down3, x4.clone(), mean_of(2)); // [b, 4c, h/8, w/8]
        let (x16, m3) = encode_level(&self.down4, x8.clone(), mean_of(3)); // [b, 8c, h/16, w/16]
        let y8 = self.up1.forward(x16) + x8; // [b, 4c, h/8, w/8]
        let y4 = self.up2.forward(y8) + x4; // [b, 2c, h/4, w/4]
        let y2 = self.up3.forward(y4) + x2; // [b, c, h/2, w/2]
        let y = self.up4.forward(y2); // [b, c/2, h, w]
        let out = self.out.forward(y).tanh(); // [b, out_channels, h, w]
        (out, [m0, m1, m2, m3])
    }
}

/// One encoder level; the channel gate uses `mean` when given, else the block's own pooled
/// input. Returns the level's output and the mean used (`[b, c_k, 1, 1]`).
fn encode_level(down: &Down, x: Tensor<4>, mean: Option<Tensor<4>>) -> (Tensor<4>, Tensor<4>) {
    let stem = down.stem(x); // [b, c_k, h_k, w_k]
    let attended = down.block.channel_attention_input(stem.clone());
    let mean = mean.unwrap_or_else(|| global_mean(attended.clone()));
    (down.block.finish(attended, stem, mean.clone()), mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Distribution, TensorData};
    use uwnr_model::config::param_count;

    #[test]
    fn narrow_generator_shapes_and_params() {
        let device = Device::flex();
        device.seed(1);
        let cfg = GeneratorConfig::with_base_width(8);
        let g = cfg.init(&device).unwrap();
        assert_eq!(g.num_params(), param_count(&cfg, false));
        let x = Tensor::<4>::random([1, 7, 32, 48], Distribution::Uniform(0.0, 1.0), &device);
        let (y, means) = g.forward_returning_channel_means(x.clone());
        assert_eq!(y.dims(), [1, 3, 32, 48]);
        for (k, m) in means.iter().enumerate() {
            assert_eq!(m.dims(), [1, 8 << k, 1, 1]);
        }
        // Feeding back the network's own means reproduces the plain forward exactly.
        let again = g.forward_with_channel_means(x.clone(), &means);
        let diff: f32 = (y.clone() - again).abs().max().into_scalar();
        assert_eq!(diff, 0.0);
        // Other means change the output: the given means are really used.
        let zeros = means.clone().map(|m| m.zeros_like());
        let other = g.forward_with_channel_means(x.clone(), &zeros);
        let diff: f32 = (y - other).abs().max().into_scalar();
        assert!(diff > 0.0);
        // The CA input of block k pools to means[k] when earlier means are the network's own.
        for k in 0..LEVELS {
            let a = g.channel_attention_input(x.clone(), &means[..k]).unwrap();
            let d: f32 = (global_mean(a) - means[k].clone())
                .abs()
                .max()
                .into_scalar();
            assert!(d < 1e-6, "block {k}: {d}");
        }
        assert!(g.channel_attention_input(x, &means).is_err());
    }

    #[test]
    fn init_statistics_follow_the_released_training() {
        let device = Device::flex();
        device.seed(7);
        let g = GeneratorConfig::default().init(&device).unwrap();
        let w = g
            .down4
            .block
            .conk3
            .weight
            .val()
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let n = w.len() as f64;
        let mean = w.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let std = (w
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!(mean.abs() < 1e-3, "{mean}");
        assert!((std - INIT_WEIGHT_STD).abs() < 1e-3, "{std}");
        // conk3 of down4: fan_in = 512 * 9, PyTorch's bias bound 1/sqrt(fan_in).
        let bound = 1.0 / (512.0f32 * 9.0).sqrt();
        let b = g.down4.block.conk3.bias.as_ref().unwrap().val().into_data();
        let b = b.try_to_vec::<f32>().unwrap();
        assert!(b.iter().all(|v| v.abs() <= bound));
        assert!(b.iter().any(|v| v.abs() > bound / 2.0));
    }

    #[test]
    fn pixel_shuffle_matches_torch_layout() {
        // torch.nn.PixelShuffle(2)(torch.arange(8.).reshape(1, 4, 1, 2)).flatten():
        // out[0, 0] = [[0, 2, 1, 3], [4, 6, 5, 7]] (channel 2i + j goes to sub-pixel (i, j)).
        let device = Device::flex();
        let x = Tensor::<4>::from_data(
            TensorData::new((0..8).map(|v| v as f32).collect::<Vec<_>>(), [1, 4, 1, 2]),
            &device,
        );
        let y = PixelShuffleConfig::new(2).init().forward(x);
        assert_eq!(y.dims(), [1, 1, 2, 4]);
        let v = y.into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(v, [0.0, 2.0, 1.0, 3.0, 4.0, 6.0, 5.0, 7.0]);
    }
}
