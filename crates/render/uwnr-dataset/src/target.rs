//! Strength calibration: how far a dataset's underwater side sits from its clean side,
//! PSNR(underwater, clean), drawn per pair from real pairs rather than left to the reference.
//!
//! A render method with a water anchor (the bundled model: `uwnr_model::water`) applies the
//! reference's water to the photo's own colours. How strong that water looks depends on the
//! photo as much as on the water: a dark green water on a bright in-air photo moves it much
//! farther than on the enhanced underwater photos real pairs hold. So each pair draws a target
//! strength from real pairs (seeded by the pair's seed) and the water is scaled along its own
//! line, `uwnr_model::water::calibrate`, to reach it on that photo (within a factor of 1.5).
//! That first scale counts the water alone; depth (farther is hazier), detail retention and the
//! camera's noise move the render farther still (0.8 dB on average with the bundled bank, 1.8
//! with `uieb-train` as the target, before the correction), and so do uwnr's effects, so the
//! dataset measures the render (before the camera stage, which it then applies once) and corrects the scale by the same closed form until it is within 0.25 dB of its target, in at
//! most three renders ([`PairWater::corrected`]):
//!
//! - no target: the strengths of the real pairs the bundled water bank was fitted on (UIEB's and
//!   LSUI's training pairs: mean 16.2 dB, 10th percentile 12.4), the reference's own water;
//! - `--target DIR` of pairs (`underwater/` and `clean/`): a pair of the target drawn per render,
//!   its fitted water and its strength, so both the strength and the colour shift follow the
//!   target's distribution;
//! - `--target DIR` of underwater photos only: a photo drawn per render, the water the bank's
//!   regressor reads from its statistics (mean, spread and percentiles per channel), at a strength
//!   drawn from the bundled real pairs.

use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_model::water::{Affine, WaterBank, bank_entry, bundled_bank, calibrate, rescaled};
use uwnr_render::record::StrengthRecord;

use crate::error::{DatasetError, Result};
use crate::plan::discover_images;

/// Mixed into a pair's seed for its target draw (a stream of its own).
const TARGET_STREAM: u64 = 0x7A26_E7CA_11B8;

/// Where a target came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TargetKind {
    /// The bundled bank's real pairs (the default).
    Bundled,
    /// A folder of real pairs.
    Pairs,
    /// A folder of real underwater photos.
    Photos,
}

/// One target item: a real pair (its water and strength) or a photo (its predicted water).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetEntry {
    /// The file (or `SET/NAME` of the bundled pairs).
    pub name: String,
    /// The water to render with; `None`: the reference's.
    pub water: Option<Affine>,
    /// The strength to reach, dB; `None`: drawn from the bundled pairs.
    pub strength_db: Option<f32>,
}

/// The strengths a dataset's pairs are drawn to.
#[derive(Clone, Debug, PartialEq)]
pub struct WaterTarget {
    /// What the entries are.
    pub kind: TargetKind,
    /// The folder as given (`bundled` for the default).
    pub source: String,
    /// At least one.
    pub entries: Vec<TargetEntry>,
    /// The bundled pairs' strengths, for photo targets.
    fallback_db: Vec<f32>,
}

impl WaterTarget {
    /// The default target: the bundled bank's real pairs, each render keeping its reference's
    /// water.
    pub fn bundled() -> Result<Self> {
        let bank = bank()?;
        Ok(Self {
            kind: TargetKind::Bundled,
            source: "bundled".into(),
            entries: bank
                .entries
                .iter()
                .map(|e| TargetEntry {
                    name: e.name.clone(),
                    water: None,
                    strength_db: Some(e.strength),
                })
                .collect(),
            fallback_db: Vec::new(),
        })
    }

