//! Shallow-UWnet (Naik, Swarnakar, Mittal, "Shallow-UWnet: Compressed Model for Underwater Image
//! Enhancement", AAAI 2021 student abstract), as its released `model.py` builds it:
//!
//! - `input`: conv3x3 `3 -> w` + ReLU;
//! - `blocks.i` (three): `a = ReLU(conv1(ReLU(drop(conv(ReLU(drop(conv(x))))))))` with one
//!   conv3x3 `w -> w` (`conv`) applied twice and conv3x3 `w -> w-3` (`conv1`), then the raw
//!   3-channel input image is concatenated back: `[a, image]`, `w` channels again;
//! - `output`: conv3x3 `w -> 3`, no activation.
//!
//! No conv has a bias. `drop` is `Dropout2d(0.2)`: whole channels are zeroed (and the rest
//! scaled by `1/(1-p)`) in training only. Field names follow the PyTorch state-dict keys.

use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{Initializer, PaddingConfig2d};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor, TensorData};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::error::{EnhanceError, Result};

/// Channels of the image in and out.
pub const IMAGE_CHANNELS: usize = 3;
/// Kernel size of every conv.
pub const KERNEL: usize = 3;

/// Architecture of the network; the default is the paper's.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShallowUwnetConfig {
    /// Feature channels (`w`, 64 in the paper).
    pub width: usize,
    /// Number of blocks (3 in the paper).
    pub blocks: usize,
    /// Channel dropout probability in training (0.2 in the paper).
    pub dropout: f64,
}

impl Default for ShallowUwnetConfig {
    fn default() -> Self {
        Self {
            width: 64,
            blocks: 3,
            dropout: 0.2,
        }
    }
}

impl ShallowUwnetConfig {
    /// Checks the config can build a network.
    pub fn validate(&self) -> Result<()> {
        if self.width <= IMAGE_CHANNELS {
            return Err(EnhanceError::InvalidConfig(format!(
                "width must exceed {IMAGE_CHANNELS} (the image is concatenated back into it), got {}",
                self.width
            )));
        }
        if self.blocks == 0 {
            return Err(EnhanceError::InvalidConfig("at least one block".into()));
        }
        if !(0.0..1.0).contains(&self.dropout) {
            return Err(EnhanceError::InvalidConfig(format!(
                "dropout must be in [0, 1), got {}",
                self.dropout
            )));
        }
        Ok(())
    }

    /// Number of parameters: `9·3·w + blocks·(9·w·w + 9·w·(w−3)) + 9·w·3` (219,456 for the
    /// paper's config).
    #[must_use]
    pub fn param_count(&self) -> usize {
        let (w, k) = (self.width, KERNEL * KERNEL);
        k * IMAGE_CHANNELS * w
            + self.blocks * (k * w * w + k * w * (w - IMAGE_CHANNELS))
            + k * w * IMAGE_CHANNELS
    }

    /// Builds the network with weights drawn from `init` (the released code keeps PyTorch's
    /// default conv init: Kaiming-uniform with `a = sqrt(5)`, i.e. U(±1/sqrt(fan_in))).
    pub fn init(&self, device: &Device) -> Result<ShallowUwnet> {
        self.validate()?;
        let w = self.width;
        Ok(ShallowUwnet {
            input: conv(IMAGE_CHANNELS, w, device),
            blocks: (0..self.blocks)
                .map(|_| Block {
                    conv: conv(w, w, device),
                    conv1: conv(w, w - IMAGE_CHANNELS, device),
                })
                .collect(),
            output: conv(w, IMAGE_CHANNELS, device),
        })
    }
}

/// A bias-free conv3x3 with zero padding 1, initialised as PyTorch's default.
fn conv(cin: usize, cout: usize, device: &Device) -> Conv2d {
    let bound = 1.0 / ((cin * KERNEL * KERNEL) as f64).sqrt();
    Conv2dConfig::new([cin, cout], [KERNEL, KERNEL])
        .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
        .with_bias(false)
        .with_initializer(Initializer::Uniform {
            min: -bound,
            max: bound,
        })
        .init(device)
}

