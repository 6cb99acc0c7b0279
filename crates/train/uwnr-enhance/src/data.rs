//! Paired enhancement data: the underwater image is the network's input, its clean partner the
//! target. Folders are discovered and decoded by [`uwnr_run::pairs`] (`underwater/` + `clean/`,
//! or UIEB's `raw-890/` + `reference-890/`).
//!
//! Training pairs are decoded once and held as 8-bit RGB ([`Rgb8`]), reflect-padded up to the
//! crop; a batch is cut from them on demand with uwnr-run's seeded plans ([`uwnr_run::plan`]),
//! so it is a pure function of `(seed, epoch, position)`. Validation pairs are kept at their
//! native size in f32.
//!
//! Nothing is dropped silently: unpaired names and undecodable pairs are listed in the data
//! report, and a folder left without any usable pair is an error.

use std::path::{Path, PathBuf};

use std::sync::Arc;

use rayon::prelude::*;
use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;
use uwnr_run::BatchSource;
use uwnr_run::pairs::{
    DataReport, Fix, PairPaths, Prepared, Rgb8, SizeMismatch, decode_pair, load_train_pairs,
    load_val_pairs, reflect_pad,
};
use uwnr_run::plan::{Geometry, epoch_order, plan_crop};

use crate::error::{EnhanceError, Result};
use crate::model::IMAGE_CHANNELS;

/// Flips and quarter turns, as UWNR training uses them.
const GEOMETRY: Geometry = Geometry {
    flip: true,
    rotate: true,
};

/// One training pair in memory, at least `crop x crop`.
pub(crate) struct TrainPair {
    /// The underwater image (the network's input).
    pub input: Rgb8,
    /// The clean image (the target).
    pub target: Rgb8,
}

/// A validation pair at its native size.
pub(crate) struct ValPair {
    pub name: String,
    /// The underwater image (the network's input).
    pub input: Image,
    /// The clean image.
    pub target: Image,
}

/// Everything a run reads.
pub(crate) struct Data {
    pub pairs: Vec<TrainPair>,
    pub val: Vec<ValPair>,
    pub report: DataReport,
}

/// Decodes the training pairs of every folder of `dirs` (brought up to `crop` by reflection)
/// and the validation pairs of `val_dir`.
pub(crate) fn load(
    dirs: &[PathBuf],
    val_dir: Option<&Path>,
    crop: usize,
    max_pairs_per_dir: Option<usize>,
    limits: &DecodeLimits,
) -> Result<Data> {
    let mut report = DataReport::default();
    let no_folder_state = |_: &_, _: &mut DataReport| Ok::<(), EnhanceError>(());
    let pairs = load_train_pairs(
        dirs,
        max_pairs_per_dir,
        &mut report,
        no_folder_state,
        |p, ()| load_train_pair(p, crop, limits),
    )?;
    let val = match val_dir {
        Some(dir) => load_val_pairs(dir, &mut report, no_folder_state, |p, ()| {
            let pair = decode_pair(p, limits, SizeMismatch::ResizeClean)?;
            Ok(ValPair {
                name: p.name.clone(),
                input: pair.underwater,
                target: pair.clean,
            })
        })?,
        None => Vec::new(),
    };
    Ok(Data { pairs, val, report })
}

/// Decodes a training pair and reflect-pads it up to `crop`.
fn load_train_pair(
    p: &PairPaths,
    crop: usize,
    limits: &DecodeLimits,
) -> Result<Prepared<TrainPair>> {
    let pair = decode_pair(p, limits, SizeMismatch::ResizeClean)?;
    let (input, target) = (pair.underwater, pair.clean);
    let (w, h) = input.size();
    let padded = w < crop || h < crop;
    let (input, target) = if padded {
        let (nw, nh) = (w.max(crop), h.max(crop));
        (reflect_pad(&input, nw, nh), reflect_pad(&target, nw, nh))
    } else {
        (input, target)
    };
    Ok(Prepared {
        data: TrainPair {
            input: Rgb8::from_image(&input)?,
            target: Rgb8::from_image(&target)?,
        },
        fix: padded.then_some(Fix::Padded),
        resized_clean: pair.resized_clean,
    })
}

