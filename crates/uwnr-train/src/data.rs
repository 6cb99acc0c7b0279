//! Paired training data: discovery of `underwater/` + `clean/` folders (or UIEB's `raw-890/` +
//! `reference-890/`) matched by file name, decoding, and the depth map of every clean image,
//! computed once.
//!
//! Training pairs are held in memory as 8-bit RGB (the datasets are 8-bit JPEG/PNG, so this is
//! lossless for them) and 16-bit depth, about 8 bytes a pixel; a sample is cut from them on
//! demand ([`crate::augment`]). Validation pairs are kept at their native resolution in f32.
//!
//! What is not used is listed, never dropped silently: names present on one side only,
//! undecodable files, and images that had to be upscaled, padded or resized to their partner.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb};
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::{DepthSource, PreparedDepth};

use crate::config::SmallImagePolicy;
use crate::error::{Result, TrainError};

/// Folder layouts of paired data: (underwater, clean). The second is UIEB's release layout.
pub const PAIR_LAYOUTS: [(&str, &str); 2] = [("underwater", "clean"), ("raw-890", "reference-890")];
/// Optional folder of depth maps beside the pair folders, matched to clean images by file stem.
pub const DEPTH_DIR: &str = "depth";
/// Largest 16-bit code: depth maps are stored as `round(d * 65535)`.
const DEPTH_CODE_MAX: f32 = 65_535.0;
/// Largest 8-bit code.
const RGB_CODE_MAX: f32 = 255.0;

/// The files of one training pair.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PairPaths {
    /// The shared file name.
    pub name: String,
    /// The real underwater image (the target, and the source of the light field).
    pub underwater: PathBuf,
    /// Its clean reference (the network's RGB input).
    pub clean: PathBuf,
}

/// A file that was not used, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Skipped {
    /// The file.
    pub path: PathBuf,
    /// Why it was left out.
    pub reason: String,
}

/// The pairs of one data folder and the files that were left out.
#[derive(Clone, Debug)]
pub struct FolderPairs {
    /// The data folder.
    pub dir: PathBuf,
    /// Its pairs, in file-name order.
    pub pairs: Vec<PairPaths>,
    /// Its depth-map folder, when it has one.
    pub depth_dir: Option<PathBuf>,
    /// Unpaired names.
    pub skipped: Vec<Skipped>,
}

/// The decoded validation pairs of `dir`: failures are listed in `report` as skipped, and the
/// folder is recorded there; an error when none could be decoded. `loaded[i]` is `pairs[i]`'s.
pub fn keep_val_pairs<T, E: std::fmt::Display>(
    dir: &Path,
    pairs: &[PairPaths],
    loaded: Vec<std::result::Result<T, E>>,
    report: &mut DataReport,
) -> Result<Vec<T>> {
    let mut val = Vec::new();
    for (p, r) in pairs.iter().zip(loaded) {
        match r {
            Ok(v) => val.push(v),
            Err(e) => report.skipped.push(Skipped {
                path: p.underwater.clone(),
                reason: format!("validation pair {} not usable: {e}", p.name),
            }),
        }
    }
    if val.is_empty() {
        return Err(TrainError::NoPairs {
            dir: dir.to_path_buf(),
            reason: "no validation pair could be decoded".into(),
        });
    }
    report.val_dir = Some((dir.to_path_buf(), val.len()));
    Ok(val)
}

/// Finds the pairs of a data folder: images with the same file name in its underwater and clean
/// folders. `max_pairs` keeps the first ones in name order. Fails when the folder has neither
/// layout of [`PAIR_LAYOUTS`] or no pair.
pub fn discover_pairs(dir: &Path, max_pairs: Option<usize>) -> Result<FolderPairs> {
    let (uw_dir, clean_dir) = PAIR_LAYOUTS
        .iter()
        .map(|(u, c)| (dir.join(u), dir.join(c)))
        .find(|(u, c)| u.is_dir() && c.is_dir())
        .ok_or_else(|| TrainError::NotAPairedFolder {
            dir: dir.to_path_buf(),
        })?;
    let underwater = list_images(&uw_dir)?;
    let clean = list_images(&clean_dir)?;
    if underwater.is_empty() || clean.is_empty() {
        let empty = if underwater.is_empty() {
            &uw_dir
        } else {
            &clean_dir
        };
        return Err(TrainError::NoPairs {
            dir: dir.to_path_buf(),
            reason: format!("{} holds no images", empty.display()),
        });
    }
    let mut pairs = Vec::new();
    let mut skipped = Vec::new();
    for (name, path) in &underwater {
        match clean.get(name) {
            Some(c) => pairs.push(PairPaths {
                name: name.clone(),
                underwater: path.clone(),
                clean: c.clone(),
            }),
            None => skipped.push(Skipped {
                path: path.clone(),
                reason: format!("no {} in {}", name, clean_dir.display()),
            }),
        }
    }
    for (name, path) in &clean {
        if !underwater.contains_key(name) {
            skipped.push(Skipped {
                path: path.clone(),
                reason: format!("no {} in {}", name, uw_dir.display()),
            });
        }
    }
    if pairs.is_empty() {
        return Err(TrainError::NoPairs {
            dir: dir.to_path_buf(),
            reason: format!(
                "no file name is in both {} and {}",
                uw_dir.display(),
                clean_dir.display()
            ),
        });
    }
    if let Some(max) = max_pairs {
        pairs.truncate(max);
    }
    let depth_dir = Some(dir.join(DEPTH_DIR)).filter(|d| d.is_dir());
    Ok(FolderPairs {
        dir: dir.to_path_buf(),
        pairs,
        depth_dir,
        skipped,
    })
}

