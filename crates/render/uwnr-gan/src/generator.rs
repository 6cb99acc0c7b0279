//! The GAN baseline's parameter generator for rendering, without a training framework: the
//! clean image and its depth area-averaged to `encoder_size²` (PyTorch's adaptive average
//! pooling), stride-2 conv3x3 + LeakyReLU(0.2) layers, a global average pool, the water code
//! `z` appended, a hidden layer with LeakyReLU(0.2) and a linear head to the raw parameters
//! ([`WaterValues::from_raw`]). The architecture and its sources are described with the module
//! that trains it (`uwnr-gan-train`'s `model`); the tests there check the two agree.

use uwnr_core::Image;

use crate::config::{ENCODER_IN, GeneratorConfig, LEAKY_SLOPE, RAW_PARAMS};
use crate::error::{GanError, Result};
use crate::imaging::{WaterValues, check_inputs, render};

/// One stride-2 conv3x3 (padding 1) of the encoder.
#[derive(Clone, Debug)]
pub struct Conv {
    /// `[out, in, 3, 3]`, row-major.
    pub weight: Vec<f32>,
    /// `[out]`.
    pub bias: Vec<f32>,
    /// Input channels.
    pub cin: usize,
    /// Output channels.
    pub cout: usize,
}

/// A fully connected layer, `y = x W + b` with `W` stored `[in, out]` (burn's layout, which the
/// weights files keep).
#[derive(Clone, Debug)]
pub struct Linear {
    /// `[in, out]`, row-major.
    pub weight: Vec<f32>,
    /// `[out]`.
    pub bias: Vec<f32>,
    /// Inputs.
    pub din: usize,
    /// Outputs.
    pub dout: usize,
}

/// The trained generator: its layers and its config.
#[derive(Clone, Debug)]
pub struct Generator {
    /// The stride-2 conv3x3 layers over `[clean, depth]`.
    pub encoder: Vec<Conv>,
    /// `c_last + z_dim → hidden`.
    pub hidden: Linear,
    /// `hidden → RAW_PARAMS`.
    pub head: Linear,
    /// The architecture and the imaging settings.
    pub config: GeneratorConfig,
}

fn leaky(x: f32) -> f32 {
    if x >= 0.0 { x } else { x * LEAKY_SLOPE as f32 }
}

/// PyTorch's adaptive average pooling of `[c][h][w]` planes to `[c][s][s]`: output cell `i`
/// averages input rows `floor(i h / s) .. ceil((i + 1) h / s)`, and the same for columns.
fn adaptive_avg_pool(x: &[f32], c: usize, h: usize, w: usize, s: usize) -> Vec<f32> {
    let span = |i: usize, n: usize| (i * n / s, ((i + 1) * n).div_ceil(s));
    let mut out = Vec::with_capacity(c * s * s);
    for ch in 0..c {
        let plane = &x[ch * h * w..(ch + 1) * h * w];
        for oy in 0..s {
            let (y0, y1) = span(oy, h);
            for ox in 0..s {
                let (x0, x1) = span(ox, w);
                let mut sum = 0.0f32;
                for y in y0..y1 {
                    sum += plane[y * w + x0..y * w + x1].iter().sum::<f32>();
                }
                out.push(sum / ((y1 - y0) * (x1 - x0)) as f32);
            }
        }
    }
    out
}

impl Conv {
    /// The conv (stride 2, padding 1) and the LeakyReLU on `[cin][h][w]`; returns
    /// `[cout][h'][w']` with `h' = (h − 1) / 2 + 1`.
    fn forward_leaky(&self, x: &[f32], h: usize, w: usize) -> (Vec<f32>, usize, usize) {
        let (oh, ow) = ((h + 2 - 3) / 2 + 1, (w + 2 - 3) / 2 + 1);
        let mut out = vec![0.0f32; self.cout * oh * ow];
        for co in 0..self.cout {
            for oy in 0..oh {
                for ox in 0..ow {
                    let mut sum = self.bias[co];
                    for ci in 0..self.cin {
                        for ky in 0..3 {
                            let Some(iy) = (oy * 2 + ky).checked_sub(1).filter(|&v| v < h) else {
                                continue;
                            };
                            for kx in 0..3 {
                                let Some(ix) = (ox * 2 + kx).checked_sub(1).filter(|&v| v < w)
                                else {
                                    continue;
                                };
                                sum += self.weight[((co * self.cin + ci) * 3 + ky) * 3 + kx]
                                    * x[(ci * h + iy) * w + ix];
                            }
                        }
                    }
                    out[(co * oh + oy) * ow + ox] = leaky(sum);
                }
            }
        }
        (out, oh, ow)
    }
}

