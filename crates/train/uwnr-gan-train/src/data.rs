//! Unpaired GAN data: clean in-air images with their depth, and real underwater references.
//!
//! Clean folders (the run's `data`) are read in one of three layouts:
//! - `rgb/` + `depth/` (the RGB-D sets in `data/rgbd/*`): depth maps matched by file stem, or
//!   else by the number that ends the stem (NYU's `rgb_00000.jpg` and `sync_depth_00000.png`),
//!   min-max normalised per map (`uwnr-depth`'s `Maps { normalize: true }`: NYU stores 16-bit
//!   millimetres, KITTI metres x 256); an image without a map is skipped and reported;
//! - `clean/` (a paired folder used for its clean side only): depth from `uwnr-depth`'s built-in
//!   prior;
//! - images directly in the folder: the built-in prior (or a `depth/` subfolder when there is one).
//!
//! Reference folders hold real underwater images: `underwater/` (a paired folder's underwater
//! side), `raw-890/` (UIEB), or images directly in the folder.
//!
//! Everything is decoded once (8-bit in memory), reflect-padded up to the crop. A batch is a
//! pure function of `(seed, epoch, index)`: clean image `k` of the epoch's seeded order, its
//! crop and flip from [`uwnr_run::plan`]; its reference drawn uniformly from an independent
//! stream, with its own crop and flip; its water code `z` drawn after the clean sample's plan.
//! Flips only, no quarter turns: the built-in depth prior is a ground-plane ramp that assumes
//! the image is upright, and a turned underwater reference would put the surface light sideways.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rand::Rng;
use rayon::prelude::*;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb};
use uwnr_depth::{DepthSource, PreparedDepth};
use uwnr_run::BatchSource;
use uwnr_run::pairs::{Rgb8, reflect_pad};
use uwnr_run::plan::{Geometry, epoch_order, mix64, plan_crop, rng_for};

use crate::error::{GanError, Result};
use crate::imaging::RGB;
use crate::model::draw_z;

/// Horizontal flips only (see the module docs).
const GEOMETRY: Geometry = Geometry {
    flip: true,
    rotate: false,
};
/// Stream tag of the reference draws ("refs").
const STREAM_REFERENCE: u64 = 0x7265_6673;

/// A clean image and its depth, at least `crop x crop`.
pub(crate) struct CleanSample {
    /// File name (for validation rows).
    pub name: String,
    /// The clean image.
    pub image: Rgb8,
    /// Depth codes (0..=255 for [0, 1], larger = farther), `width * height`.
    pub depth: Vec<u8>,
}

impl CleanSample {
    /// The centre `crop x crop` window as images (RGB, and 1-channel depth).
    pub fn centre(&self, crop: usize) -> Result<(Image, Image)> {
        let (w, h) = (self.image.width, self.image.height);
        let (x0, y0) = ((w - crop.min(w)) / 2, (h - crop.min(h)) / 2);
        let image = self
            .image
            .to_image()?
            .crop(x0, y0, crop.min(w), crop.min(h))?;
        let depth =
            Image::from_u8_codes(w, h, 1, &self.depth)?.crop(x0, y0, crop.min(w), crop.min(h))?;
        Ok((image, depth))
    }
}

/// Everything a run reads.
pub(crate) struct Data {
    pub clean: Vec<CleanSample>,
    pub references: Vec<Rgb8>,
    /// Mean over the references of their per-channel mean and standard deviation
    /// (R, G, B means, then R, G, B deviations): what the validation proxy compares renders to.
    pub reference_moments: [f64; 6],
    pub report: String,
}

/// Where a clean folder's images and depth maps are.
fn clean_layout(dir: &Path) -> (PathBuf, Option<PathBuf>) {
    let sub = |name: &str| Some(dir.join(name)).filter(|p| p.is_dir());
    if let Some(rgb) = sub("rgb") {
        return (rgb, sub("depth"));
    }
    if let Some(clean) = sub("clean") {
        return (clean, None);
    }
    (dir.to_path_buf(), sub("depth"))
}

/// Where a reference folder's images are.
fn reference_layout(dir: &Path) -> PathBuf {
    ["underwater", "raw-890"]
        .iter()
        .map(|s| dir.join(s))
        .find(|p| p.is_dir())
        .unwrap_or_else(|| dir.to_path_buf())
}

/// The image files directly in `dir`, in name order, at most `max`.
fn list_images(dir: &Path, max: Option<usize>) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|source| uwnr_run::RunError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && is_image_path(p))
        .collect();
    files.sort();
    if let Some(m) = max {
        files.truncate(m);
    }
    Ok(files)
}

