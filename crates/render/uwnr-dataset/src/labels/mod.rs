//! Labels of the clean images, carried to every pair: COCO instances ([`coco`]), YOLO label files
//! ([`yolo`]) and segmentation masks ([`mask`]), all through the same [`Fit`] as the pixels.
//!
//! In a dataset folder:
//! ```text
//! OUT/labels/NAME_k.json   COCO: {"image": {...}, "annotations": [...]} of the pair
//! OUT/labels/NAME_k.txt    YOLO: the pair's label file
//! OUT/masks/NAME_k.png     the pair's label mask (values as in the source mask)
//! OUT/coco.json            COCO: the whole file (every pair, the source's categories)
//! ```
//! A pair's labels are written with its images, before its manifest line, so resume, shards,
//! `merge` and `verify` treat them as they treat the images. Degenerate and out-of-bounds
//! geometry follows one rule for every format ([`rules`]); `dataset.json` records a fingerprint
//! of each clean image's labels ([`resume`]), and each manifest line those of the files written
//! ([`info`]).

pub mod coco;
pub mod geometry;
pub mod info;
pub mod mask;
pub mod resume;
pub mod rle;
pub mod rules;
pub mod yolo;

use std::path::{Path, PathBuf};

use serde_json::{Value, json};
use uwnr_core::io::DecodeLimits;

pub use geometry::Fit;
pub use info::LabelsInfo;
pub use rules::{Drop, DropCounts};

use crate::error::{DatasetError, Result, io_err};
use crate::manifest::Record;

pub use crate::manifest::{LABELS_DIR, MASKS_DIR};
/// The assembled COCO file.
pub const COCO_FILE: &str = "coco.json";

/// Labels given with the clean images.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LabelInputs {
    /// A COCO instances file.
    pub coco: Option<PathBuf>,
    /// A folder of YOLO label files.
    pub yolo: Option<PathBuf>,
    /// A folder of label masks (PNG), matched by name.
    pub masks: Option<PathBuf>,
}

impl LabelInputs {
    /// Whether any label was given.
    #[must_use]
    pub fn any(&self) -> bool {
        self.coco.is_some() || self.yolo.is_some() || self.masks.is_some()
    }
}

/// The box labels of the run.
#[derive(Debug)]
enum Boxes {
    Coco {
        file: coco::CocoFile,
        /// Per clean image: its entry.
        entries: Vec<Option<usize>>,
        /// Per clean image: the first annotation id of its pair 0 (each pair takes as many ids
        /// as the entry has annotations).
        first_ids: Vec<u64>,
    },
    Yolo {
        dir: PathBuf,
        /// Per clean image: its label file (`None`: no objects).
        files: Vec<Option<PathBuf>>,
    },
}

/// The labels of a run, matched to the clean images and checked.
#[derive(Debug, Default)]
pub struct Labels {
    boxes: Option<Boxes>,
    /// Relative paths of the clean images (as matched).
    rel: Vec<String>,
    masks: Option<(PathBuf, Vec<Option<PathBuf>>)>,
    /// What the settings record (compared on resume).
    settings_labels: Option<Value>,
    settings_masks: Option<Value>,
}

/// One clean image's labels, ready for its pairs.
#[derive(Debug, Default)]
pub struct CleanLabels {
    coco: Option<(coco::FittedImage, u64, usize)>,
    yolo: Option<String>,
    mask: Option<Vec<u8>>,
    /// Annotations dropped under the [`rules`] (the same for every pair of the image).
    dropped: DropCounts,
}

/// A pair's label files: (path relative to the dataset folder, bytes), and what was dropped.
#[derive(Debug, Default)]
pub struct PairLabels {
    pub labels: Option<(String, Vec<u8>)>,
    pub mask: Option<(String, Vec<u8>)>,
    pub dropped: DropCounts,
}

impl PairLabels {
    /// What the pair's manifest line records of its labels (`None` without labels).
    #[must_use]
    pub fn info(&self) -> Option<LabelsInfo> {
        if self.labels.is_none() && self.mask.is_none() {
            return None;
        }
        let fp = |f: &Option<(String, Vec<u8>)>| {
            f.as_ref().map(|(_, b)| uwnr_render::record::fingerprint(b))
        };
        Some(LabelsInfo {
            dropped: self.dropped.clone(),
            labels_fingerprint: fp(&self.labels),
            mask_fingerprint: fp(&self.mask),
        })
    }
}