    /// The target in `dir`: real pairs when it holds `underwater/` and `clean/`, otherwise the
    /// underwater photos found in it. Refuses a folder with nothing usable.
    pub fn load(dir: &Path, limits: &DecodeLimits) -> Result<Self> {
        let (uw, cl) = (dir.join("underwater"), dir.join("clean"));
        let bank = bank()?;
        let source = dir.to_string_lossy().into_owned();
        let (kind, entries) = if uw.is_dir() && cl.is_dir() {
            let mut entries = Vec::new();
            for under in discover_images(std::slice::from_ref(&uw), "target", None)? {
                let Ok(rel) = under.strip_prefix(&uw) else {
                    continue;
                };
                let clean = cl.join(rel);
                if !clean.is_file() {
                    continue;
                }
                let read = |p: &PathBuf| {
                    load_rgb(p, limits)
                        .map_err(|e| DatasetError::Invalid(format!("target {}: {e}", p.display())))
                };
                let e = bank_entry(
                    rel.to_string_lossy().into_owned(),
                    &read(&clean)?,
                    &read(&under)?,
                )
                .map_err(|e| DatasetError::Invalid(format!("target {}: {e}", under.display())))?;
                entries.push(TargetEntry {
                    name: e.name,
                    water: Some(e.water.clamped()),
                    strength_db: Some(e.strength),
                });
            }
            (TargetKind::Pairs, entries)
        } else {
            let mut entries = Vec::new();
            for photo in discover_images(&[dir.to_path_buf()], "target", None)? {
                let img = load_rgb(&photo, limits).map_err(|e| {
                    DatasetError::Invalid(format!("target {}: {e}", photo.display()))
                })?;
                let water = bank.predict(&img).map_err(|e| {
                    DatasetError::Invalid(format!("target {}: {e}", photo.display()))
                })?;
                let name = photo
                    .strip_prefix(dir)
                    .unwrap_or(&photo)
                    .to_string_lossy()
                    .into_owned();
                entries.push(TargetEntry {
                    name,
                    water: Some(water),
                    strength_db: None,
                });
            }
            (TargetKind::Photos, entries)
        };
        if entries.is_empty() {
            return Err(DatasetError::Invalid(format!(
                "--target {}: no real pairs (underwater/ and clean/ with the same names) or \
                 underwater photos found",
                dir.display()
            )));
        }
        Ok(Self {
            kind,
            source,
            entries,
            fallback_db: bank.entries.iter().map(|e| e.strength).collect(),
        })
    }

    /// What `dataset.json` records: the kind, the source, and every entry (so a resume with a
    /// changed target is refused), with the target's own strength when it has one.
    #[must_use]
    pub fn record(&self) -> Value {
        let strengths: Vec<f32> = self.entries.iter().filter_map(|e| e.strength_db).collect();
        rounded(json!({
            "kind": self.kind,
            "source": self.source,
            "pairs": self.entries.len(),
            "strength": StrengthSummary::of(&strengths),
            "entries": self.entries,
            // Folders made before the correction on the render lack these, so a resume does
            // not mix their pairs with pairs made this way.
            "corrected_on": "render",
            "tolerance_db": STRENGTH_TOLERANCE_DB,
            "max_renders": MAX_STRENGTH_RENDERS,
        }))
    }

    /// The water of one pair: the target item drawn by `seed`, its water (or the reference's
    /// `reference`), scaled to the drawn strength on `clean` by the affine water alone. The
    /// full render (depth, detail, noise) moves a pair farther than that, so the dataset then
    /// corrects the scale on the render itself ([`PairWater::corrected`]).
    pub fn water_for(
        &self,
        reference: Option<Affine>,
        clean: &Image,
        seed: u64,
    ) -> Result<PairWater> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ TARGET_STREAM);
        let entry = &self.entries[rng.random_range(0..self.entries.len())];
        let water = entry.water.or(reference).ok_or_else(|| {
            DatasetError::Invalid("the strength target needs a water (the reference's)".into())
        })?;
        let target_db = match entry.strength_db {
            Some(db) => db,
            None if !self.fallback_db.is_empty() => {
                self.fallback_db[rng.random_range(0..self.fallback_db.len())]
            }
            None => {
                return Err(DatasetError::Invalid(
                    "no strength to draw from the bundled pairs".into(),
                ));
            }
        };
        let (_, scale) = calibrate(&water, clean, target_db)
            .map_err(|e| DatasetError::Invalid(format!("calibrating the water: {e}")))?;
        Ok(PairWater {
            name: entry.name.clone(),
            base: water,
            target_db,
            scale,
            rendered_db: Vec::new(),
        })
    }
}

/// A render whose strength is within this of its target is kept, dB.
pub const STRENGTH_TOLERANCE_DB: f32 = 0.25;

/// Renders of a pair at most, the first included ([`PairWater::corrected`]).
pub const MAX_STRENGTH_RENDERS: usize = 3;

