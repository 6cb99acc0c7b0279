//! One encoder level of the generator on the engine's kernels (the block, its spatial and
//! channel attention, the residual) and the decoder's pixel shuffle with its skip.

use rayon::prelude::*;

use super::{Conv3, Level, UPSCALE};
use crate::kernels::act::{LEAKY_RELU_SLOPE, sigmoid};
use crate::tensor::{Feature, Pool};
use crate::weights::{ATTENTION_REDUCTION, ConvWeights};

impl Level {
    /// The stem (the block's residual) and `SA(LeakyReLU(conk1 + conk3 + id))`.
    pub(super) fn attention_input(&self, x: &Feature, pool: &mut Pool) -> (Feature, Feature) {
        self.attention_input_probed(x, pool, &mut |_| {})
    }

    /// [`Self::attention_input`], calling `probe` as each stage ends.
    pub(super) fn attention_input_probed(
        &self,
        x: &Feature,
        pool: &mut Pool,
        probe: &mut dyn FnMut(&str),
    ) -> (Feature, Feature) {
        let (ho, wo) = self.stem.out_size(x.h, x.w);
        let mut stem = Feature::output_in(pool, ho, wo, self.c, 1);
        self.stem.run(x, &mut stem, pool);
        probe("stem");
        let mut o = Feature::output_in(pool, ho, wo, self.c, 0);
        self.body.run(&stem, &mut o, pool);
        probe("body");
        self.spatial_attention(&mut o, pool);
        probe("spatial_attention");
        (stem, o)
    }

    /// `o <- o * sigmoid(expand(LeakyReLU(reduce(o))))`, per pixel.
    pub(super) fn spatial_attention(&self, o: &mut Feature, pool: &mut Pool) {
        let (ho, wo) = (o.h, o.w);
        let r = self.c / ATTENTION_REDUCTION;
        let mut hidden = Feature::output_in(pool, ho, wo, r, 0);
        self.sa_reduce.run(o, &mut hidden, pool);
        let (c, w2, b2) = (self.c, &self.sa_expand, self.sa_expand_bias);
        o.data
            .par_chunks_mut(wo * c)
            .zip(hidden.data.par_chunks(wo * r))
            .for_each(|(orow, hrow)| {
                for (px, hid) in orow.chunks_exact_mut(c).zip(hrow.chunks_exact(r)) {
                    let z: f32 = hid.iter().zip(w2).map(|(a, b)| a * b).sum::<f32>() + b2;
                    let s = sigmoid(z);
                    for v in px {
                        *v *= s;
                    }
                }
            });
        pool.give(hidden);
    }

    /// `stem + t g` with the channel gate `g` computed from `mean`.
    pub(super) fn finish(&self, mut stem: Feature, attended: &Feature, mean: &[f32]) -> Feature {
        let gate = channel_gate(&self.ca_reduce, &self.ca_expand, mean);
        let (w, c) = (stem.w, self.c);
        let stride = stem.row_stride();
        let pad = stem.pad;
        stem.data
            .par_chunks_mut(stride)
            .skip(pad)
            .take(stem.h)
            .zip(attended.data.par_chunks(w * c))
            .for_each(|(srow, trow)| {
                let srow = &mut srow[pad * c..pad * c + w * c];
                for (s, t) in srow.chunks_exact_mut(c).zip(trow.chunks_exact(c)) {
                    for ((s, t), g) in s.iter_mut().zip(t).zip(&gate) {
                        *s += t * g;
                    }
                }
            });
        stem
    }
}

/// Mean over all pixels of each channel (f64 sums).
pub(super) fn pool_means(t: &Feature) -> Vec<f32> {
    let c = t.c;
    let sums = (0..t.h)
        .into_par_iter()
        .fold(
            || vec![0.0f64; c],
            |mut acc, y| {
                for px in t.row(y).chunks_exact(c) {
                    for (a, &v) in acc.iter_mut().zip(px) {
                        *a += f64::from(v);
                    }
                }
                acc
            },
        )
        .reduce(
            || vec![0.0f64; c],
            |mut a, b| {
                for (x, y) in a.iter_mut().zip(b) {
                    *x += y;
                }
                a
            },
        );
    let n = (t.h * t.w) as f64;
    sums.into_iter().map(|s| (s / n) as f32).collect()
}

