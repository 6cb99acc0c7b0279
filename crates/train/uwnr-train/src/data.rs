//! UWNR's paired training data: the pairs of [`uwnr_run::pairs`] with the depth map of every
//! clean image, computed once (from the folder's own `depth/` maps when it has them).
//!
//! Training pairs are held in memory as 8-bit RGB ([`Rgb8`], lossless for the 8-bit datasets)
//! and 16-bit depth, about 8 bytes a pixel; a sample is cut from them on demand
//! ([`crate::augment`]). Validation pairs are kept at their native resolution in f32.
//!
//! What is not used is listed, never dropped silently: names present on one side only,
//! undecodable files, and images that had to be upscaled, padded or resized to their partner.

use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::{DepthSource, PreparedDepth};
use uwnr_run::pairs::{
    DataReport, Fix, FolderPairs, PairPaths, Prepared, Rgb8, SizeMismatch, decode_pair,
    load_train_pairs, load_val_pairs, reflect_pad,
};

use crate::config::SmallImagePolicy;
use crate::error::{Result, TrainError};

/// Optional folder of depth maps beside the pair folders, matched to clean images by file stem.
pub const DEPTH_DIR: &str = "depth";
/// Largest 16-bit code: depth maps are stored as `round(d * 65535)`.
const DEPTH_CODE_MAX: f32 = 65_535.0;

/// One training pair in memory: 8-bit RGB and a 16-bit depth plane, all the same size.
#[derive(Clone, Debug)]
pub struct PairData {
    /// Name, for reports.
    pub name: String,
    /// Clean image.
    pub clean: Rgb8,
    /// Underwater image.
    pub underwater: Rgb8,
    /// Depth of the clean image, `round(d * 65535)`, one plane.
    pub depth: Vec<u16>,
}

impl PairData {
    /// Packs f32 images (clean and underwater RGB, depth grey; same size) into the compact form.
    pub fn pack(name: &str, clean: &Image, underwater: &Image, depth: &Image) -> Result<Self> {
        for (what, im, ch) in [
            ("clean", clean, 3),
            ("underwater", underwater, 3),
            ("depth", depth, 1),
        ] {
            if im.size() != clean.size() || im.channels() != ch {
                return Err(TrainError::BadImage {
                    path: PathBuf::from(name),
                    reason: format!(
                        "{what} is {}x{}x{}, expected {}x{}x{ch}",
                        im.width(),
                        im.height(),
                        im.channels(),
                        clean.width(),
                        clean.height()
                    ),
                });
            }
        }
        Ok(Self {
            name: name.to_string(),
            clean: Rgb8::from_image(clean)?,
            underwater: Rgb8::from_image(underwater)?,
            depth: depth
                .data()
                .iter()
                .map(|&v| (v * DEPTH_CODE_MAX + 0.5).clamp(0.0, DEPTH_CODE_MAX) as u16)
                .collect(),
        })
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.clean.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.clean.height
    }

    /// The clean image as f32.
    pub fn clean_image(&self) -> Result<Image> {
        Ok(self.clean.to_image()?)
    }

    /// The underwater image as f32.
    pub fn underwater_image(&self) -> Result<Image> {
        Ok(self.underwater.to_image()?)
    }

    /// The depth map as f32.
    pub fn depth_image(&self) -> Result<Image> {
        let data = self
            .depth
            .iter()
            .map(|&v| f32::from(v) / DEPTH_CODE_MAX)
            .collect();
        Ok(Image::from_planar(self.width(), self.height(), 1, data)?)
    }
}

/// A validation pair at its native resolution, with everything the render needs.
#[derive(Clone, Debug)]
pub struct ValPair {
    /// File name.
    pub name: String,
    /// Clean image (the render's RGB input).
    pub clean: Image,
    /// Depth of the clean image.
    pub depth: Image,
    /// The real underwater image (the reference of the light field and the score's target).
    pub underwater: Image,
}

/// Everything a training run reads: the training pairs and the validation pairs.
#[derive(Debug)]
pub struct TrainData {
    /// Training pairs (all folders, in folder then name order).
    pub pairs: Vec<PairData>,
    /// Validation pairs.
    pub val: Vec<ValPair>,
    /// What was used, skipped, upscaled...
    pub report: DataReport,
}

/// How [`load_data`] prepares the pairs.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Side of the training crops: smaller pairs are brought up to it.
    pub crop: usize,
    /// How.
    pub small_images: SmallImagePolicy,
    /// Depth for folders without a `depth/` folder.
    pub depth: DepthSource,
    /// Pairs per folder at most.
    pub max_pairs_per_dir: Option<usize>,
    /// Decoding limits.
    pub limits: DecodeLimits,
}