/// Depth codes of a 1-channel map in [0, 1].
fn depth_codes(map: &Image) -> Vec<u8> {
    map.to_u8_codes()
}

/// Decodes the clean folders (with depth) and the reference folders.
pub(crate) fn load(
    clean_dirs: &[PathBuf],
    reference_dirs: &[PathBuf],
    crop: usize,
    max_per_dir: Option<usize>,
    limits: &DecodeLimits,
) -> Result<Data> {
    let mut report = String::new();
    let mut skipped: Vec<String> = Vec::new();
    let mut clean = Vec::new();
    for dir in clean_dirs {
        let (images, depth_dir) = clean_layout(dir);
        let prior = DepthSource::Builtin.prepare_with_limits(*limits)?;
        let maps = match &depth_dir {
            Some(d) => Some(list_images(d, None)?),
            None => None,
        };
        let plan = match &maps {
            Some(m) => DepthPlan::Maps(m),
            None => DepthPlan::Prior(&prior),
        };
        let files = list_images(&images, max_per_dir)?;
        let loaded: Vec<std::result::Result<CleanSample, String>> = files
            .par_iter()
            .map(|p| {
                load_clean(p, &plan, crop, limits).map_err(|e| format!("{}: {e}", p.display()))
            })
            .collect();
        let before = clean.len();
        for r in loaded {
            match r {
                Ok(s) => clean.push(s),
                Err(e) => skipped.push(e),
            }
        }
        report.push_str(&format!(
            "clean {}: {} images, depth from {}\n",
            images.display(),
            clean.len() - before,
            depth_dir
                .as_ref()
                .map_or("the built-in prior".to_string(), |d| {
                    format!("maps in {} (normalised per map)", d.display())
                })
        ));
    }
    let mut references = Vec::new();
    for dir in reference_dirs {
        let images = reference_layout(dir);
        let files = list_images(&images, max_per_dir)?;
        let loaded: Vec<std::result::Result<Rgb8, String>> = files
            .par_iter()
            .map(|p| load_reference(p, crop, limits).map_err(|e| format!("{}: {e}", p.display())))
            .collect();
        let before = references.len();
        for r in loaded {
            match r {
                Ok(s) => references.push(s),
                Err(e) => skipped.push(e),
            }
        }
        report.push_str(&format!(
            "references {}: {} images\n",
            images.display(),
            references.len() - before
        ));
    }
    for s in &skipped {
        report.push_str(&format!("skipped {s}\n"));
    }
    if clean.is_empty() {
        return Err(
            uwnr_run::RunError::NoData("no clean images in the data folders".into()).into(),
        );
    }
    if references.is_empty() {
        return Err(uwnr_run::RunError::NoData("no underwater reference images".into()).into());
    }
    let reference_moments = mean_moments(&references);
    Ok(Data {
        clean,
        references,
        reference_moments,
        report,
    })
}

