//! Depth maps read from files.
//!
//! - [`DepthUnit::Relative`] (the default), as the released UWNR code reads maps: a grey image
//!   divided by its largest code (8-bit `/255`, 16-bit `/65535`, `uwnr_core::io::load_gray`),
//!   resized to the clean image with the antialiased bilinear resize, optionally min-max
//!   normalised and inverted.
//! - A metric unit ([`DepthUnit::Millimetres`], [`DepthUnit::Metres`],
//!   [`DepthUnit::CodesPerMetre`]): each stored value times the unit is the distance in metres
//!   (NYU-v2 and Redwood store 16-bit millimetres, KITTI 256 codes per metre; float maps, 32-bit
//!   TIFF or NumPy `.npy`, store metres). The map keeps its metres: it is divided by its
//!   farthest value `z_max` into uwnr's [0, 1] and `z_max` travels with it
//!   ([`crate::Depth::metric_max`]).
//!
//! Zeros are holes in metric and normalised maps (sensors store missing depth as 0: a quarter
//! of an NYU frame, four fifths of a KITTI one): they are filled at the map's own resolution,
//! before any resize, from the nearest measured values ([`fill_holes`]), so that a hole is
//! neither "at the camera" nor mixed into its neighbours by the resize.
//!
//! A single file serves every clean image. A directory is indexed once and searched for the
//! map whose file stem equals the clean image's stem (`photo.jpg` -> `photo.png`, any extension
//! `uwnr_core::io::is_image_path` accepts, or `.npy`), or else the only one whose stem ends in
//! the same number (`rgb_00050.jpg` -> `sync_depth_00050.png`, as RGB-D sets name them).

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::io::{
    DecodeLimits, is_image_path, load_gray, load_gray_codes, load_gray_codes_from_memory,
    load_gray_from_memory,
};
use uwnr_core::resize::resize_bilinear;

use crate::error::{DepthError, Result};
use crate::npy::{is_npy_path, load_npy, parse_npy};
use crate::util::{check_not_empty, normalise_min_max};

/// What the values stored in a depth map file mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthUnit {
    /// A fraction of the largest code (`/255`, `/65535`; float files as stored): the released
    /// code's reading, with no metres attached.
    #[default]
    Relative,
    /// Integer codes in millimetres (NYU-v2, Redwood, TUM, ScanNet).
    Millimetres,
    /// Values in metres (float maps: 32-bit TIFF, `.npy`).
    Metres,
    /// Integer codes, this many per metre (KITTI: 256).
    CodesPerMetre(u32),
}

impl std::fmt::Display for DepthUnit {
    /// As `--depth-unit` spells it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Relative => f.write_str("relative"),
            Self::Millimetres => f.write_str("mm"),
            Self::Metres => f.write_str("m"),
            Self::CodesPerMetre(n) => write!(f, "{n} codes per metre"),
        }
    }
}

impl DepthUnit {
    /// Metres per stored value; `None` for [`DepthUnit::Relative`].
    #[must_use]
    pub fn metres_per_code(self) -> Option<f32> {
        match self {
            Self::Relative => None,
            Self::Millimetres => Some(1e-3),
            Self::Metres => Some(1.0),
            Self::CodesPerMetre(n) => Some(1.0 / n.max(1) as f32),
        }
    }

    /// Whether the unit is metric.
    #[must_use]
    pub fn is_metric(self) -> bool {
        self != Self::Relative
    }
}

/// Where the maps come from.
#[derive(Debug)]
enum Store {
    /// One map, decoded once, used for every clean image.
    Single { path: PathBuf, map: Image },
    /// A directory of maps indexed by file stem.
    Directory {
        dir: PathBuf,
        by_stem: HashMap<OsString, Vec<PathBuf>>,
    },
}

/// A prepared map source: the single map decoded, or the directory indexed.
#[derive(Debug)]
pub(crate) struct MapSource {
    store: Store,
    invert: bool,
    normalize: bool,
    unit: DepthUnit,
    limits: DecodeLimits,
}

impl MapSource {
    /// Whether every map is min-max normalised (so relative).
    pub(crate) fn normalizes(&self) -> bool {
        self.normalize
    }

    /// Decodes the single map, or lists and indexes the directory. A metric unit cannot be
    /// inverted or normalised (its values are distances).
    pub(crate) fn new(
        path: &Path,
        invert: bool,
        normalize: bool,
        unit: DepthUnit,
        limits: DecodeLimits,
    ) -> Result<Self> {
        if unit.is_metric() && (invert || normalize) {
            return Err(DepthError::MetricOptions {
                option: if invert { "invert" } else { "normalize" },
            });
        }
        let store = if path.is_dir() {
            Store::Directory {
                dir: path.to_path_buf(),
                by_stem: index_directory(path)?,
            }
        } else if path.is_file() {
            Store::Single {
                path: path.to_path_buf(),
                map: read_stored(path, unit, normalize, &limits)?,
            }
        } else {
            return Err(DepthError::MapsNotFound {
                path: path.to_path_buf(),
            });
        };
        Ok(Self {
            store,
            invert,
            normalize,
            unit,
            limits,
        })
    }