/// Discovers, decodes and prepares the training and validation pairs (in parallel). Files that
/// cannot be decoded are skipped and listed; a folder without pairs is an error.
pub fn load_data(
    train_dirs: &[PathBuf],
    val_dir: Option<&Path>,
    opts: &LoadOptions,
) -> Result<TrainData> {
    if train_dirs.is_empty() {
        return Err(uwnr_run::RunError::NoData("no --data folder given".into()).into());
    }
    let default_depth = opts.depth.prepare_with_limits(opts.limits)?;
    let mut report = DataReport {
        depth_notes: vec![format!(
            "{:?} for folders without a {DEPTH_DIR}/ folder",
            opts.depth
        )],
        ..DataReport::default()
    };
    let pairs = load_train_pairs(
        train_dirs,
        opts.max_pairs_per_dir,
        &mut report,
        |found, report| folder_depth(found, opts, report),
        |p, own: &Option<PreparedDepth>| {
            load_train_pair(p, own.as_ref().unwrap_or(&default_depth), opts)
        },
    )?;
    let val = match val_dir {
        Some(dir) => load_val_pairs(
            dir,
            &mut report,
            |found, report| folder_depth(found, opts, report),
            |p, own: &Option<PreparedDepth>| {
                load_val_pair(p, own.as_ref().unwrap_or(&default_depth), opts.limits)
            },
        )?,
        None => Vec::new(),
    };
    Ok(TrainData { pairs, val, report })
}

/// The depth-map source of a folder that has its own `depth/` folder.
fn folder_depth(
    found: &FolderPairs,
    opts: &LoadOptions,
    report: &mut DataReport,
) -> Result<Option<PreparedDepth>> {
    let dir = found.dir.join(DEPTH_DIR);
    if !dir.is_dir() {
        return Ok(None);
    }
    report.depth_notes.push(format!(
        "{}: maps from {}",
        found.dir.display(),
        dir.display()
    ));
    let source = DepthSource::Maps {
        path: dir,
        invert: false,
        normalize: false,
        unit: uwnr_depth::DepthUnit::Relative,
    };
    Ok(Some(source.prepare_with_limits(opts.limits)?))
}

/// Decodes a pair, brings the clean image to the underwater image's size, computes the depth of
/// the (full) clean image and brings the pair up to the crop size.
fn load_train_pair(
    p: &PairPaths,
    depth: &PreparedDepth,
    opts: &LoadOptions,
) -> Result<Prepared<PairData>> {
    let pair = decode_pair(p, &opts.limits, SizeMismatch::ResizeClean)?;
    let (clean, underwater) = (pair.clean, pair.underwater);
    let d = depth.depth_for(&clean, Some(&p.clean))?.map;
    let (w, h) = underwater.size();
    let crop = opts.crop;
    let (clean, underwater, d, fix) = if w >= crop && h >= crop {
        (clean, underwater, d, None)
    } else {
        match opts.small_images {
            SmallImagePolicy::Upscale => {
                let scale = crop as f64 / w.min(h) as f64;
                let nw = ((w as f64 * scale).round() as usize).max(crop);
                let nh = ((h as f64 * scale).round() as usize).max(crop);
                (
                    resize_bilinear(&clean, nw, nh)?,
                    resize_bilinear(&underwater, nw, nh)?,
                    resize_bilinear(&d, nw, nh)?,
                    Some(Fix::Upscaled),
                )
            }
            SmallImagePolicy::Pad => {
                let (nw, nh) = (w.max(crop), h.max(crop));
                (
                    reflect_pad(&clean, nw, nh),
                    reflect_pad(&underwater, nw, nh),
                    reflect_pad(&d, nw, nh),
                    Some(Fix::Padded),
                )
            }
        }
    };
    Ok(Prepared {
        data: PairData::pack(&p.name, &clean, &underwater, &d)?,
        fix,
        resized_clean: pair.resized_clean,
    })
}

fn load_val_pair(p: &PairPaths, depth: &PreparedDepth, limits: DecodeLimits) -> Result<ValPair> {
    let pair = decode_pair(p, &limits, SizeMismatch::ResizeClean)?;
    let d = depth.depth_for(&pair.clean, Some(&p.clean))?.map;
    Ok(ValPair {
        name: p.name.clone(),
        clean: pair.clean,
        depth: d,
        underwater: pair.underwater,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_round_trips_8_bit_values() {
        let clean =
            Image::from_planar(2, 1, 3, vec![0.0, 1.0, 0.5, 0.25, 1.0 / 255.0, 0.2]).unwrap();
        let depth = Image::from_planar(2, 1, 1, vec![0.0, 0.123_456]).unwrap();
        let p = PairData::pack("a", &clean, &clean, &depth).unwrap();
        let back = p.clean_image().unwrap();
        for (a, b) in back.data().iter().zip(clean.data()) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-7);
        }
        let d = p.depth_image().unwrap();
        assert!((d.data()[1] - 0.123_456).abs() < 1e-5);
    }
}
