//! Paired enhancement data: the underwater image is the network's input, its clean partner the
//! target. Folders have uwnr-train's layouts (`underwater/` + `clean/`, or UIEB's `raw-890/` +
//! `reference-890/`) and are discovered by [`uwnr_train::data::discover_pairs`].
//!
//! Training pairs are decoded once and held as planar 8-bit RGB (lossless for the 8-bit
//! datasets used here), reflect-padded up to the crop; a batch is cut from them on demand with
//! uwnr-train's seeded plans ([`uwnr_train::augment`]), so it is a pure function of
//! `(seed, epoch, position)`. Validation pairs are kept at their native size in f32.
//!
//! Nothing is dropped silently: unpaired names and undecodable pairs are listed in the data
//! report, and a folder left without any usable pair is an error.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_core::resize::resize_bilinear;
use uwnr_train::TrainError;
use uwnr_train::augment::{plan_sample, source_of};
use uwnr_train::config::AugmentConfig;
use uwnr_train::data::{
    DataReport, PairPaths, Skipped, discover_pairs, keep_val_pairs, reflect_pad,
};

use crate::error::Result;
use crate::model::IMAGE_CHANNELS;

/// Largest 8-bit code.
const RGB_CODE_MAX: f32 = 255.0;

/// One training pair in memory, at least `crop x crop`.
pub(crate) struct TrainPair {
    pub width: usize,
    pub height: usize,
    /// The underwater image, planar RGB, 8-bit codes.
    pub input: Vec<u8>,
    /// The clean image, planar RGB, 8-bit codes.
    pub target: Vec<u8>,
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
    if dirs.is_empty() {
        return Err(TrainError::NoData("no --data folder given".into()).into());
    }
    let mut report = DataReport::default();
    let mut pairs = Vec::new();
    for dir in dirs {
        let found = discover_pairs(dir, max_pairs_per_dir)?;
        report.skipped.extend(found.skipped.iter().cloned());
        let loaded: Vec<Result<(TrainPair, bool, bool)>> = found
            .pairs
            .par_iter()
            .map(|p| load_train_pair(p, crop, limits))
            .collect();
        let mut used = 0;
        for (p, r) in found.pairs.iter().zip(loaded) {
            match r {
                Ok((pair, resized, padded)) => {
                    if resized {
                        report.resized_clean.push(p.name.clone());
                    }
                    if padded {
                        report.padded.push(p.name.clone());
                    }
                    pairs.push(pair);
                    used += 1;
                }
                Err(e) => report.skipped.push(Skipped {
                    path: p.underwater.clone(),
                    reason: format!("pair {} not usable: {e}", p.name),
                }),
            }
        }
        if used == 0 {
            return Err(TrainError::NoPairs {
                dir: dir.clone(),
                reason: "no pair could be decoded".into(),
            }
            .into());
        }
        report.train_dirs.push((dir.clone(), used));
    }
    let val = match val_dir {
        Some(dir) => {
            let found = discover_pairs(dir, None)?;
            report.skipped.extend(found.skipped.iter().cloned());
            let loaded: Vec<Result<ValPair>> = found
                .pairs
                .par_iter()
                .map(|p| {
                    let (input, target, _) = decode_pair(p, limits, true)?;
                    Ok(ValPair {
                        name: p.name.clone(),
                        input,
                        target,
                    })
                })
                .collect();
            keep_val_pairs(dir, &found.pairs, loaded, &mut report)?
        }
        None => Vec::new(),
    };
    Ok(Data { pairs, val, report })
}

/// Decodes a pair: `(underwater, clean, clean_was_resized)`. A clean image of another size
/// than its underwater partner is resized to it when `resize` is set, and is an error
/// otherwise.
pub(crate) fn decode_pair(
    p: &PairPaths,
    limits: &DecodeLimits,
    resize: bool,
) -> Result<(Image, Image, bool)> {
    let input = load_rgb(&p.underwater, limits)?;
    let target = load_rgb(&p.clean, limits)?;
    if target.size() == input.size() {
        return Ok((input, target, false));
    }
    if !resize {
        return Err(crate::error::EnhanceError::BadPair {
            path: p.clean.clone(),
            reason: format!(
                "{}x{}, but its underwater partner {} is {}x{}",
                target.width(),
                target.height(),
                p.underwater.display(),
                input.width(),
                input.height()
            ),
        });
    }
    let (w, h) = input.size();
    Ok((input, resize_bilinear(&target, w, h)?, true))
}

