//! `dataset.json`: the settings and inputs of a run ([`Settings`]), written once and compared on
//! every resume, so a resumed run cannot mix two configurations.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{FORMAT, SETTINGS_FILE};
use crate::error::{DatasetError, Result, io_err};
use crate::plan::{Shard, Size, clean_names, pair_id};

/// Everything that decides a dataset's content. Two runs with equal settings make the same
/// files, byte for byte.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// [`FORMAT`].
    pub format: String,
    /// `uwnr`, `jerlov`, `uisa`, `seathru` or `reinhard`.
    pub method: String,
    /// The method's configuration (for `uwnr`: the weights, their fingerprint and config, and
    /// `precision: "bf16"` when the products run in bf16).
    pub method_params: serde_json::Value,
    /// The depth source, as `uwnr_depth::DepthSource` serialises it.
    pub depth_source: serde_json::Value,
    /// How depth is read and trusted (`uwnr_render::DepthPolicy`); `null` in datasets made
    /// before it existed, which a resume therefore refuses to mix with new renders.
    #[serde(default)]
    pub depth_policy: serde_json::Value,
    /// Renders per clean image (K).
    pub per_image: usize,
    /// Seed of the reference draw and of the methods' sampling.
    pub seed: u64,
    /// Size of the pairs.
    pub size: Size,
    /// Whether `depth/` is written.
    pub save_depth: bool,
    /// Whether `lightfield/` is written.
    pub save_lightfield: bool,
    /// The clean images, in plan order.
    pub clean: Vec<String>,
    /// The references, in plan order (empty for methods that use none).
    pub references: Vec<String>,
    /// `clean.len() * per_image`.
    pub pairs_planned: usize,
    /// The box labels carried to the pairs (`format` `coco` or `yolo`, their source and its
    /// fingerprint; for COCO also its `info`, `licenses` and `categories`); absent without.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<serde_json::Value>,
    /// The label masks carried to the pairs (their folder); absent without.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub masks: Option<serde_json::Value>,
    /// The strength target of a water-anchored model's pairs (`crate::target`); absent for
    /// other methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<serde_json::Value>,
    /// The camera stage the underwater side went through (`uwnr_render::camera`); absent when
    /// none did (and in datasets made before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<uwnr_render::Camera>,
    /// The strength of the finished folder, PSNR(underwater, clean) (written when a run
    /// completes; not compared on resume).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strength: Option<crate::target::StrengthSummary>,
    /// Annotations dropped over the folder's pairs, by reason (written when an unsharded run
    /// ends; not compared on resume).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels_dropped: Option<crate::labels::DropCounts>,
}

/// One pair of the plan: its id, global index and clean image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlannedPair {
    pub id: String,
    pub index: u64,
    pub clean_index: usize,
    pub k: usize,
}

impl Settings {
    /// Output names of the clean images (see [`clean_names`]).
    #[must_use]
    pub fn names(&self) -> Vec<String> {
        let paths: Vec<PathBuf> = self.clean.iter().map(PathBuf::from).collect();
        clean_names(&paths)
    }

    /// Every planned pair, in index order; with a shard, only that shard's.
    #[must_use]
    pub fn planned_pairs(&self, shard: Option<Shard>) -> Vec<PlannedPair> {
        let names = self.names();
        let mut out = Vec::new();
        for (i, name) in names.iter().enumerate() {
            if shard.is_some_and(|s| !s.owns(i)) {
                continue;
            }
            for k in 0..self.per_image {
                out.push(PlannedPair {
                    id: pair_id(name, k),
                    index: (i * self.per_image + k) as u64,
                    clean_index: i,
                    k,
                });
            }
        }
        out
    }