/// The batches of a run: batch `k` of epoch `e` holds the pairs at positions
/// `k * batch_size ..` of the epoch's order, each cut, flipped and turned by its seeded plan.
pub(crate) struct Batches {
    pub pairs: Arc<Vec<TrainPair>>,
    pub seed: u64,
    pub batch_size: usize,
    pub crop: usize,
}

/// Input and target of a batch, `[b, 3, crop, crop]` each, planar.
pub(crate) struct Batch {
    pub input: Vec<f32>,
    pub target: Vec<f32>,
}

impl BatchSource for Batches {
    type Batch = Batch;
    type Error = EnhanceError;

    fn batches_per_epoch(&self) -> usize {
        self.pairs.len() / self.batch_size.max(1)
    }

    fn batch(&self, epoch: usize, index: usize) -> Result<Batch> {
        let order = epoch_order(self.seed, epoch, self.pairs.len());
        let (input, target) = batch(
            &self.pairs,
            &order,
            self.seed,
            epoch,
            index * self.batch_size,
            self.batch_size,
            self.crop,
        );
        Ok(Batch { input, target })
    }
}

/// The input and target of a training batch, `[b, 3, crop, crop]` each, planar: sample `slot`
/// is pair `order[first + slot]` cut, flipped and turned by its seeded plan. Samples are cut in
/// parallel.
fn batch(
    pairs: &[TrainPair],
    order: &[usize],
    seed: u64,
    epoch: usize,
    first: usize,
    size: usize,
    crop: usize,
) -> (Vec<f32>, Vec<f32>) {
    let plane = crop * crop;
    let samples: Vec<(Vec<f32>, Vec<f32>)> = (0..size)
        .into_par_iter()
        .map(|slot| {
            let position = first + slot;
            let index = order[position];
            let pair = &pairs[index];
            let (width, height) = (pair.input.width, pair.input.height);
            let (plan, _) = plan_crop(
                seed,
                epoch,
                position,
                (index, width, height),
                crop,
                GEOMETRY,
            );
            let mut x = vec![0.0_f32; IMAGE_CHANNELS * plane];
            let mut y = vec![0.0_f32; IMAGE_CHANNELS * plane];
            for oy in 0..crop {
                for ox in 0..crop {
                    let src = plan.source_index(ox, oy, crop, width);
                    let dst = oy * crop + ox;
                    for c in 0..IMAGE_CHANNELS {
                        x[c * plane + dst] = pair.input.value(c, src);
                        y[c * plane + dst] = pair.target.value(c, src);
                    }
                }
            }
            (x, y)
        })
        .collect();
    let mut x = Vec::with_capacity(size * IMAGE_CHANNELS * plane);
    let mut y = Vec::with_capacity(size * IMAGE_CHANNELS * plane);
    for (sx, sy) in samples {
        x.extend_from_slice(&sx);
        y.extend_from_slice(&sy);
    }
    (x, y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_is_cut_from_the_planned_window() {
        // A 4x4 pair whose input codes are the pixel index and target codes twice that.
        let input: Vec<u8> = (0..3).flat_map(|_| 0..16_u8).collect();
        let target: Vec<u8> = input.iter().map(|v| v * 2).collect();
        let rgb = |codes| Rgb8 {
            width: 4,
            height: 4,
            codes,
        };
        let pairs = vec![TrainPair {
            input: rgb(input),
            target: rgb(target),
        }];
        let (x, y) = batch(&pairs, &[0], 3, 0, 0, 1, 4);
        assert_eq!(x.len(), 3 * 16);
        // A full-size crop is a flip and rotation of the image: every value appears once per
        // channel, and the target stays aligned with the input.
        let mut codes: Vec<u32> = x[..16].iter().map(|v| (v * 255.0).round() as u32).collect();
        codes.sort_unstable();
        assert_eq!(codes, (0..16).collect::<Vec<_>>());
        for (a, b) in x.iter().zip(&y) {
            assert!((b - 2.0 * a).abs() < 1e-6);
        }
    }
}