/// Where a clean folder's depth comes from.
enum DepthPlan<'a> {
    /// The built-in prior.
    Prior(&'a PreparedDepth),
    /// The map files of its `depth/` folder.
    Maps(&'a [PathBuf]),
}

/// Decodes a clean image, computes its depth, and pads both up to `crop`.
fn load_clean(
    path: &Path,
    plan: &DepthPlan<'_>,
    crop: usize,
    limits: &DecodeLimits,
) -> Result<CleanSample> {
    let image = load_rgb(path, limits)?;
    let map = match plan {
        DepthPlan::Prior(prior) => prior.depth_for(&image, Some(path))?.map,
        DepthPlan::Maps(maps) => {
            let file = uwnr_depth::partner_map(path, maps).ok_or_else(|| {
                GanError::Run(uwnr_run::RunError::BadImage {
                    path: path.to_path_buf(),
                    reason: "no depth map with the same stem or number".into(),
                })
            })?;
            DepthSource::Maps {
                path: file.clone(),
                invert: false,
                normalize: true,
                unit: uwnr_depth::DepthUnit::Relative,
            }
            .prepare_with_limits(*limits)?
            .depth_for(&image, None)?
            .map
        }
    };
    let (w, h) = image.size();
    let (nw, nh) = (w.max(crop), h.max(crop));
    let (image, map) = if (nw, nh) == (w, h) {
        (image, map)
    } else {
        (reflect_pad(&image, nw, nh), reflect_pad(&map, nw, nh))
    };
    Ok(CleanSample {
        name: path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        image: Rgb8::from_image(&image)?,
        depth: depth_codes(&map),
    })
}

/// Decodes a reference and pads it up to `crop`.
fn load_reference(path: &Path, crop: usize, limits: &DecodeLimits) -> Result<Rgb8> {
    let image = load_rgb(path, limits)?;
    let (w, h) = image.size();
    let image = if w < crop || h < crop {
        reflect_pad(&image, w.max(crop), h.max(crop))
    } else {
        image
    };
    Ok(Rgb8::from_image(&image)?)
}

/// Per-channel mean and standard deviation of planar RGB values `[3, n]`: R, G, B means, then
/// R, G, B deviations.
pub(crate) fn moments(planar: &[f32]) -> [f64; 6] {
    let n = planar.len() / RGB;
    let mut out = [0.0; 6];
    if n == 0 {
        return out;
    }
    for c in 0..RGB {
        let p = &planar[c * n..(c + 1) * n];
        let mean = p.iter().map(|&v| f64::from(v)).sum::<f64>() / n as f64;
        let var = p
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n as f64;
        out[c] = mean;
        out[RGB + c] = var.sqrt();
    }
    out
}

/// The mean of the references' [`moments`].
fn mean_moments(references: &[Rgb8]) -> [f64; 6] {
    let mut sum = [0.0; 6];
    for r in references {
        let planar: Vec<f32> = r
            .codes
            .iter()
            .map(|&c| f32::from(c) / f32::from(u8::MAX))
            .collect();
        for (s, m) in sum.iter_mut().zip(moments(&planar)) {
            *s += m;
        }
    }
    sum.map(|s| s / references.len().max(1) as f64)
}

/// The batches of a run.
pub(crate) struct Batches {
    pub clean: Arc<Vec<CleanSample>>,
    pub references: Arc<Vec<Rgb8>>,
    pub seed: u64,
    pub batch_size: usize,
    pub crop: usize,
    pub z_dim: usize,
}

/// A batch, planar: `clean` `[b, 3, crop, crop]`, `depth` `[b, 1, crop, crop]`, `reference`
/// `[b, 3, crop, crop]`, `z` `[b, z_dim]`.
pub(crate) struct Batch {
    pub clean: Vec<f32>,
    pub depth: Vec<f32>,
    pub reference: Vec<f32>,
    pub z: Vec<f32>,
}

/// One sample of a batch.
struct Sample {
    clean: Vec<f32>,
    depth: Vec<f32>,
    reference: Vec<f32>,
    z: Vec<f32>,
}

impl BatchSource for Batches {
    type Batch = Batch;
    type Error = GanError;

    fn batches_per_epoch(&self) -> usize {
        self.clean.len() / self.batch_size.max(1)
    }

    fn batch(&self, epoch: usize, index: usize) -> Result<Batch> {
        let order = epoch_order(self.seed, epoch, self.clean.len());
        let first = index * self.batch_size;
        let samples: Vec<Sample> = (0..self.batch_size)
            .into_par_iter()
            .map(|slot| self.sample(&order, epoch, first + slot))
            .collect();
        let mut batch = Batch {
            clean: Vec::new(),
            depth: Vec::new(),
            reference: Vec::new(),
            z: Vec::new(),
        };
        for s in samples {
            batch.clean.extend_from_slice(&s.clean);
            batch.depth.extend_from_slice(&s.depth);
            batch.reference.extend_from_slice(&s.reference);
            batch.z.extend_from_slice(&s.z);
        }
        Ok(batch)
    }
}

impl Batches {
    /// Sample `position` of epoch `epoch`.
    fn sample(&self, order: &[usize], epoch: usize, position: usize) -> Sample {
        let crop = self.crop;
        let plane = crop * crop;
        let index = order[position];
        let c = &self.clean[index];
        let (w, h) = (c.image.width, c.image.height);
        let (plan, mut rng) = plan_crop(self.seed, epoch, position, (index, w, h), crop, GEOMETRY);
        let mut clean = vec![0.0_f32; RGB * plane];
        let mut depth = vec![0.0_f32; plane];
        for oy in 0..crop {
            for ox in 0..crop {
                let src = plan.source_index(ox, oy, crop, w);
                let dst = oy * crop + ox;
                for ch in 0..RGB {
                    clean[ch * plane + dst] = c.image.value(ch, src);
                }
                depth[dst] = f32::from(c.depth[src]) / f32::from(u8::MAX);
            }
        }
        let z = draw_z(&mut rng, self.z_dim);
        let mut pick = rng_for(self.seed, STREAM_REFERENCE, epoch as u64, position as u64);
        let r_index = pick.random_range(0..self.references.len());
        let r = &self.references[r_index];
        let (rplan, _) = plan_crop(
            mix64(self.seed ^ STREAM_REFERENCE),
            epoch,
            position,
            (r_index, r.width, r.height),
            crop,
            GEOMETRY,
        );
        let mut reference = vec![0.0_f32; RGB * plane];
        for oy in 0..crop {
            for ox in 0..crop {
                let src = rplan.source_index(ox, oy, crop, r.width);
                for ch in 0..RGB {
                    reference[ch * plane + oy * crop + ox] = r.value(ch, src);
                }
            }
        }
        Sample {
            clean,
            depth,
            reference,
            z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rgb(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Rgb8 {
        let codes = (0..RGB)
            .flat_map(|c| (0..w * h).map(move |i| (c, i)))
            .map(|(c, i)| f(c, i))
            .collect();
        Rgb8 {
            width: w,
            height: h,
            codes,
        }
    }

    fn source(n_clean: usize) -> Batches {
        let clean = (0..n_clean)
            .map(|k| CleanSample {
                name: format!("{k}.png"),
                image: rgb(6, 5, |c, i| (c * 50 + i + k) as u8),
                depth: (0..30).map(|i| (i * 8) as u8).collect(),
            })
            .collect();
        Batches {
            clean: Arc::new(clean),
            references: Arc::new(vec![
                rgb(6, 6, |c, _| (c * 100) as u8),
                rgb(5, 5, |_, i| i as u8),
            ]),
            seed: 9,
            batch_size: 2,
            crop: 4,
            z_dim: 3,
        }
    }

    #[test]
    fn batches_are_pure_functions_of_their_position() {
        let s = source(5);
        assert_eq!(s.batches_per_epoch(), 2);
        let a = s.batch(1, 1).unwrap();
        let b = s.batch(1, 1).unwrap();
        assert_eq!(
            (a.clean.len(), a.depth.len(), a.reference.len(), a.z.len()),
            (96, 32, 96, 6)
        );
        assert_eq!(
            (&a.clean, &a.depth, &a.reference, &a.z),
            (&b.clean, &b.depth, &b.reference, &b.z)
        );
        let c = s.batch(1, 0).unwrap();
        assert_ne!(a.z, c.z);
        assert!(a.z.iter().all(|v| (-1.0..=1.0).contains(v)));
    }

    #[test]
    fn depth_follows_its_image_through_the_crop_and_flip() {
        // Depth code of pixel i is 8 i and the red code is i + k: depth = 8 (red - k).
        let s = source(3);
        let order = epoch_order(s.seed, 0, 3);
        for pos in 0..3 {
            let smp = s.sample(&order, 0, pos);
            let k = order[pos] as f32;
            for (i, d) in smp.depth.iter().enumerate() {
                let red = smp.clean[i] * 255.0;
                assert!((d * 255.0 - 8.0 * (red - k)).abs() < 1e-3, "pixel {i}");
            }
        }
    }

    #[test]
    fn depth_maps_are_found_by_stem_or_trailing_number() {
        let maps: Vec<PathBuf> = [
            "d/sync_depth_00000.png",
            "d/sync_depth_00050.png",
            "d/a.png",
            "d/x1.png",
            "d/y1.png",
        ]
        .iter()
        .map(PathBuf::from)
        .collect();
        let find = |p: &str| {
            uwnr_depth::partner_map(Path::new(p), &maps).map(|m| m.to_string_lossy().into_owned())
        };
        assert_eq!(
            find("r/rgb_00050.jpg").as_deref(),
            Some("d/sync_depth_00050.png")
        );
        assert_eq!(find("r/a.jpg").as_deref(), Some("d/a.png"));
        // Two maps end in 1: ambiguous, so none.
        assert_eq!(find("r/z1.jpg"), None);
        assert_eq!(find("r/b.jpg"), None);
    }

    #[test]
    fn moments_of_a_hand_image() {
        // R = {0, 1}, G = {0.5, 0.5}, B = {1, 1}.
        let m = moments(&[0.0, 1.0, 0.5, 0.5, 1.0, 1.0]);
        let want = [0.5, 0.5, 1.0, 0.5, 0.0, 0.0];
        for (g, w) in m.iter().zip(want) {
            assert!((g - w).abs() < 1e-12);
        }
    }
}