/// Decodes a training pair and reflect-pads it up to `crop`: `(pair, resized, padded)`.
fn load_train_pair(
    p: &PairPaths,
    crop: usize,
    limits: &DecodeLimits,
) -> Result<(TrainPair, bool, bool)> {
    let (input, target, resized) = decode_pair(p, limits, true)?;
    let (w, h) = input.size();
    let padded = w < crop || h < crop;
    let (input, target) = if padded {
        let (nw, nh) = (w.max(crop), h.max(crop));
        (reflect_pad(&input, nw, nh), reflect_pad(&target, nw, nh))
    } else {
        (input, target)
    };
    Ok((
        TrainPair {
            width: input.width(),
            height: input.height(),
            input: quantise(&input),
            target: quantise(&target),
        },
        resized,
        padded,
    ))
}

/// Planar 8-bit codes of an image in [0, 1] (round half up, clamped).
fn quantise(img: &Image) -> Vec<u8> {
    img.data()
        .iter()
        .map(|&v| (v * RGB_CODE_MAX + 0.5).clamp(0.0, RGB_CODE_MAX) as u8)
        .collect()
}

/// The image rounded to 8-bit codes, as it would be once saved as PNG: scores of an output in
/// memory then equal scores of the written file.
pub(crate) fn quantised(img: &Image) -> Result<Image> {
    let data = quantise(img)
        .into_iter()
        .map(|v| f32::from(v) / RGB_CODE_MAX)
        .collect();
    Ok(Image::from_planar(
        img.width(),
        img.height(),
        img.channels(),
        data,
    )?)
}

/// The input and target of a training batch, `[b, 3, crop, crop]` each, planar: sample `slot`
/// is pair `order[first + slot]` cut, flipped and turned by its seeded plan. Samples are cut in
/// parallel.
pub(crate) fn batch(
    pairs: &[TrainPair],
    order: &[usize],
    seed: u64,
    epoch: usize,
    first: usize,
    size: usize,
    crop: usize,
) -> (Vec<f32>, Vec<f32>) {
    let aug = AugmentConfig {
        flip: true,
        rotate: true,
        color_cast: None,
    };
    let plane = crop * crop;
    let samples: Vec<(Vec<f32>, Vec<f32>)> = (0..size)
        .into_par_iter()
        .map(|slot| {
            let position = first + slot;
            let index = order[position];
            let pair = &pairs[index];
            let plan = plan_sample(
                seed,
                epoch,
                position,
                (index, pair.width, pair.height),
                crop,
                &aug,
            );
            let mut x = vec![0.0_f32; IMAGE_CHANNELS * plane];
            let mut y = vec![0.0_f32; IMAGE_CHANNELS * plane];
            let src_plane = pair.width * pair.height;
            for oy in 0..crop {
                for ox in 0..crop {
                    // Output pixel (ox, oy) shows this pixel of the un-augmented crop.
                    let (sx, sy) = source_of(ox, oy, crop, plan.flip, plan.quarter_turns);
                    let src = (plan.y0 + sy) * pair.width + plan.x0 + sx;
                    let dst = oy * crop + ox;
                    for c in 0..IMAGE_CHANNELS {
                        x[c * plane + dst] = f32::from(pair.input[c * src_plane + src]) / 255.0;
                        y[c * plane + dst] = f32::from(pair.target[c * src_plane + src]) / 255.0;
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
    fn quantised_images_are_8_bit_codes() {
        let img = Image::from_planar(1, 1, 3, vec![0.1, 0.5, 1.2]).unwrap();
        let q = quantised(&img).unwrap();
        assert_eq!(
            q.data(),
            &[26.0 / 255.0, 128.0 / 255.0, 1.0],
            "rounded half up and clamped"
        );
    }

    #[test]
    fn a_batch_is_cut_from_the_planned_window() {
        // A 4x4 pair whose input codes are the pixel index and target codes twice that.
        let input: Vec<u8> = (0..3).flat_map(|_| 0..16_u8).collect();
        let target: Vec<u8> = input.iter().map(|v| v * 2).collect();
        let pairs = vec![TrainPair {
            width: 4,
            height: 4,
            input,
            target,
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
