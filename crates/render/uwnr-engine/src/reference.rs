//! Plain reference implementations of every operation of the generator, on planar tensors,
//! with f64 accumulation and `std` math: the ground truth the optimised kernels are tested
//! against. They follow PyTorch's definitions (`nn.Conv2d` with zero padding `k / 2`,
//! `nn.ELU`, `nn.LeakyReLU`, `nn.PixelShuffle`, `nn.AdaptiveAvgPool2d(1)`).

use crate::kernels::Act;
use crate::kernels::act::LEAKY_RELU_SLOPE;
use crate::tensor::Planar;
use crate::weights::{BlockWeights, ConvWeights, GeneratorWeights};

/// `nn.Conv2d(cin, cout, k, stride, padding = k / 2)` with weights `[cout][cin][k][k]`.
#[must_use]
pub fn conv2d(
    x: &Planar,
    weight: &[f32],
    bias: &[f32],
    cout: usize,
    k: usize,
    stride: usize,
) -> Planar {
    let (cin, h, w) = (x.channels, x.height, x.width);
    let pad = k / 2;
    let ho = (h + 2 * pad - k) / stride + 1;
    let wo = (w + 2 * pad - k) / stride + 1;
    let mut out = Planar::zeros(cout, ho, wo);
    for co in 0..cout {
        for oy in 0..ho {
            for ox in 0..wo {
                let mut s = f64::from(bias[co]);
                for ci in 0..cin {
                    for ky in 0..k {
                        let iy = (oy * stride + ky) as isize - pad as isize;
                        if iy < 0 || iy >= h as isize {
                            continue;
                        }
                        for kx in 0..k {
                            let ix = (ox * stride + kx) as isize - pad as isize;
                            if ix < 0 || ix >= w as isize {
                                continue;
                            }
                            let v = x.data[(ci * h + iy as usize) * w + ix as usize];
                            let wv = weight[((co * cin + ci) * k + ky) * k + kx];
                            s += f64::from(v) * f64::from(wv);
                        }
                    }
                }
                out.data[(co * ho + oy) * wo + ox] = s as f32;
            }
        }
    }
    out
}

/// The activation `act`, elementwise, with `std` math.
#[must_use]
pub fn activate(act: Act, mut x: Planar) -> Planar {
    for v in &mut x.data {
        *v = match act {
            Act::Identity => *v,
            Act::LeakyRelu => {
                if *v > 0.0 {
                    *v
                } else {
                    *v * LEAKY_RELU_SLOPE
                }
            }
            Act::Elu => {
                if *v > 0.0 {
                    *v
                } else {
                    v.exp_m1()
                }
            }
            Act::Tanh => v.tanh(),
        };
    }
    x
}

fn sigmoid(v: f32) -> f32 {
    1.0 / (1.0 + (-v).exp())
}

fn add(mut a: Planar, b: &Planar) -> Planar {
    for (x, y) in a.data.iter_mut().zip(&b.data) {
        *x += y;
    }
    a
}

fn conv(x: &Planar, c: &ConvWeights, stride: usize) -> Planar {
    conv2d(x, &c.weight, &c.bias, c.cout, c.k, stride)
}

/// `nn.PixelShuffle(r)`: channel `c r^2 + i r + j` goes to sub-pixel `(i, j)` of channel `c`.
#[must_use]
pub fn pixel_shuffle(x: &Planar, r: usize) -> Planar {
    let (c, h, w) = (x.channels / (r * r), x.height, x.width);
    let mut out = Planar::zeros(c, h * r, w * r);
    for ch in 0..c {
        for i in 0..r {
            for j in 0..r {
                let src = ch * r * r + i * r + j;
                for y in 0..h {
                    for xx in 0..w {
                        out.data[(ch * h * r + y * r + i) * w * r + xx * r + j] =
                            x.data[(src * h + y) * w + xx];
                    }
                }
            }
        }
    }
    out
}

/// Mean over height and width of each channel.
#[must_use]
pub fn channel_means(x: &Planar) -> Vec<f32> {
    let plane = x.height * x.width;
    x.data
        .chunks_exact(plane)
        .map(|p| (p.iter().map(|&v| f64::from(v)).sum::<f64>() / plane as f64) as f32)
        .collect()
}

/// `SA(LeakyReLU(conk1(x) + conk3(x) + x))`: the input of the block's channel attention.
#[must_use]
pub fn block_attention_input(b: &BlockWeights, x: &Planar) -> Planar {
    let y = add(add(conv(x, &b.conk3, 1), &conv(x, &b.conk1, 1)), x);
    let o = activate(Act::LeakyRelu, y);
    let hidden = activate(Act::LeakyRelu, conv(&o, &b.sa_reduce, 1));
    let gate = conv(&hidden, &b.sa_expand, 1); // [1, h, w]
    let mut t = o;
    let plane = t.height * t.width;
    for p in t.data.chunks_exact_mut(plane) {
        for (v, &g) in p.iter_mut().zip(&gate.data) {
            *v *= sigmoid(g);
        }
    }
    t
}

/// `CA(attended) + residual` with the channel gate computed from `mean`.
#[must_use]
pub fn block_finish(
    b: &BlockWeights,
    attended: &Planar,
    residual: &Planar,
    mean: &[f32],
) -> Planar {
    let m = Planar {
        channels: mean.len(),
        height: 1,
        width: 1,
        data: mean.to_vec(),
    };
    let hidden = activate(Act::LeakyRelu, conv(&m, &b.ca_reduce, 1));
    let gate = conv(&hidden, &b.ca_expand, 1);
    let plane = attended.height * attended.width;
    let mut out = attended.clone();
    for (c, p) in out.data.chunks_exact_mut(plane).enumerate() {
        let g = sigmoid(gate.data[c]);
        for v in p {
            *v *= g;
        }
    }
    add(out, residual)
}

/// The released forward pass of the generator; `means` replaces each block's own channel
/// pool when given. Returns the output and the means used.
#[must_use]
pub fn generator(
    g: &GeneratorWeights,
    x: &Planar,
    means: Option<&[Vec<f32>]>,
) -> (Planar, Vec<Vec<f32>>) {
    let mut skips = Vec::new();
    let mut used = Vec::new();
    let mut h = x.clone();
    for (level, d) in g.downs.iter().enumerate() {
        let stem = activate(Act::Elu, conv(&h, &d.conv, 2));
        let attended = block_attention_input(&d.block, &stem);
        let mean = means.map_or_else(|| channel_means(&attended), |m| m[level].clone());
        h = block_finish(&d.block, &attended, &stem, &mean);
        used.push(mean);
        skips.push(h.clone());
    }
    skips.pop();
    for up in &g.ups {
        h = pixel_shuffle(&activate(Act::Elu, conv(&h, up, 1)), 2);
        if let Some(skip) = skips.pop() {
            h = add(h, &skip);
        }
    }
    (activate(Act::Tanh, conv(&h, &g.out, 1)), used)
}

/// Largest absolute difference between two equally long slices (infinite when the lengths
/// differ).
#[must_use]
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    if a.len() != b.len() {
        return f32::INFINITY;
    }
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// `n` seeded values in `[-scale, scale)` (a 64-bit LCG), the operands of the kernels' tests.
#[cfg(test)]
pub(crate) fn test_values(seed: u64, n: usize, scale: f32) -> Vec<f32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0 * scale
        })
        .collect()
}