    /// Reads `dir/dataset.json`.
    pub fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(SETTINGS_FILE);
        let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
        let s: Self = serde_json::from_str(&text).map_err(|e| DatasetError::Corrupt {
            path: path.clone(),
            reason: format!("not a dataset settings file: {e}"),
        })?;
        if s.format != FORMAT {
            return Err(DatasetError::Corrupt {
                path,
                reason: format!("format {:?}, this uwnr reads {FORMAT:?}", s.format),
            });
        }
        Ok(s)
    }

    /// These settings with what a folder's `records` measured, as `dataset.json` keeps it beside
    /// them (not compared on resume): their strength when the folder is `complete`, and the
    /// annotations their labels dropped when the run has labels or masks.
    #[must_use]
    pub fn finished(&self, records: &[super::Record], complete: bool) -> Self {
        let mut finished = self.clone();
        if complete {
            let strengths: Vec<f32> = records.iter().filter_map(|r| r.strength_db).collect();
            finished.strength = crate::target::StrengthSummary::of(&strengths);
        }
        if self.labels.is_some() || self.masks.is_some() {
            let mut dropped = crate::labels::DropCounts::default();
            for info in records.iter().filter_map(|r| r.labels_info.as_ref()) {
                dropped.merge(&info.dropped);
            }
            finished.labels_dropped = Some(dropped);
        }
        finished
    }

    /// Writes `dir/dataset.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(SETTINGS_FILE);
        let text = serde_json::to_string_pretty(self).map_err(|e| {
            DatasetError::Invalid(format!("cannot serialise the dataset settings: {e}"))
        })?;
        uwnr_core::io::write_atomic(&path, |w| {
            w.write_all(text.as_bytes())?;
            w.write_all(b"\n")
        })?;
        Ok(())
    }

    /// The first field in which `other` differs, with both values shown briefly.
    pub fn first_difference(&self, other: &Self) -> Result<Option<(String, String, String)>> {
        // The finished folder's strength is a result, not a setting.
        let (mut a, mut b) = (self.clone(), other.clone());
        a.strength = None;
        b.strength = None;
        a.labels_dropped = None;
        b.labels_dropped = None;
        first_difference(&a, &b)
    }
}

/// The first top-level field in which two settings differ, with both values shown briefly, as
/// their JSON forms compare. Settings that cannot be serialised are an error, never "equal": a
/// resume must not be accepted because nothing could be compared.
pub fn first_difference<T: Serialize>(a: &T, b: &T) -> Result<Option<(String, String, String)>> {
    let json = |v: &T| {
        serde_json::to_value(v)
            .map_err(|e| DatasetError::Invalid(format!("cannot compare the dataset settings: {e}")))
    };
    let (a, b) = (json(a)?, json(b)?);
    if !(a.is_object() && b.is_object()) {
        return Ok((a != b).then(|| ("settings".into(), brief(&a), brief(&b))));
    }
    Ok(nested_difference("", &a, &b))
}

/// The path (`labels.file`, `clean[3]`) of the first difference between two JSON values, with
/// both values shown briefly: descending into objects and equal-length lists, so the message
/// names what differs instead of showing two long values that look alike.
fn nested_difference(
    path: &str,
    a: &serde_json::Value,
    b: &serde_json::Value,
) -> Option<(String, String, String)> {
    use serde_json::Value;
    if a == b {
        return None;
    }
    match (a, b) {
        (Value::Object(ao), Value::Object(bo)) => {
            let null = Value::Null;
            let keys: std::collections::BTreeSet<&String> = ao.keys().chain(bo.keys()).collect();
            keys.into_iter().find_map(|key| {
                let p = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                nested_difference(
                    &p,
                    ao.get(key).unwrap_or(&null),
                    bo.get(key).unwrap_or(&null),
                )
            })
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (u, v))| nested_difference(&format!("{path}[{i}]"), u, v)),
        _ => Some((
            if path.is_empty() {
                "settings".into()
            } else {
                path.to_string()
            },
            brief(a),
            brief(b),
        )),
    }
}

fn brief(v: &serde_json::Value) -> String {
    let s = match v {
        serde_json::Value::Array(items) => format!("{} items", items.len()),
        other => other.to_string(),
    };
    if s.len() > 120 {
        format!("{}...", &s[..s.floor_char_boundary(117)])
    } else {
        s
    }
}
