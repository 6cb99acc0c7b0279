//! Depth maps read from files, as the released UWNR code uses them: a grey image divided by its
//! largest code (8-bit `/255`, 16-bit `/65535`, `uwnr_core::io::load_gray`), resized to the clean
//! image with the antialiased bilinear resize, optionally min-max normalised and inverted.
//!
//! A single file serves every clean image. A directory is indexed once and searched for the
//! image whose file stem equals the clean image's stem (`photo.jpg` -> `photo.png`,
//! `photo.tif`, ... any extension `uwnr_core::io::is_image_path` accepts).

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_gray};
use uwnr_core::resize::resize_bilinear;

use crate::error::{DepthError, Result};
use crate::util::{check_not_empty, normalise_min_max};

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
    limits: DecodeLimits,
}

impl MapSource {
    /// Whether every map is min-max normalised (so relative).
    pub(crate) fn normalizes(&self) -> bool {
        self.normalize
    }

    /// Decodes the single map, or lists and indexes the directory.
    pub(crate) fn new(
        path: &Path,
        invert: bool,
        normalize: bool,
        limits: DecodeLimits,
    ) -> Result<Self> {
        let store = if path.is_dir() {
            Store::Directory {
                dir: path.to_path_buf(),
                by_stem: index_directory(path)?,
            }
        } else if path.is_file() {
            Store::Single {
                path: path.to_path_buf(),
                map: load_gray(path, &limits)?,
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
            limits,
        })
    }

    /// The map for `clean` (found by `clean_path`'s stem when the source is a directory), at
    /// the clean image's size, with notes on what was done to it.
    pub(crate) fn depth_for(
        &self,
        clean: &Image,
        clean_path: Option<&Path>,
    ) -> Result<(Image, Vec<String>)> {
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
                loaded = load_gray(map_path, &self.limits)?;
                &loaded
            }
        };
        let mut notes = Vec::new();
        let (width, height) = clean.size();
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
        if self.normalize {
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
        if self.invert {
            for v in values.iter_mut() {
                *v = 1.0 - *v;
            }
        }
        Ok((depth, notes))
    }
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
        if !path.is_file() || !is_image_path(&path) {
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

/// The one map of the directory whose stem equals the clean image's stem.
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
        _ => Err(DepthError::MissingMap {
            clean: clean_path.to_path_buf(),
            dir: dir.to_path_buf(),
            stem: stem.to_string_lossy().into_owned(),
        }),
    }
}