/// Paths of the clean images relative to the folder they were found in (`/`-separated), or their
/// file names when given as files.
#[must_use]
pub fn relative_paths(cleans: &[PathBuf], roots: &[PathBuf]) -> Vec<String> {
    let folders: Vec<&PathBuf> = roots.iter().filter(|r| r.is_dir()).collect();
    cleans
        .iter()
        .map(|c| {
            let rel = folders
                .iter()
                .find_map(|r| c.strip_prefix(r).ok())
                .unwrap_or_else(|| Path::new(c.file_name().unwrap_or(c.as_os_str())));
            rel.components()
                .map(|p| p.as_os_str().to_string_lossy())
                .collect::<Vec<_>>()
                .join("/")
        })
        .collect()
}

/// The file in `dir` that belongs to the clean image at `rel`: `dir/rel` with extension `ext`,
/// else `dir/STEM.ext`.
fn beside(dir: &Path, rel: &str, ext: &str) -> Option<PathBuf> {
    let p = dir.join(rel).with_extension(ext);
    if p.is_file() {
        return Some(p);
    }
    let stem = Path::new(rel).file_stem()?;
    let p = dir.join(stem).with_extension(ext);
    p.is_file().then_some(p)
}

/// For each clean image (at `rel`), its file in the folder `dir` given as `flag`: refused when the
/// folder is missing or matches no image; a note says how many have none and what that means.
fn match_files(
    dir: &Path,
    flag: &str,
    what: &str,
    rel: &[String],
    ext: &str,
    notes: &mut Vec<String>,
    without: &str,
) -> Result<Vec<Option<PathBuf>>> {
    if !dir.is_dir() {
        return Err(DatasetError::Invalid(format!(
            "{flag} {} is not a folder",
            dir.display()
        )));
    }
    let files: Vec<Option<PathBuf>> = rel.iter().map(|r| beside(dir, r, ext)).collect();
    let found = files.iter().filter(|f| f.is_some()).count();
    if found == 0 {
        return Err(DatasetError::Invalid(format!(
            "{flag} {}: no {what} matches the clean images (looked for {})",
            dir.display(),
            dir.join(&rel[0]).with_extension(ext).display()
        )));
    }
    if found < rel.len() {
        notes.push(format!(
            "{} of {} clean images have no {what} in {}: {}",
            rel.len() - found,
            rel.len(),
            dir.display(),
            without
        ));
    }
    Ok(files)
}

/// The fingerprint of each file's bytes (`None` where there is no file).
fn file_fingerprints(files: &[Option<PathBuf>]) -> Result<Vec<Option<String>>> {
    files
        .iter()
        .map(|f| {
            f.as_ref()
                .map(|f| {
                    let bytes = std::fs::read(f).map_err(io_err(f))?;
                    Ok(uwnr_render::record::fingerprint(&bytes))
                })
                .transpose()
        })
        .collect()
}