/// One pair's water: the target drawn, its water along its line, and the scale reached.
#[derive(Clone, Debug, PartialEq)]
pub struct PairWater {
    /// The target item drawn.
    pub name: String,
    /// The water at scale 1.
    pub base: Affine,
    /// The strength to reach, dB.
    pub target_db: f32,
    /// The scale along the water's line ([`Affine::scaled`]) of the next render.
    pub scale: f32,
    /// The strength of each render so far, dB.
    pub rendered_db: Vec<f32>,
}

impl PairWater {
    /// The water to render with.
    pub fn water(&self) -> Affine {
        self.base.scaled(self.scale)
    }

    /// After a render of strength `rendered_db`: whether to render again, with the scale moved
    /// by the closed form of [`Affine::scaled`] (PSNR falls by `20 log10 s`). Stops within
    /// [`STRENGTH_TOLERANCE_DB`], after [`MAX_STRENGTH_RENDERS`], or when the scale is held at
    /// a bound ([`uwnr_model::water::MAX_STRENGTH_SCALE`] or 0).
    pub fn corrected(&mut self, rendered_db: f32) -> bool {
        self.rendered_db.push(rendered_db);
        if !rendered_db.is_finite()
            || (rendered_db - self.target_db).abs() <= STRENGTH_TOLERANCE_DB
            || self.rendered_db.len() >= MAX_STRENGTH_RENDERS
        {
            return false;
        }
        let next = rescaled(self.scale, rendered_db, self.target_db);
        if (next - self.scale).abs() < 1e-4 {
            return false;
        }
        self.scale = next;
        true
    }

    /// What the manifest records of it.
    #[must_use]
    pub fn record(&self) -> StrengthRecord {
        StrengthRecord {
            target: self.name.clone(),
            target_db: self.target_db,
            scale: self.scale,
            renders: self.rendered_db.len(),
        }
    }
}

/// Decimals kept of the recorded numbers: they are compared on resume after a round trip
/// through JSON text, which a float of full precision does not always survive exactly.
const RECORD_DECIMALS: i32 = 5;

/// `v` with every non-integer number rounded to [`RECORD_DECIMALS`].
fn rounded(v: Value) -> Value {
    match v {
        Value::Number(n) if n.is_f64() => {
            let scale = 10f64.powi(RECORD_DECIMALS);
            n.as_f64()
                .map_or(Value::Null, |x| json!((x * scale).round() / scale))
        }
        Value::Array(a) => Value::Array(a.into_iter().map(rounded).collect()),
        Value::Object(o) => Value::Object(o.into_iter().map(|(k, v)| (k, rounded(v))).collect()),
        other => other,
    }
}

fn bank() -> Result<&'static WaterBank> {
    bundled_bank().map_err(|e| DatasetError::Invalid(e.to_string()))
}

/// The distribution of PSNR(underwater, clean) over a set of pairs, dB.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StrengthSummary {
    /// Pairs counted (those with a finite strength).
    pub pairs: usize,
    /// Mean.
    pub mean: f32,
    /// 10th, 50th and 90th percentiles (nearest rank).
    pub p10: f32,
    pub p50: f32,
    pub p90: f32,
    /// Extremes.
    pub min: f32,
    pub max: f32,
}

