//! VGG19 features for the perceptual loss (Simonyan & Zisserman 2015), as the released
//! `loss/perceptual.py` uses them: `torchvision.models.vgg19(pretrained=True).features`, cut at
//! `[:1]`, `[:3]`, `[:5]`, `[:9]` and `[:13]`, each cut's output compared with L1 and weighted
//! 0.2, the images fed in [0, 1] without ImageNet normalisation.
//!
//! The first 13 modules of `features` are
//! `0 conv(3,64) 1 relu 2 conv(64,64) 3 relu 4 maxpool 5 conv(64,128) 6 relu 7 conv(128,128)
//! 8 relu 9 maxpool 10 conv(128,256) 11 relu 12 conv(256,256)`, so the five cuts end at the
//! output of conv 0, conv 2, pool 4, relu 8 and conv 12. Convs are 3x3 with padding 1, pools
//! 2x2 with stride 2.
//!
//! Weights come from a safetensors file with torchvision's key names
//! (`features.N.weight` `[out, in, 3, 3]`, `features.N.bias` `[out]`), e.g. written by
//! `safetensors.torch.save_file(torchvision.models.vgg19(weights="DEFAULT").state_dict(), f)`.
//! Keys of later layers (and the classifier) are ignored.
//!
//! The perceptual distance itself, [`Vgg19Features::perceptual_loss`], is a loss and lives with
//! the others in [`crate::losses`].

use std::path::Path;

use burn::module::{Module, Param};
use burn::nn::PaddingConfig2d;
use burn::nn::conv::Conv2d;
use burn::tensor::activation::relu;
use burn::tensor::module::max_pool2d;
use burn::tensor::ops::MaxPoolOptions;
use burn::tensor::{Device, Tensor, TensorData};
use safetensors::{Dtype, SafeTensors};

use crate::error::{Result, TrainError};

/// `(index in features, in channels, out channels)` of the convs before cut point 13.
pub const VGG19_CONVS: [(usize, usize, usize); 6] = [
    (0, 3, 64),
    (2, 64, 64),
    (5, 64, 128),
    (7, 128, 128),
    (10, 128, 256),
    (12, 256, 256),
];
/// Weight of each cut's L1 in `PerceptualLoss.forward`.
pub const CUT_WEIGHT: f64 = 0.2;
/// Kernel of the VGG convs.
const KERNEL: usize = 3;

/// VGG19 `features[:13]`, frozen.
#[derive(Module, Debug)]
pub struct Vgg19Features {
    /// `features.0`.
    pub conv0: Conv2d,
    /// `features.2`.
    pub conv2: Conv2d,
    /// `features.5`.
    pub conv5: Conv2d,
    /// `features.7`.
    pub conv7: Conv2d,
    /// `features.10`.
    pub conv10: Conv2d,
    /// `features.12`.
    pub conv12: Conv2d,
}

impl Vgg19Features {
    /// Loads the six convs from a safetensors file with torchvision's keys onto `device`; the
    /// parameters do not require gradients.
    pub fn load(path: &Path, device: &Device) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|source| TrainError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&bytes, path, device)
    }

    /// [`Self::load`] from bytes in memory (`path` only names the source in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path, device: &Device) -> Result<Self> {
        let err = |reason: String| TrainError::Vgg {
            path: path.to_path_buf(),
            reason,
        };
        let st = SafeTensors::deserialize(bytes).map_err(|e| err(e.to_string()))?;
        let read = |key: String, shape: &[usize]| -> Result<Vec<f32>> {
            let view = st
                .tensor(&key)
                .map_err(|_| err(format!("missing tensor {key}")))?;
            if view.shape() != shape {
                return Err(err(format!(
                    "{key} has shape {:?}, expected {shape:?}",
                    view.shape()
                )));
            }
            let data = view.data();
            let values: Vec<f32> = match view.dtype() {
                Dtype::F32 => data
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
                Dtype::F16 => data
                    .chunks_exact(2)
                    .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
                    .collect(),
                Dtype::BF16 => data
                    .chunks_exact(2)
                    .map(|b| half::bf16::from_le_bytes([b[0], b[1]]).to_f32())
                    .collect(),
                other => {
                    return Err(err(format!(
                        "{key} has dtype {other:?}, expected a float type"
                    )));
                }
            };
            if values.iter().any(|v| !v.is_finite()) {
                return Err(err(format!("{key} holds non-finite values")));
            }
            Ok(values)
        };
        let mut convs = Vec::with_capacity(VGG19_CONVS.len());
        for (index, cin, cout) in VGG19_CONVS {
            let shape = [cout, cin, KERNEL, KERNEL];
            let w = read(format!("features.{index}.weight"), &shape)?;
            let b = read(format!("features.{index}.bias"), &[cout])?;
            convs.push(frozen_conv(
                Tensor::from_data(TensorData::new(w, shape), device),
                Tensor::from_data(TensorData::new(b, [cout]), device),
            ));
        }
        let [conv0, conv2, conv5, conv7, conv10, conv12]: [Conv2d; 6] = convs
            .try_into()
            .map_err(|_| err("wrong number of convs".into()))?;
        Ok(Self {
            conv0,
            conv2,
            conv5,
            conv7,
            conv10,
            conv12,
        }
        .no_grad())
    }

    /// The outputs of the five cut points `features[:1]`, `[:3]`, `[:5]`, `[:9]`, `[:13]`.
    ///
    /// # Shapes
    /// - `x`: `[b, 3, h, w]`; outputs: `[b, 64, h, w]`, `[b, 64, h, w]`, `[b, 64, h/2, w/2]`,
    ///   `[b, 128, h/2, w/2]`, `[b, 256, h/4, w/4]`
    pub fn cuts(&self, x: Tensor<4>) -> [Tensor<4>; 5] {
        let f1 = self.conv0.forward(x); // features[:1]
        let f3 = self.conv2.forward(relu(f1.clone())); // features[:3]
        let f5 = max_pool2d(relu(f3.clone()), pool()); // features[:5]
        let f9 = relu(self.conv7.forward(relu(self.conv5.forward(f5.clone())))); // features[:9]
        let f13 = self
            .conv12
            .forward(relu(self.conv10.forward(max_pool2d(f9.clone(), pool())))); // features[:13]
        [f1, f3, f5, f9, f13]
    }
}

fn pool() -> MaxPoolOptions<2> {
    MaxPoolOptions::new([2, 2]).with_stride([2, 2])
}

fn frozen_conv(weight: Tensor<4>, bias: Tensor<1>) -> Conv2d {
    let [_, _, kh, kw] = weight.dims();
    Conv2d {
        weight: Param::from_tensor(weight),
        bias: Some(Param::from_tensor(bias)),
        stride: [1, 1],
        kernel_size: [kh, kw],
        dilation: [1, 1],
        groups: 1,
        padding: PaddingConfig2d::Explicit(1, 1, 1, 1),
    }
}