impl Labels {
    /// Reads and matches the labels of `cleans` (found under `roots`). Problems with a label
    /// file as a whole are errors; `notes` collects what the user should know (images without
    /// labels).
    pub fn prepare(
        inputs: &LabelInputs,
        cleans: &[PathBuf],
        roots: &[PathBuf],
        per_image: usize,
        notes: &mut Vec<String>,
    ) -> Result<Self> {
        if inputs.coco.is_some() && inputs.yolo.is_some() {
            return Err(DatasetError::Invalid(
                "--coco and --yolo are two formats of the same boxes: give one".into(),
            ));
        }
        let rel = relative_paths(cleans, roots);
        let mut out = Self {
            rel: rel.clone(),
            ..Self::default()
        };
        if let Some(path) = &inputs.coco {
            let bytes = std::fs::read(path).map_err(io_err(path))?;
            let file = coco::CocoFile::parse(path, &bytes).map_err(DatasetError::Invalid)?;
            let entries = file.match_images(&rel);
            let matched = entries.iter().filter(|e| e.is_some()).count();
            if matched == 0 {
                return Err(DatasetError::Invalid(format!(
                    "{}: none of its {} images is among the clean images (matched by file_name, \
                     e.g. {:?})",
                    path.display(),
                    file.image_count(),
                    rel.first().map(String::as_str).unwrap_or_default()
                )));
            }
            if matched < cleans.len() {
                notes.push(format!(
                    "{} of {} clean images have no entry in {}: their pairs are not made (listed \
                     in failed.jsonl)",
                    cleans.len() - matched,
                    cleans.len(),
                    path.display()
                ));
            }
            let mut first_ids = Vec::with_capacity(cleans.len());
            let mut next = 1u64;
            for e in &entries {
                first_ids.push(next);
                let n = e.map_or(0, |e| file.annotation_count(e));
                next += (n * per_image) as u64;
            }
            // Per clean image, so that fixing one image's labels lets its failed pairs be made.
            let images: Vec<Option<String>> = entries
                .iter()
                .zip(&first_ids)
                .map(|(e, &first)| e.map(|e| file.image_fingerprint(e, first)))
                .collect();
            out.settings_labels = Some(json!({
                "format": "coco",
                "file": path.to_string_lossy(),
                "info": file.info,
                "licenses": file.licenses,
                "categories": file.categories,
                "images": images,
            }));
            out.boxes = Some(Boxes::Coco {
                file,
                entries,
                first_ids,
            });
        }
        if let Some(dir) = &inputs.yolo {
            let files = match_files(
                dir,
                "--yolo",
                "label file",
                &rel,
                "txt",
                notes,
                "written as empty label files (no objects), as YOLO reads a missing file",
            )?;
            // The settings remember each label file's contents, so a resume notices edits.
            out.settings_labels = Some(json!({
                "format": "yolo",
                "dir": dir.to_string_lossy(),
                "images": file_fingerprints(&files)?,
            }));
            out.boxes = Some(Boxes::Yolo {
                dir: dir.clone(),
                files,
            });
        }
        if let Some(dir) = &inputs.masks {
            let files = match_files(
                dir,
                "--masks",
                "PNG mask",
                &rel,
                "png",
                notes,
                "their pairs are not made (listed in failed.jsonl)",
            )?;
            out.settings_masks = Some(json!({
                "dir": dir.to_string_lossy(),
                "images": file_fingerprints(&files)?,
            }));
            out.masks = Some((dir.clone(), files));
        }
        Ok(out)
    }

    /// The label files of clean image `i`, for messages: the COCO file and the image's entry,
    /// the YOLO file, the mask.
    #[must_use]
    pub fn files_of(&self, i: usize) -> Vec<String> {
        let mut out = Vec::new();
        match &self.boxes {
            Some(Boxes::Coco { file, .. }) => out.push(format!(
                "{} (the entry of {})",
                file.path.display(),
                self.rel[i]
            )),
            Some(Boxes::Yolo { dir, files }) => out.push(match &files[i] {
                Some(f) => f.display().to_string(),
                None => format!("{} (no file for {})", dir.display(), self.rel[i]),
            }),
            None => {}
        }
        if let Some((dir, files)) = &self.masks {
            out.push(match &files[i] {
                Some(f) => f.display().to_string(),
                None => format!("{} (no mask for {})", dir.display(), self.rel[i]),
            });
        }
        out
    }

    /// What `dataset.json` records about the labels and the masks.
    #[must_use]
    pub fn settings(&self) -> (Option<Value>, Option<Value>) {
        (self.settings_labels.clone(), self.settings_masks.clone())
    }