impl StrengthSummary {
    /// The summary of `values` (non-finite ones, identical images, are left out); `None` when
    /// none is left.
    #[must_use]
    pub fn of(values: &[f32]) -> Option<Self> {
        let mut v: Vec<f32> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f32::total_cmp);
        let rank = |q: f64| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
        Some(Self {
            pairs: v.len(),
            mean: (v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64) as f32,
            p10: rank(0.1),
            p50: rank(0.5),
            p90: rank(0.9),
            min: v[0],
            max: v[v.len() - 1],
        })
    }

    /// One line for the end of a run.
    #[must_use]
    pub fn line(&self) -> String {
        format!(
            "strength PSNR(underwater, clean) over {} pairs: mean {:.2} dB, p10 {:.2}, median {:.2}, p90 {:.2} (min {:.2}, max {:.2})",
            self.pairs, self.mean, self.p10, self.p50, self.p90, self.min, self.max
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use uwnr_model::water::MAX_STRENGTH_SCALE;

    #[test]
    fn strength_summary_by_nearest_rank() {
        let v: Vec<f32> = (1..=10).map(|x| x as f32).collect();
        let s = StrengthSummary::of(&v).unwrap();
        assert_eq!((s.pairs, s.p10, s.p50, s.p90), (10, 1.0, 5.0, 9.0));
        assert!((s.mean - 5.5).abs() < 1e-6);
        assert!(StrengthSummary::of(&[f32::INFINITY]).is_none());
    }

    #[test]
    fn the_bundled_target_draws_real_strengths_deterministically() {
        let t = WaterTarget::bundled().unwrap();
        assert!(t.entries.len() > 100);
        let clean = Image::from_planar(
            32,
            24,
            3,
            (0..3 * 32 * 24).map(|i| (i % 97) as f32 / 97.0).collect(),
        )
        .unwrap();
        let reference = Affine {
            gain: [0.4, 0.7, 0.6],
            offset: [0.05, 0.2, 0.25],
        };
        let a = t.water_for(Some(reference), &clean, 7).unwrap();
        let b = t.water_for(Some(reference), &clean, 7).unwrap();
        assert_eq!(a, b);
        let c = t.water_for(Some(reference), &clean, 8).unwrap();
        assert_ne!(a.record(), c.record());
        assert!(t.water_for(None, &clean, 7).is_err());
    }

    #[test]
    fn an_empty_target_is_refused_and_pairs_give_their_water() {
        let tmp = tempfile::tempdir().unwrap();
        let err = WaterTarget::load(tmp.path(), &DecodeLimits::default()).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains("no images") || msg.contains("no real pairs"),
            "{msg}"
        );
        for d in ["underwater", "clean"] {
            std::fs::create_dir_all(tmp.path().join(d)).unwrap();
        }
        let clean = Image::from_planar(
            16,
            16,
            3,
            (0..3 * 256).map(|i| (i % 29) as f32 / 29.0).collect(),
        )
        .unwrap();
        let water = Affine {
            gain: [0.5, 0.8, 0.7],
            offset: [0.05, 0.1, 0.2],
        };
        uwnr_core::io::save_rgb(&tmp.path().join("clean/a.png"), &clean).unwrap();
        uwnr_core::io::save_rgb(
            &tmp.path().join("underwater/a.png"),
            &water.apply(&clean).unwrap(),
        )
        .unwrap();
        let t = WaterTarget::load(tmp.path(), &DecodeLimits::default()).unwrap();
        assert_eq!(t.kind, TargetKind::Pairs);
        let got = t.entries[0].water.unwrap();
        for c in 0..3 {
            assert!((got.gain[c] - water.gain[c]).abs() < 0.02, "{got:?}");
        }
        // Rendering the target's own clean image reaches its own strength with its own water.
        let pw = t.water_for(None, &clean, 1).unwrap();
        let (w, rec) = (pw.water(), pw.record());
        let db = uwnr_model::water::pair_psnr(&w.apply(&clean).unwrap(), &clean).unwrap();
        assert!(
            (db - t.entries[0].strength_db.unwrap()).abs() < 0.3,
            "{db} {rec:?}"
        );
    }

    #[test]
    fn a_render_off_its_target_is_rescaled_within_bounds() {
        let water = Affine {
            gain: [0.5, 0.8, 0.7],
            offset: [0.05, 0.1, 0.2],
        };
        let mut pw = PairWater {
            name: "x".into(),
            base: water,
            target_db: 16.0,
            scale: 1.0,
            rendered_db: Vec::new(),
        };
        // 2 dB too strong: the scale falls by the closed form, 10^(-2/20).
        assert!(pw.corrected(14.0));
        assert!((pw.scale - 10f32.powf(-0.1)).abs() < 1e-5, "{}", pw.scale);
        // Within the tolerance: kept.
        assert!(!pw.corrected(16.2));
        assert_eq!(pw.rendered_db, [14.0, 16.2]);
        assert_eq!(pw.record().renders, 2);
        // Too weak at the largest scale: nothing left to move.
        pw.rendered_db.clear();
        pw.scale = MAX_STRENGTH_SCALE;
        assert!(!pw.corrected(20.0));
        // At most MAX_STRENGTH_RENDERS renders.
        pw.rendered_db.clear();
        pw.scale = 1.0;
        assert!(pw.corrected(10.0));
        assert!(pw.corrected(11.0));
        assert!(!pw.corrected(12.0));
        assert_eq!(pw.rendered_db.len(), MAX_STRENGTH_RENDERS);
    }
}