/// Builds a bias-free conv3x3 from a `[cout, cin, 3, 3]` weight (shape checked by the caller).
pub(crate) fn conv_from_weight(weight: Tensor<4>) -> Conv2d {
    Conv2d {
        weight: Param::from_tensor(weight),
        bias: None,
        stride: [1, 1],
        kernel_size: [KERNEL, KERNEL],
        dilation: [1, 1],
        groups: 1,
        padding: PaddingConfig2d::Explicit(1, 1, 1, 1),
    }
}

/// One block (`ConvBlock` in `model.py`).
#[derive(Module, Debug)]
pub struct Block {
    /// conv3x3 `w -> w`, applied twice.
    pub conv: Conv2d,
    /// conv3x3 `w -> w-3`.
    pub conv1: Conv2d,
}

/// Shallow-UWnet.
#[derive(Module, Debug)]
pub struct ShallowUwnet {
    /// conv3x3 `3 -> w`.
    pub input: Conv2d,
    /// The blocks.
    pub blocks: Vec<Block>,
    /// conv3x3 `w -> 3`.
    pub output: Conv2d,
}

/// Channel-dropout masks for one training forward pass, drawn from a seeded generator so a
/// step is reproducible.
pub struct Dropout<'a, R: Rng> {
    /// Drop probability.
    pub p: f64,
    /// Where the masks come from.
    pub rng: &'a mut R,
}

impl<R: Rng> Dropout<'_, R> {
    /// `x` with whole channels zeroed with probability `p` and the rest scaled by `1/(1-p)`.
    fn apply(&mut self, x: Tensor<4>) -> Tensor<4> {
        if self.p <= 0.0 {
            return x;
        }
        let [b, c, _, _] = x.dims();
        let keep = 1.0 - self.p;
        let mask: Vec<f32> = (0..b * c)
            .map(|_| {
                if self.rng.random::<f64>() < keep {
                    (1.0 / keep) as f32
                } else {
                    0.0
                }
            })
            .collect();
        let mask = Tensor::<4>::from_data(TensorData::new(mask, [b, c, 1, 1]), &x.device());
        x * mask // [b, c, h, w]
    }
}

impl ShallowUwnet {
    /// Enhances a batch (inference: no dropout).
    ///
    /// # Shapes
    /// - `image`: `[b, 3, h, w]`, RGB in [0, 1]; output: `[b, 3, h, w]` (not clamped, as in the
    ///   released code; callers clamp when they save)
    pub fn forward(&self, image: Tensor<4>) -> Tensor<4> {
        self.forward_impl::<rand_chacha::ChaCha8Rng>(image, None)
    }

    /// The training forward pass, with channel dropout after each `conv`.
    pub fn forward_train<R: Rng>(
        &self,
        image: Tensor<4>,
        dropout: &mut Dropout<'_, R>,
    ) -> Tensor<4> {
        self.forward_impl(image, Some(dropout))
    }

    fn forward_impl<R: Rng>(
        &self,
        image: Tensor<4>,
        mut dropout: Option<&mut Dropout<'_, R>>,
    ) -> Tensor<4> {
        let mut drop = |x: Tensor<4>| match dropout.as_deref_mut() {
            Some(d) => d.apply(x),
            None => x,
        };
        let mut x = relu(self.input.forward(image.clone())); // [b, w, h, w]
        for block in &self.blocks {
            let a = relu(drop(block.conv.forward(x)));
            let a = relu(drop(block.conv.forward(a)));
            let a = relu(block.conv1.forward(a)); // [b, w-3, h, w]
            x = Tensor::cat(vec![a, image.clone()], 1); // [b, w, h, w]
        }
        self.output.forward(x)
    }
}