    /// The map for `clean` (found by `clean_path`'s stem when the source is a directory), at
    /// the clean image's size, with notes on what was done to it, and for a metric unit the
    /// distance in metres that 1 stands for.
    pub(crate) fn depth_for(
        &self,
        clean: &Image,
        clean_path: Option<&Path>,
    ) -> Result<(Image, Vec<String>, Option<f32>)> {
        check_not_empty(clean)?;
        let (map_path, loaded);
        let map = match &self.store {
            Store::Single { path, map } => {
                map_path = path.as_path();
                map
            }
            Store::Directory { dir, by_stem } => {
                let clean_path =
                    clean_path.ok_or_else(|| DepthError::NeedsCleanPath { dir: dir.clone() })?;
                map_path = find_partner(dir, by_stem, clean_path)?;
                loaded = read_stored(map_path, self.unit, self.normalize, &self.limits)?;
                &loaded
            }
        };
        shape_map(
            map,
            map_path,
            clean.size(),
            self.unit,
            self.normalize,
            self.invert,
        )
    }
}

/// Where a map's bytes come from: a file, or bytes already read (named in messages).
#[derive(Clone, Copy)]
enum MapInput<'a> {
    File(&'a Path),
    Memory { bytes: &'a [u8], name: &'a Path },
}

/// Reads one map file as stored: metres for a metric unit, the fraction of the largest code
/// otherwise; holes filled for metric and normalised maps (module doc).
fn read_stored(
    path: &Path,
    unit: DepthUnit,
    normalize: bool,
    limits: &DecodeLimits,
) -> Result<Image> {
    read_input(MapInput::File(path), unit, normalize, limits)
}

fn read_input(
    input: MapInput<'_>,
    unit: DepthUnit,
    normalize: bool,
    limits: &DecodeLimits,
) -> Result<Image> {
    let path = match input {
        MapInput::File(p) | MapInput::Memory { name: p, .. } => p,
    };
    let in_memory = |e: uwnr_core::CoreError| DepthError::BadMapFile {
        path: path.to_path_buf(),
        reason: e.to_string().replace("\"<memory>\": ", ""),
    };
    let npy = is_npy_path(path);
    let gray = || -> Result<Image> {
        match input {
            MapInput::File(p) => Ok(load_gray(p, limits)?),
            MapInput::Memory { bytes, .. } => {
                load_gray_from_memory(bytes, limits).map_err(in_memory)
            }
        }
    };
    let codes = || -> Result<(Image, f32)> {
        match (input, npy) {
            (MapInput::File(p), true) => load_npy(p, limits),
            (MapInput::File(p), false) => Ok(load_gray_codes(p, limits)?),
            (MapInput::Memory { bytes, .. }, true) => {
                parse_npy(bytes, limits).map_err(|reason| DepthError::BadMapFile {
                    path: path.to_path_buf(),
                    reason,
                })
            }
            (MapInput::Memory { bytes, .. }, false) => {
                load_gray_codes_from_memory(bytes, limits).map_err(in_memory)
            }
        }
    };
    let mut map = match (unit.metres_per_code(), npy) {
        (None, false) => gray()?,
        (None, true) => codes()?.0,
        (Some(per_code), _) => {
            let (mut codes, _) = codes()?;
            for v in codes.plane_mut(0) {
                *v *= per_code;
            }
            codes
        }
    };
    if unit.is_metric() || normalize {
        let (w, h) = map.size();
        if !fill_holes(map.plane_mut(0), w, h) {
            return Err(DepthError::NoMeasuredDepth {
                path: path.to_path_buf(),
            });
        }
    }
    Ok(map)
}

/// Reads the map file `path` for a clean image of `clean_size`, as [`crate::DepthSource::Maps`]
/// with these settings would: the map in uwnr's convention at the clean image's size, notes,
/// and for a metric unit the metres that 1 stands for.
pub fn read_map(
    path: &Path,
    clean_size: (usize, usize),
    unit: DepthUnit,
    normalize: bool,
    limits: &DecodeLimits,
) -> Result<(Image, Vec<String>, Option<f32>)> {
    check_request(clean_size, unit, normalize)?;
    let map = read_stored(path, unit, normalize, limits)?;
    shape_map(&map, path, clean_size, unit, normalize, false)
}