    /// Clean image `i`'s labels carried through `fit` (its decoded size is `fit`'s source
    /// size). The error names the label file and entry.
    pub fn for_clean(
        &self,
        i: usize,
        fit: &Fit,
        limits: &DecodeLimits,
    ) -> std::result::Result<CleanLabels, String> {
        let size = (fit.src_width, fit.src_height);
        let mut out = CleanLabels::default();
        match &self.boxes {
            None => {}
            Some(Boxes::Coco {
                file,
                entries,
                first_ids,
            }) => {
                let Some(e) = entries[i] else {
                    return Err(format!(
                        "{} has no entry for this image",
                        file.path.display()
                    ));
                };
                let fitted = file.fitted(e, size, fit)?;
                out.dropped.merge(&fitted.dropped());
                out.coco = Some((fitted, first_ids[i], file.annotation_count(e)));
            }
            Some(Boxes::Yolo { dir, files }) => {
                let text = match &files[i] {
                    Some(f) => {
                        std::fs::read_to_string(f).map_err(|e| format!("{}: {e}", f.display()))?
                    }
                    None => String::new(),
                };
                let objects = yolo::parse(&text).map_err(|e| {
                    let f = files[i].as_deref().unwrap_or(dir);
                    format!("{}: {e}", f.display())
                })?;
                let (text, dropped) = yolo::fitted(&text, &objects, fit);
                out.dropped.merge(&dropped);
                out.yolo = Some(text);
            }
        }
        if let Some((_, files)) = &self.masks {
            let Some(f) = &files[i] else {
                return Err("no label mask for this image in --masks".into());
            };
            let m =
                mask::LabelImage::read(f, limits).map_err(|e| format!("{}: {e}", f.display()))?;
            if (m.width, m.height) != size {
                return Err(format!(
                    "{}: the mask is {}x{}, the image is {}x{}",
                    f.display(),
                    m.width,
                    m.height,
                    size.0,
                    size.1
                ));
            }
            let png = m
                .fitted(fit)
                .encode()
                .map_err(|e| format!("{}: {e}", f.display()))?;
            out.mask = Some(png);
        }
        Ok(out)
    }
}

impl CleanLabels {
    /// The label files of pair `k` (global index `index`, name `id`) at the pair size `size`.
    #[must_use]
    pub fn pair(&self, id: &str, index: u64, k: usize, size: (usize, usize)) -> PairLabels {
        let labels = if let Some((fitted, first, per_pair)) = &self.coco {
            let v = fitted.pair(id, index, size, first + (k * per_pair) as u64);
            let mut bytes = serde_json::to_vec(&v).unwrap_or_default();
            bytes.push(b'\n');
            Some((format!("{LABELS_DIR}/{id}.json"), bytes))
        } else {
            self.yolo
                .as_ref()
                .map(|t| (format!("{LABELS_DIR}/{id}.txt"), t.as_bytes().to_vec()))
        };
        PairLabels {
            labels,
            mask: self
                .mask
                .as_ref()
                .map(|m| (format!("{MASKS_DIR}/{id}.png"), m.clone())),
            dropped: self.dropped.clone(),
        }
    }
}

/// The bytes of `OUT/coco.json` assembled from the pairs' labels files (`None` when the dataset
/// has no COCO labels); `records` in pair order.
pub fn coco_bytes(
    out: &Path,
    settings_labels: Option<&Value>,
    records: &[Record],
) -> Result<Option<Vec<u8>>> {
    let Some(s) = settings_labels.filter(|s| s["format"] == "coco") else {
        return Ok(None);
    };
    let mut pairs = Vec::with_capacity(records.len());
    for r in records {
        let Some(f) = &r.labels else { continue };
        let p = out.join(f);
        let bytes = std::fs::read(&p).map_err(io_err(&p))?;
        let v: Value = serde_json::from_slice(&bytes).map_err(|e| DatasetError::Corrupt {
            path: p.clone(),
            reason: format!("not a pair's COCO labels: {e}"),
        })?;
        pairs.push(v);
    }
    let all = coco::assemble(&s["info"], &s["licenses"], &s["categories"], pairs);
    let mut bytes = serde_json::to_vec(&all)
        .map_err(|e| DatasetError::Invalid(format!("cannot write {COCO_FILE}: {e}")))?;
    bytes.push(b'\n');
    Ok(Some(bytes))
}

/// Writes `OUT/coco.json` from the pairs' labels files (when the dataset has COCO labels),
/// atomically; `records` in pair order.
pub fn write_coco(out: &Path, settings_labels: Option<&Value>, records: &[Record]) -> Result<()> {
    if let Some(bytes) = coco_bytes(out, settings_labels, records)? {
        uwnr_core::io::write_atomic_bytes(&out.join(COCO_FILE), &bytes)?;
    }
    Ok(())
}