/// Image files of a folder by file name (sorted).
fn list_images(dir: &Path) -> Result<BTreeMap<String, PathBuf>> {
    let io_err = |source| TrainError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut out = BTreeMap::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let path = entry.map_err(io_err)?.path();
        if path.is_file()
            && is_image_path(&path)
            && let Some(name) = path.file_name().and_then(|n| n.to_str())
        {
            out.insert(name.to_string(), path.clone());
        }
    }
    Ok(out)
}

/// One training pair in memory: 8-bit RGB planes and a 16-bit depth plane, all the same size.
#[derive(Clone, Debug)]
pub struct PairData {
    /// Name, for reports.
    pub name: String,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Clean image, planar RGB, 8-bit codes.
    pub clean: Vec<u8>,
    /// Underwater image, planar RGB, 8-bit codes.
    pub underwater: Vec<u8>,
    /// Depth of the clean image, `round(d * 65535)`.
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
        let q8 = |im: &Image| -> Vec<u8> {
            im.data()
                .iter()
                .map(|&v| (v * RGB_CODE_MAX + 0.5).clamp(0.0, RGB_CODE_MAX) as u8)
                .collect()
        };
        Ok(Self {
            name: name.to_string(),
            width: clean.width(),
            height: clean.height(),
            clean: q8(clean),
            underwater: q8(underwater),
            depth: depth
                .data()
                .iter()
                .map(|&v| (v * DEPTH_CODE_MAX + 0.5).clamp(0.0, DEPTH_CODE_MAX) as u16)
                .collect(),
        })
    }

    /// The clean image as f32.
    pub fn clean_image(&self) -> Result<Image> {
        rgb8_to_image(self.width, self.height, &self.clean)
    }

    /// The underwater image as f32.
    pub fn underwater_image(&self) -> Result<Image> {
        rgb8_to_image(self.width, self.height, &self.underwater)
    }

    /// The depth map as f32.
    pub fn depth_image(&self) -> Result<Image> {
        let data = self
            .depth
            .iter()
            .map(|&v| f32::from(v) / DEPTH_CODE_MAX)
            .collect();
        Ok(Image::from_planar(self.width, self.height, 1, data)?)
    }
}

fn rgb8_to_image(w: usize, h: usize, planar: &[u8]) -> Result<Image> {
    let data = planar
        .iter()
        .map(|&v| f32::from(v) / RGB_CODE_MAX)
        .collect();
    Ok(Image::from_planar(w, h, 3, data)?)
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

/// What loading did to the data, for the run's `data-report.txt`.
#[derive(Clone, Debug, Default)]
pub struct DataReport {
    /// `(folder, pairs used)` for each training folder.
    pub train_dirs: Vec<(PathBuf, usize)>,
    /// Validation folder and its pairs, if any.
    pub val_dir: Option<(PathBuf, usize)>,
    /// Files left out, with the reason.
    pub skipped: Vec<Skipped>,
    /// Pairs smaller than the crop that were upscaled.
    pub upscaled: Vec<String>,
    /// Pairs smaller than the crop that were padded.
    pub padded: Vec<String>,
    /// Pairs whose clean image had another size than its underwater image and was resized.
    pub resized_clean: Vec<String>,
    /// Where depth came from.
    pub depth_notes: Vec<String>,
}

impl DataReport {
    /// A human-readable summary.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        for (dir, n) in &self.train_dirs {
            let _ = writeln!(s, "train: {} ({n} pairs)", dir.display());
        }
        if let Some((dir, n)) = &self.val_dir {
            let _ = writeln!(s, "val: {} ({n} pairs)", dir.display());
        }
        for note in &self.depth_notes {
            let _ = writeln!(s, "depth: {note}");
        }
        let lists: [(&str, &Vec<String>); 3] = [
            (
                "upscaled to the crop (smaller than the crop)",
                &self.upscaled,
            ),
            ("padded to the crop (smaller than the crop)", &self.padded),
            (
                "clean image resized to its underwater partner",
                &self.resized_clean,
            ),
        ];
        for (what, names) in lists {
            if !names.is_empty() {
                let _ = writeln!(s, "{} pairs {what}: {}", names.len(), names.join(", "));
            }
        }
        if !self.skipped.is_empty() {
            let _ = writeln!(s, "{} files skipped:", self.skipped.len());
            for k in &self.skipped {
                let _ = writeln!(s, "  {}: {}", k.path.display(), k.reason);
            }
        }
        s
    }
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
        return Err(TrainError::NoData("no --data folder given".into()));
    }
    let default_depth = opts.depth.prepare_with_limits(opts.limits)?;
    let mut report = DataReport {
        depth_notes: vec![format!(
            "{:?} for folders without a {DEPTH_DIR}/ folder",
            opts.depth
        )],
        ..DataReport::default()
    };
    let mut pairs = Vec::new();
    for dir in train_dirs {
        let found = discover_pairs(dir, opts.max_pairs_per_dir)?;
        report.skipped.extend(found.skipped.iter().cloned());
        let own_depth = folder_depth(&found, opts, &mut report)?;
        let depth = own_depth.as_ref().unwrap_or(&default_depth);
        let loaded: Vec<Result<Loaded>> = found
            .pairs
            .par_iter()
            .map(|p| load_train_pair(p, depth, opts))
            .collect();
        let mut used = 0;
        for (p, r) in found.pairs.iter().zip(loaded) {
            match r {
                Ok(l) => {
                    match l.fix {
                        Some(Fix::Upscaled) => report.upscaled.push(p.name.clone()),
                        Some(Fix::Padded) => report.padded.push(p.name.clone()),
                        None => {}
                    }
                    if l.resized_clean {
                        report.resized_clean.push(p.name.clone());
                    }
                    pairs.push(l.data);
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
            });
        }
        report.train_dirs.push((dir.clone(), used));
    }
    let val = match val_dir {
        Some(dir) => {
            let found = discover_pairs(dir, None)?;
            report.skipped.extend(found.skipped.iter().cloned());
            let own_depth = folder_depth(&found, opts, &mut report)?;
            let depth = own_depth.as_ref().unwrap_or(&default_depth);
            let loaded: Vec<Result<ValPair>> = found
                .pairs
                .par_iter()
                .map(|p| load_val_pair(p, depth, opts.limits))
                .collect();
            keep_val_pairs(dir, &found.pairs, loaded, &mut report)?
        }
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
    let Some(dir) = &found.depth_dir else {
        return Ok(None);
    };
    report.depth_notes.push(format!(
        "{}: maps from {}",
        found.dir.display(),
        dir.display()
    ));
    let source = DepthSource::Maps {
        path: dir.clone(),
        invert: false,
        normalize: false,
    };
    Ok(Some(source.prepare_with_limits(opts.limits)?))
}