/// [`read_map`] for a map already read into memory (`name`, whose extension says whether it is
/// a `.npy` array, is what messages and notes call it).
pub fn read_map_bytes(
    bytes: &[u8],
    name: &Path,
    clean_size: (usize, usize),
    unit: DepthUnit,
    normalize: bool,
    limits: &DecodeLimits,
) -> Result<(Image, Vec<String>, Option<f32>)> {
    check_request(clean_size, unit, normalize)?;
    let map = read_input(MapInput::Memory { bytes, name }, unit, normalize, limits)?;
    shape_map(&map, name, clean_size, unit, normalize, false)
}

/// Refuses an empty clean image and a metric unit asked to be normalised.
fn check_request((w, h): (usize, usize), unit: DepthUnit, normalize: bool) -> Result<()> {
    if w == 0 || h == 0 {
        return Err(DepthError::EmptyImage {
            width: w,
            height: h,
        });
    }
    if unit.is_metric() && normalize {
        return Err(DepthError::MetricOptions {
            option: "normalize",
        });
    }
    Ok(())
}

/// A stored map brought to the clean image's size and uwnr's convention (module doc).
fn shape_map(
    map: &Image,
    map_path: &Path,
    (width, height): (usize, usize),
    unit: DepthUnit,
    normalize: bool,
    invert: bool,
) -> Result<(Image, Vec<String>, Option<f32>)> {
    let mut notes = Vec::new();
    let mut depth = if map.size() == (width, height) {
        map.clone()
    } else {
        notes.push(format!(
            "depth map {} {}x{} resized to {width}x{height}",
            map_path.display(),
            map.width(),
            map.height()
        ));
        resize_bilinear(map, width, height)?
    };
    let values = depth.plane_mut(0);
    if unit.is_metric() {
        let far = values.iter().fold(0.0f32, |m, &v| m.max(v));
        if !(far.is_finite() && far > 0.0) {
            return Err(DepthError::NoMeasuredDepth {
                path: map_path.to_path_buf(),
            });
        }
        for v in values.iter_mut() {
            *v = (*v / far).clamp(0.0, 1.0);
        }
        return Ok((depth, notes, Some(far)));
    }
    if normalize {
        match normalise_min_max(values) {
            Some((lo, hi)) => notes.push(format!(
                "depth map {} normalised from [{lo:.4}, {hi:.4}] to [0, 1]",
                map_path.display()
            )),
            None => notes.push(format!(
                "depth map {} is constant; not normalised",
                map_path.display()
            )),
        }
    }
    if invert {
        for v in values.iter_mut() {
            *v = 1.0 - *v;
        }
    }
    Ok((depth, notes, None))
}

/// Fills the holes of a map (values that are 0, negative or not finite) in place, from the
/// measured values nearest in scale: a pull-push pyramid, each level the mean of the measured
/// values of its 2x2 cells, each hole taking the mean of the finest level whose cell around it
/// holds measurements. Measured values are kept exactly. Returns `false` when the map holds
/// no measured value at all.
pub fn fill_holes(values: &mut [f32], w: usize, h: usize) -> bool {
    let valid = |v: f32| v.is_finite() && v > 0.0;
    if values.iter().all(|&v| valid(v)) {
        return true;
    }
    // Level 0: (sum, count) per pixel.
    let mut levels: Vec<(Vec<f64>, Vec<f64>, usize, usize)> = vec![(
        values
            .iter()
            .map(|&v| if valid(v) { f64::from(v) } else { 0.0 })
            .collect(),
        values
            .iter()
            .map(|&v| if valid(v) { 1.0 } else { 0.0 })
            .collect(),
        w,
        h,
    )];
    while let Some((sum, count, lw, lh)) = levels.last() {
        if *lw == 1 && *lh == 1 {
            break;
        }
        let (nw, nh) = (lw.div_ceil(2), lh.div_ceil(2));
        let (mut s2, mut c2) = (vec![0.0f64; nw * nh], vec![0.0f64; nw * nh]);
        for y in 0..*lh {
            for x in 0..*lw {
                let (i, j) = (y * lw + x, (y / 2) * nw + x / 2);
                s2[j] += sum[i];
                c2[j] += count[i];
            }
        }
        levels.push((s2, c2, nw, nh));
    }
    let top = levels.len() - 1;
    if levels[top].1[0] == 0.0 {
        return false;
    }
    // Push: every level's empty cells take their parent's mean, from the top down.
    let mut filled: Vec<f64> = vec![levels[top].0[0] / levels[top].1[0]];
    for l in (0..top).rev() {
        let (sum, count, lw, lh) = &levels[l];
        let pw = lw.div_ceil(2);
        let mut next = vec![0.0f64; lw * lh];
        for y in 0..*lh {
            for x in 0..*lw {
                let i = y * lw + x;
                next[i] = if count[i] > 0.0 {
                    sum[i] / count[i]
                } else {
                    filled[(y / 2) * pw + x / 2]
                };
            }
        }
        filled = next;
    }
    for (v, f) in values.iter_mut().zip(filled) {
        if !valid(*v) {
            *v = f as f32;
        }
    }
    true
}

