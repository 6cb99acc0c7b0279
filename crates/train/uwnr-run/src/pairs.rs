//! Paired data for every trainer: discovery of `underwater/` + `clean/` folders (or UIEB's
//! `raw-890/` + `reference-890/`) matched by file name, decoding with one rule for pairs whose
//! images differ in size, the compact 8-bit store training pairs are held in, and the data
//! report that lists everything not used as given.
//!
//! Nothing is dropped silently: names present on one side only, undecodable files, and images
//! that had to be resized, upscaled or padded are listed in [`DataReport`]; a folder left
//! without any usable pair is an error.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use uwnr_core::Image;
use uwnr_core::index::reflect101;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb};
use uwnr_core::resize::resize_bilinear;

use crate::error::{Result, RunError};

/// Folder layouts of paired data: (underwater, clean). The second is UIEB's release layout.
pub const PAIR_LAYOUTS: [(&str, &str); 2] = [("underwater", "clean"), ("raw-890", "reference-890")];

/// The files of one pair.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PairPaths {
    /// The shared file name.
    pub name: String,
    /// The real underwater image.
    pub underwater: PathBuf,
    /// Its clean partner.
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
    /// Unpaired names.
    pub skipped: Vec<Skipped>,
}

/// Finds the pairs of a data folder: images with the same file name in its underwater and clean
/// folders. `max_pairs` keeps the first ones in name order. Fails when the folder has neither
/// layout of [`PAIR_LAYOUTS`] or no pair.
pub fn discover_pairs(dir: &Path, max_pairs: Option<usize>) -> Result<FolderPairs> {
    let (uw_dir, clean_dir) = PAIR_LAYOUTS
        .iter()
        .map(|(u, c)| (dir.join(u), dir.join(c)))
        .find(|(u, c)| u.is_dir() && c.is_dir())
        .ok_or_else(|| RunError::NotAPairedFolder {
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
        return Err(RunError::NoPairs {
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
        return Err(RunError::NoPairs {
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
    Ok(FolderPairs {
        dir: dir.to_path_buf(),
        pairs,
        skipped,
    })
}

/// Image files of a folder by file name (sorted).
fn list_images(dir: &Path) -> Result<BTreeMap<String, PathBuf>> {
    let mut out = BTreeMap::new();
    for entry in std::fs::read_dir(dir).map_err(RunError::io(dir))? {
        let path = entry.map_err(RunError::io(dir))?.path();
        if path.is_file()
            && is_image_path(&path)
            && let Some(name) = path.file_name().and_then(|n| n.to_str())
        {
            out.insert(name.to_string(), path.clone());
        }
    }
    Ok(out)
}

/// What to do with a pair whose clean image has another size than its underwater image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SizeMismatch {
    /// Resize the clean image to the underwater one (bilinear) and report it: training, where a
    /// pair of slightly different sizes still teaches the mapping.
    ResizeClean,
    /// Refuse the pair: scoring, where a resized target would change the score.
    Refuse,
}

/// A decoded pair, both images the same size.
#[derive(Clone, Debug)]
pub struct DecodedPair {
    /// The real underwater image.
    pub underwater: Image,
    /// The clean image.
    pub clean: Image,
    /// The clean image was resized to the underwater one's size.
    pub resized_clean: bool,
}

/// Decodes both images of a pair, applying `mismatch` when their sizes differ.
pub fn decode_pair(
    p: &PairPaths,
    limits: &DecodeLimits,
    mismatch: SizeMismatch,
) -> Result<DecodedPair> {
    let underwater = load_rgb(&p.underwater, limits)?;
    let clean = load_rgb(&p.clean, limits)?;
    if clean.size() == underwater.size() {
        return Ok(DecodedPair {
            underwater,
            clean,
            resized_clean: false,
        });
    }
    let (w, h) = underwater.size();
    match mismatch {
        SizeMismatch::ResizeClean => Ok(DecodedPair {
            clean: resize_bilinear(&clean, w, h)?,
            underwater,
            resized_clean: true,
        }),
        SizeMismatch::Refuse => Err(RunError::BadImage {
            path: p.clean.clone(),
            reason: format!(
                "{}x{}, but its underwater partner {} is {w}x{h}",
                clean.width(),
                clean.height(),
                p.underwater.display(),
            ),
        }),
    }
}

/// An RGB image held as planar 8-bit codes: how training pairs stay in memory (the datasets are
/// 8-bit JPEG/PNG, so this is lossless for them, at a quarter of f32's size).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgb8 {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Planar R, G, B codes.
    pub codes: Vec<u8>,
}

impl Rgb8 {
    /// The codes of an RGB image in [0, 1] (rounded half up, clamped).
    pub fn from_image(img: &Image) -> Result<Self> {
        if img.channels() != 3 {
            return Err(RunError::BadImage {
                path: PathBuf::new(),
                reason: format!("{} channels, an RGB image has 3", img.channels()),
            });
        }
        Ok(Self {
            width: img.width(),
            height: img.height(),
            codes: img.to_u8_codes(),
        })
    }

    /// The image as f32 in [0, 1].
    pub fn to_image(&self) -> Result<Image> {
        Ok(Image::from_u8_codes(
            self.width,
            self.height,
            3,
            &self.codes,
        )?)
    }

    /// Value of channel `c` at the planar pixel index `i`, in [0, 1].
    #[must_use]
    pub fn value(&self, c: usize, i: usize) -> f32 {
        f32::from(self.codes[c * self.width * self.height + i]) / f32::from(u8::MAX)
    }
}

/// How a training pair was brought to a usable size, for the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fix {
    /// Smaller than the crop: upscaled.
    Upscaled,
    /// Smaller than the crop: padded by reflection.
    Padded,
}

/// A training pair as a task prepared it, and what was done to it.
#[derive(Clone, Debug)]
pub struct Prepared<T> {
    /// The task's form of the pair.
    pub data: T,
    /// How it was brought up to the crop, if it was.
    pub fix: Option<Fix>,
    /// Its clean image was resized to its underwater partner.
    pub resized_clean: bool,
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
    /// Where depth came from (trainers that use depth).
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

/// Discovers and prepares the training pairs of every folder of `dirs` in parallel, in folder
/// then name order. `folder` is called once per folder (for per-folder resources such as its
/// depth maps) and `prepare` once per pair with that folder's value. Pairs that fail are
/// skipped and listed; a folder left without pairs, or no folder at all, is an error.
pub fn load_train_pairs<T, F, E>(
    dirs: &[PathBuf],
    max_pairs_per_dir: Option<usize>,
    report: &mut DataReport,
    mut folder: impl FnMut(&FolderPairs, &mut DataReport) -> std::result::Result<F, E>,
    prepare: impl Fn(&PairPaths, &F) -> std::result::Result<Prepared<T>, E> + Sync,
) -> std::result::Result<Vec<T>, E>
where
    T: Send,
    F: Sync,
    E: From<RunError> + std::fmt::Display + Send,
{
    if dirs.is_empty() {
        return Err(RunError::NoData("no --data folder given".into()).into());
    }
    let mut out = Vec::new();
    for dir in dirs {
        let found = discover_pairs(dir, max_pairs_per_dir)?;
        report.skipped.extend(found.skipped.iter().cloned());
        let shared = folder(&found, report)?;
        let loaded: Vec<std::result::Result<Prepared<T>, E>> = found
            .pairs
            .par_iter()
            .map(|p| prepare(p, &shared))
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
                    out.push(l.data);
                    used += 1;
                }
                Err(e) => report.skipped.push(Skipped {
                    path: p.underwater.clone(),
                    reason: format!("pair {} not usable: {e}", p.name),
                }),
            }
        }
        if used == 0 {
            return Err(RunError::NoPairs {
                dir: dir.clone(),
                reason: "no pair could be decoded".into(),
            }
            .into());
        }
        report.train_dirs.push((dir.clone(), used));
    }
    Ok(out)
}

/// Discovers and prepares the validation pairs of `dir` in parallel (see
/// [`load_train_pairs`]); failures are listed as skipped, and none usable is an error.
pub fn load_val_pairs<T, F, E>(
    dir: &Path,
    report: &mut DataReport,
    folder: impl FnOnce(&FolderPairs, &mut DataReport) -> std::result::Result<F, E>,
    prepare: impl Fn(&PairPaths, &F) -> std::result::Result<T, E> + Sync,
) -> std::result::Result<Vec<T>, E>
where
    T: Send,
    F: Sync,
    E: From<RunError> + std::fmt::Display + Send,
{
    let found = discover_pairs(dir, None)?;
    report.skipped.extend(found.skipped.iter().cloned());
    let shared = folder(&found, report)?;
    let loaded: Vec<std::result::Result<T, E>> = found
        .pairs
        .par_iter()
        .map(|p| prepare(p, &shared))
        .collect();
    let mut val = Vec::new();
    for (p, r) in found.pairs.iter().zip(loaded) {
        match r {
            Ok(v) => val.push(v),
            Err(e) => report.skipped.push(Skipped {
                path: p.underwater.clone(),
                reason: format!("validation pair {} not usable: {e}", p.name),
            }),
        }
    }
    if val.is_empty() {
        return Err(RunError::NoPairs {
            dir: dir.to_path_buf(),
            reason: "no validation pair could be decoded".into(),
        }
        .into());
    }
    report.val_dir = Some((dir.to_path_buf(), val.len()));
    Ok(val)
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
            let sy = reflect101(y as i64, h);
            for x in 0..width {
                dst[y * width + x] = src[sy * w + reflect101(x as i64, w)];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb8_round_trips_8_bit_values() {
        let img = Image::from_planar(2, 1, 3, vec![0.0, 1.0, 0.5, 0.25, 1.0 / 255.0, 1.2]).unwrap();
        let q = Rgb8::from_image(&img).unwrap();
        assert_eq!(q.codes, [0, 255, 128, 64, 1, 255]);
        let back = q.to_image().unwrap();
        assert_eq!(back.data()[4], 1.0 / 255.0);
        assert_eq!(q.value(2, 1), 1.0);
        assert!(Rgb8::from_image(&Image::filled(1, 1, 1, 0.0)).is_err());
    }

    #[test]
    fn size_mismatch_follows_the_policy() {
        let dir = tempfile::tempdir().unwrap();
        let (u, c) = (dir.path().join("u.png"), dir.path().join("c.png"));
        uwnr_core::io::save_rgb(&u, &Image::filled(8, 6, 3, 0.5)).unwrap();
        uwnr_core::io::save_rgb(&c, &Image::filled(4, 3, 3, 0.25)).unwrap();
        let p = PairPaths {
            name: "x.png".into(),
            underwater: u,
            clean: c,
        };
        let limits = DecodeLimits::default();
        let d = decode_pair(&p, &limits, SizeMismatch::ResizeClean).unwrap();
        assert!(d.resized_clean);
        assert_eq!(d.clean.size(), (8, 6));
        let err = decode_pair(&p, &limits, SizeMismatch::Refuse).unwrap_err();
        assert!(err.to_string().contains("4x3"), "{err}");
    }
}