enum Fix {
    Upscaled,
    Padded,
}

struct Loaded {
    data: PairData,
    fix: Option<Fix>,
    resized_clean: bool,
}

/// Decodes a pair, brings the clean image to the underwater image's size, computes the depth of
/// the (full) clean image and brings the pair up to the crop size.
fn load_train_pair(p: &PairPaths, depth: &PreparedDepth, opts: &LoadOptions) -> Result<Loaded> {
    let (underwater, clean, resized_clean) = decode_pair(p, opts.limits)?;
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
    Ok(Loaded {
        data: PairData::pack(&p.name, &clean, &underwater, &d)?,
        fix,
        resized_clean,
    })
}

fn load_val_pair(p: &PairPaths, depth: &PreparedDepth, limits: DecodeLimits) -> Result<ValPair> {
    let (underwater, clean, _) = decode_pair(p, limits)?;
    let d = depth.depth_for(&clean, Some(&p.clean))?.map;
    Ok(ValPair {
        name: p.name.clone(),
        clean,
        depth: d,
        underwater,
    })
}

/// Decodes both images; the clean one is resized to the underwater one's size when they differ.
fn decode_pair(p: &PairPaths, limits: DecodeLimits) -> Result<(Image, Image, bool)> {
    let underwater = load_rgb(&p.underwater, &limits)?;
    let clean = load_rgb(&p.clean, &limits)?;
    if clean.size() == underwater.size() {
        return Ok((underwater, clean, false));
    }
    let (w, h) = underwater.size();
    Ok((underwater, resize_bilinear(&clean, w, h)?, true))
}

/// Pads an image by reflection (without repeating the edge pixel, as `numpy.pad(mode="reflect")`)
/// to `width x height`, keeping it at the top-left. Repeats the reflection when the pad exceeds
/// the image.
#[must_use]
pub fn reflect_pad(img: &Image, width: usize, height: usize) -> Image {
    let (w, h) = img.size();
    let mut out = Image::filled(width, height, img.channels(), 0.0);
    for c in 0..img.channels() {
        let src = img.plane(c);
        let dst = out.plane_mut(c);
        for y in 0..height {
            let sy = reflect_index(y, h);
            for x in 0..width {
                dst[y * width + x] = src[sy * w + reflect_index(x, w)];
            }
        }
    }
    out
}

/// Index `i` folded into `0..n` by mirror reflection about the end pixels.
fn reflect_index(i: usize, n: usize) -> usize {
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let k = i % period;
    if k < n { k } else { period - k }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect_index_mirrors() {
        let got: Vec<usize> = (0..9).map(|i| reflect_index(i, 3)).collect();
        assert_eq!(got, [0, 1, 2, 1, 0, 1, 2, 1, 0]);
        assert_eq!(reflect_index(5, 1), 0);
    }

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