/// Image files of `dir` (not recursive) grouped by file stem; each group sorted for stable
/// error messages.
fn index_directory(dir: &Path) -> Result<HashMap<OsString, Vec<PathBuf>>> {
    let read_err = |source| DepthError::ReadDir {
        path: dir.to_path_buf(),
        source,
    };
    let mut by_stem: HashMap<OsString, Vec<PathBuf>> = HashMap::new();
    for entry in std::fs::read_dir(dir).map_err(read_err)? {
        let path = entry.map_err(read_err)?.path();
        if !path.is_file() || !(is_image_path(&path) || is_npy_path(&path)) {
            continue;
        }
        if let Some(stem) = path.file_stem() {
            by_stem.entry(stem.to_os_string()).or_default().push(path);
        }
    }
    for paths in by_stem.values_mut() {
        paths.sort();
    }
    Ok(by_stem)
}

/// The one map of the directory whose stem equals the clean image's stem, or else the only one
/// whose stem ends in the clean image's trailing number.
fn find_partner<'a>(
    dir: &Path,
    by_stem: &'a HashMap<OsString, Vec<PathBuf>>,
    clean_path: &Path,
) -> Result<&'a Path> {
    let stem = clean_path.file_stem().ok_or_else(|| DepthError::NoStem {
        clean: clean_path.to_path_buf(),
    })?;
    match by_stem.get(stem).map(Vec::as_slice) {
        Some([one]) => Ok(one),
        Some(many) if !many.is_empty() => Err(DepthError::AmbiguousMap {
            clean: clean_path.to_path_buf(),
            candidates: many.to_vec(),
        }),
        _ => by_number(clean_path, by_stem.values().flatten()).ok_or_else(|| {
            DepthError::MissingMap {
                clean: clean_path.to_path_buf(),
                dir: dir.to_path_buf(),
                stem: stem.to_string_lossy().into_owned(),
            }
        }),
    }
}

/// The number that ends a file stem (`"sync_depth_00050"` -> `"00050"`), if any.
fn trailing_number(path: &Path) -> Option<&str> {
    let stem = path.file_stem()?.to_str()?;
    let digits = stem.len() - stem.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    (digits > 0).then(|| &stem[stem.len() - digits..])
}

/// The only one of `maps` whose stem ends in the same number as `image`'s.
fn by_number<'a>(image: &Path, maps: impl Iterator<Item = &'a PathBuf>) -> Option<&'a Path> {
    let number = trailing_number(image)?;
    let mut same = maps.filter(|m| trailing_number(m) == Some(number));
    match (same.next(), same.next()) {
        (Some(m), None) => Some(m),
        _ => None,
    }
}

/// The depth map of `image` among `maps`: the one with the same file stem, or else the only one
/// whose stem ends in the same number (`rgb_00050.jpg` -> `sync_depth_00050.png`).
#[must_use]
pub fn partner_map<'a>(image: &Path, maps: &'a [PathBuf]) -> Option<&'a PathBuf> {
    let stem = image.file_stem();
    if let Some(m) = maps.iter().find(|m| m.file_stem() == stem) {
        return Some(m);
    }
    let found = by_number(image, maps.iter())?;
    maps.iter().find(|m| m.as_path() == found)
}

/// For each clean image in an RGB-D layout (`X/rgb/NAME` beside `X/depth/`), its depth map in
/// `X/depth/` ([`partner_map`]); `None` for images outside such a layout or without a partner.
/// Each `depth/` folder is listed once.
pub fn beside_maps(cleans: &[PathBuf]) -> Result<Vec<Option<PathBuf>>> {
    let mut listed: HashMap<PathBuf, Vec<PathBuf>> = HashMap::new();
    let mut out = Vec::with_capacity(cleans.len());
    for clean in cleans {
        let Some(depth_dir) = rgbd_depth_dir(clean) else {
            out.push(None);
            continue;
        };
        if !listed.contains_key(&depth_dir) {
            let mut maps: Vec<PathBuf> = index_directory(&depth_dir)?
                .into_values()
                .flatten()
                .collect();
            maps.sort();
            listed.insert(depth_dir.clone(), maps);
        }
        out.push(partner_map(clean, &listed[&depth_dir]).cloned());
    }
    Ok(out)
}

/// `X/depth` for an image `X/rgb/NAME` when that folder exists.
fn rgbd_depth_dir(clean: &Path) -> Option<PathBuf> {
    let parent = clean.parent()?;
    if parent.file_name()? != "rgb" {
        return None;
    }
    Some(parent.parent()?.join("depth")).filter(|d| d.is_dir())
}

#[cfg(test)]
mod tests;