impl Linear {
    fn forward(&self, x: &[f32]) -> Vec<f32> {
        (0..self.dout)
            .map(|o| {
                x.iter().enumerate().fold(self.bias[o], |acc, (i, &v)| {
                    acc + v * self.weight[i * self.dout + o]
                })
            })
            .collect()
    }
}

impl Generator {
    /// Predicts the image-formation parameters of `clean` (RGB in [0, 1]) with its `depth`
    /// (1 channel, the same size) and the water code `z` (`z_dim` values).
    pub fn params(&self, clean: &Image, depth: &Image, z: &[f32]) -> Result<WaterValues> {
        check_inputs(clean, depth)?;
        if z.len() != self.config.z_dim {
            return Err(GanError::ShapeMismatch {
                what: "water code z",
                expected: vec![self.config.z_dim],
                got: vec![z.len()],
            });
        }
        let (w, h) = clean.size();
        let s = self.config.encoder_size;
        let mut x = clean.data().to_vec();
        x.extend_from_slice(depth.data()); // [4, h, w]
        let mut x = adaptive_avg_pool(&x, ENCODER_IN, h, w, s); // [4, s, s]
        let (mut xh, mut xw) = (s, s);
        for conv in &self.encoder {
            (x, xh, xw) = conv.forward_leaky(&x, xh, xw); // [c, s/2, s/2] per layer
        }
        let n = (xh * xw) as f32;
        let mut feature: Vec<f32> = x
            .chunks(xh * xw)
            .map(|p| p.iter().sum::<f32>() / n)
            .collect(); // [c]
        feature.extend_from_slice(z); // [c + z_dim]
        let hidden: Vec<f32> = self
            .hidden
            .forward(&feature)
            .into_iter()
            .map(leaky)
            .collect(); // [hidden]
        let raw: [f32; RAW_PARAMS] =
            self.head
                .forward(&hidden)
                .try_into()
                .map_err(|v: Vec<f32>| GanError::ShapeMismatch {
                    what: "head outputs",
                    expected: vec![RAW_PARAMS],
                    got: vec![v.len()],
                })?;
        Ok(WaterValues::from_raw(&raw))
    }

    /// Predicts the parameters and renders the underwater image.
    pub fn forward(&self, clean: &Image, depth: &Image, z: &[f32]) -> Result<(Image, WaterValues)> {
        let values = self.params(clean, depth, z)?;
        let out = render(clean, depth, &values, &self.config.imaging)?;
        Ok((out, values))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adaptive_pooling_averages_pytorchs_windows() {
        // 1 x 3 x 3 to 2 x 2: windows rows/cols 0..2 and 1..3.
        let x: Vec<f32> = (0..9).map(|v| v as f32).collect();
        let out = adaptive_avg_pool(&x, 1, 3, 3, 2);
        assert_eq!(out, vec![2.0, 3.0, 5.0, 6.0]);
        // Exact halving averages 2 x 2 blocks.
        let x: Vec<f32> = (0..16).map(|v| v as f32).collect();
        assert_eq!(
            adaptive_avg_pool(&x, 1, 4, 4, 2),
            vec![2.5, 4.5, 10.5, 12.5]
        );
    }

    #[test]
    fn the_conv_strides_and_pads_as_pytorch_does() {
        // One input channel of ones, a kernel of ones, bias 0: each output counts the taps
        // inside the image (4 at the corner, 6 on an edge, 9 inside).
        let conv = Conv {
            weight: vec![1.0; 9],
            bias: vec![0.0],
            cin: 1,
            cout: 1,
        };
        let (out, oh, ow) = conv.forward_leaky(&[1.0; 25], 5, 5);
        assert_eq!((oh, ow), (3, 3));
        assert_eq!(out, vec![4.0, 6.0, 4.0, 6.0, 9.0, 6.0, 4.0, 6.0, 4.0]);
    }
}