/// `sigmoid(expand(LeakyReLU(reduce(mean))))`.
fn channel_gate(reduce: &ConvWeights, expand: &ConvWeights, mean: &[f32]) -> Vec<f32> {
    let dense = |w: &ConvWeights, x: &[f32]| -> Vec<f32> {
        (0..w.cout)
            .map(|o| {
                let row = &w.weight[o * w.cin..(o + 1) * w.cin];
                w.bias[o] + row.iter().zip(x).map(|(a, b)| a * b).sum::<f32>()
            })
            .collect()
    };
    let hidden: Vec<f32> = dense(reduce, mean)
        .into_iter()
        .map(|v| v.max(v * LEAKY_RELU_SLOPE))
        .collect();
    dense(expand, &hidden).into_iter().map(sigmoid).collect()
}

/// `conk3 + conk1 + I` as one 3x3 kernel (the identity and `conk1` on the centre tap).
pub(super) fn fuse_block(conk3: &ConvWeights, conk1: &ConvWeights) -> (Vec<f32>, Vec<f32>) {
    let c = conk3.cout;
    let mut w = conk3.weight.clone();
    for co in 0..c {
        for ci in 0..c {
            let centre = (co * c + ci) * 9 + 4;
            w[centre] += conk1.weight[co * c + ci] + if co == ci { 1.0 } else { 0.0 };
        }
    }
    let b = conk3
        .bias
        .iter()
        .zip(&conk1.bias)
        .map(|(a, b)| a + b)
        .collect();
    (w, b)
}

/// Packed channel `n = s C + c` of an up conv takes original channel `c r^2 + s`, so that
/// sub-pixel `s = i r + j` of the shuffle is the contiguous run `[s C, (s + 1) C)`.
pub(super) fn shuffle_order(cout: usize) -> Vec<usize> {
    let sub = UPSCALE * UPSCALE;
    let c = cout / sub;
    (0..cout).map(|n| (n % c) * sub + n / c).collect()
}

/// `PixelShuffle(ELU(conv(x))) + skip` into a padded map.
pub(super) fn upsample(
    conv: &Conv3,
    x: &Feature,
    skip: Option<&Feature>,
    pool: &mut Pool,
    probe: &mut dyn FnMut(&str),
) -> Feature {
    let cout = 2 * x.c;
    let mut tmp = Feature::output_in(pool, x.h, x.w, cout, 0);
    conv.run(x, &mut tmp, pool);
    probe("conv");
    let c = cout / (UPSCALE * UPSCALE);
    let mut out = Feature::output_in(pool, x.h * UPSCALE, x.w * UPSCALE, c, 1);
    let stride = out.row_stride();
    let (pad, wo) = (out.pad, out.w);
    out.data
        .par_chunks_mut(stride)
        .skip(pad)
        .take(x.h * UPSCALE)
        .enumerate()
        .for_each(|(oy, orow)| {
            let (y, i) = (oy / UPSCALE, oy % UPSCALE);
            let src = tmp.row(y);
            let orow = &mut orow[pad * c..pad * c + wo * c];
            for (ox, px) in orow.chunks_exact_mut(c).enumerate() {
                let (xx, j) = (ox / UPSCALE, ox % UPSCALE);
                let s = i * UPSCALE + j;
                let from = &src[xx * cout + s * c..xx * cout + (s + 1) * c];
                px.copy_from_slice(from);
                if let Some(skip) = skip {
                    let sk = &skip.data[skip.at(oy, ox)..skip.at(oy, ox) + c];
                    for (v, s) in px.iter_mut().zip(sk) {
                        *v += s;
                    }
                }
            }
        });
    pool.give(tmp);
    probe("shuffle_skip");
    out
}
