//! `uwnr dataset verify`: checks a dataset folder against its own settings and manifest. Every
//! manifest line must parse and name a planned pair once; every file of every pair must exist,
//! decode, and have the recorded size; the pair folders must hold nothing the manifest does not
//! name; and every planned pair must be in the manifest or in a failure list.

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;
use uwnr_core::io::{DecodeLimits, load_rgb};

use crate::error::{Result, io_err};
use crate::labels::mask::LabelImage;
use crate::labels::{COCO_FILE, LABELS_DIR, MASKS_DIR, yolo};
use crate::manifest::{
    PAIR_DIRS, Record, Settings, failed_ids, metadata_files, read_failures, read_manifest,
    temp_target,
};
use crate::plan::Size;
use crate::webdataset::{INDEX_FILE, Index, WEBDATASET_DIR, key, tar_members};

/// What verification found.
#[derive(Debug, Default)]
pub struct Report {
    /// Pairs in the manifest(s).
    pub pairs: usize,
    /// Pairs the settings plan.
    pub planned: usize,
    /// Planned pairs accounted for by failure lists.
    pub failed: usize,
    /// Problems, one line each; empty when the dataset is sound.
    pub problems: Vec<String>,
    /// Facts worth knowing that are not problems.
    pub notes: Vec<String>,
}

impl Report {
    /// Whether the dataset passed.
    #[must_use]
    pub fn ok(&self) -> bool {
        self.problems.is_empty()
    }
}

/// Verifies the dataset in `out`. `progress(done, total)` is called as pairs are checked (from
/// several threads).
pub fn verify(out: &Path, progress: &(dyn Fn(usize, usize) + Sync)) -> Result<Report> {
    let settings = Settings::read(out)?;
    let mut report = Report {
        planned: settings.pairs_planned,
        ..Report::default()
    };
    let planned: HashMap<String, u64> = settings
        .planned_pairs(None)
        .into_iter()
        .map(|p| (p.id, p.index))
        .collect();
    let (manifests, failed_files) = metadata_files(out)?;
    if manifests.is_empty() {
        report
            .problems
            .push("no manifest.jsonl: no pair was completed".into());
    }
    if manifests.len() > 1 || manifests.iter().any(|m| m != "manifest.jsonl") {
        report.notes.push(format!(
            "shard manifests present ({}); `uwnr dataset merge` joins them into manifest.jsonl",
            manifests.join(", ")
        ));
    }

    let mut records: Vec<Record> = Vec::new();
    let mut seen: HashMap<String, String> = HashMap::new();
    for m in &manifests {
        let contents = read_manifest(&out.join(m))?;
        for (line, reason) in &contents.bad_lines {
            report.problems.push(format!("{m} line {line}: {reason}"));
        }
        for (line, file) in &contents.unsafe_paths {
            let reason = crate::manifest::unsafe_path_reason(*line, file);
            report.problems.push(format!("{m} {reason}"));
        }
        if contents.torn_tail {
            report.problems.push(format!(
                "{m} ends in a torn line (an interrupted run): run the same command again"
            ));
        }
        for (line, r) in contents.records {
            let at = format!("{m} line {line}");
            match planned.get(&r.id) {
                None => {
                    report
                        .problems
                        .push(format!("{at}: pair {} is not in the plan", r.id));
                    continue;
                }
                Some(&index) if index != r.index => {
                    report.problems.push(format!(
                        "{at}: pair {} has index {}, the plan says {index}",
                        r.id, r.index
                    ));
                    continue;
                }
                Some(_) => {}
            }
            if let Some(first) = seen.get(&r.id) {
                report.problems.push(format!(
                    "{at}: pair {} is recorded twice (also {first})",
                    r.id
                ));
                continue;
            }
            seen.insert(r.id.clone(), at.clone());
            check_record_fields(&settings, &r, &at, &mut report.problems);
            records.push(r);
        }
    }
    report.pairs = records.len();

    // Files: present, decodable, the recorded size. In parallel: decoding dominates.
    let done = AtomicUsize::new(0);
    let total = records.len();
    let limits = DecodeLimits::default();
    let mut file_problems: Vec<String> = records
        .par_iter()
        .flat_map_iter(|r| {
            let mut problems = Vec::new();
            check_labels(out, r, &limits, &mut problems);
            for f in r.images() {
                let path = out.join(f);
                if !path.is_file() {
                    problems.push(format!("{f} (pair {}) is missing", r.id));
                    continue;
                }
                match load_rgb(&path, &limits) {
                    Ok(img) if img.size() != (r.width, r.height) => problems.push(format!(
                        "{f} is {}x{}, the manifest says {}x{}",
                        img.width(),
                        img.height(),
                        r.width,
                        r.height
                    )),
                    Ok(_) => {}
                    Err(e) => problems.push(format!("{f} does not decode: {e}")),
                }
            }
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            problems
        })
        .collect();
    file_problems.sort();
    report.problems.extend(file_problems);

    // Files nobody recorded.
    let named: HashSet<&str> = records.iter().flat_map(Record::files).collect();
    for d in PAIR_DIRS {
        let dir = out.join(d);
        if !dir.is_dir() {
            continue;
        }
        let mut stray = Vec::new();
        for entry in std::fs::read_dir(&dir).map_err(io_err(&dir))? {
            let name = entry
                .map_err(io_err(&dir))?
                .file_name()
                .to_string_lossy()
                .into_owned();
            let rel = format!("{d}/{name}");
            if temp_target(&name).is_some() {
                stray.push(format!(
                    "{rel} is a temporary file left by an interrupted run: run the same command \
                     again to finish and clean up"
                ));
            } else if !named.contains(rel.as_str()) {
                stray.push(format!("{rel} is not in the manifest"));
            }
        }
        stray.sort();
        report.problems.extend(stray);
    }

    check_coco(out, &settings, &manifests, &records, &mut report.problems);
    check_webdataset(out, &records, &mut report.problems);

    // Completeness.
    let mut failures = Vec::new();
    for f in &failed_files {
        failures.extend(read_failures(&out.join(f))?);
    }
    let failed = failed_ids(&failures);
    let mut missing: Vec<(u64, &str)> = planned
        .iter()
        .filter(|(id, _)| !seen.contains_key(*id) && !failed.contains(*id))
        .map(|(id, &i)| (i, id.as_str()))
        .collect();
    missing.sort_unstable();
    report.failed = planned.keys().filter(|id| failed.contains(*id)).count();
    if !missing.is_empty() {
        let first: Vec<&str> = missing.iter().take(5).map(|(_, id)| *id).collect();
        report.problems.push(format!(
            "{} of {} planned pairs are missing (first: {}): run the same command again to finish",
            missing.len(),
            planned.len(),
            first.join(", ")
        ));
    }
    if report.failed > 0 {
        report.notes.push(format!(
            "{} planned pairs were not made because their inputs failed (see {})",
            report.failed,
            failed_files.join(", ")
        ));
    }
    Ok(report)
}

/// Checks a record against the settings: method, file names, size.
fn check_record_fields(settings: &Settings, r: &Record, at: &str, problems: &mut Vec<String>) {
    if r.method != settings.method {
        problems.push(format!(
            "{at}: pair {} says method {}, the dataset is {}",
            r.id, r.method, settings.method
        ));
    }
    let expect = |dir: &str| format!("{dir}/{}.png", r.id);
    if r.underwater != expect("underwater") || r.clean != expect("clean") {
        problems.push(format!("{at}: pair {} names unexpected files", r.id));
    }
    if r.depth.is_some() != settings.save_depth
        || r.lightfield.is_some() != settings.save_lightfield
    {
        problems.push(format!(
            "{at}: pair {} does not list the depth / light-field files the settings ask for",
            r.id
        ));
    }
    if r.labels.is_some() != settings.labels.is_some()
        || r.mask.is_some() != settings.masks.is_some()
    {
        problems.push(format!(
            "{at}: pair {} does not list the label files the settings ask for",
            r.id
        ));
    }
    let labels_ext = match settings.labels.as_ref().map(|l| &l["format"]) {
        Some(f) if f == "yolo" => "txt",
        _ => "json",
    };
    if r.labels
        .as_ref()
        .is_some_and(|l| *l != format!("{LABELS_DIR}/{}.{labels_ext}", r.id))
        || r.mask
            .as_ref()
            .is_some_and(|m| *m != format!("{MASKS_DIR}/{}.png", r.id))
    {
        problems.push(format!("{at}: pair {} names unexpected label files", r.id));
    }
    if let Size::Fixed { width, height } = settings.size
        && (r.width, r.height) != (width, height)
    {
        problems.push(format!(
            "{at}: pair {} is {}x{}, the dataset is {width}x{height}",
            r.id, r.width, r.height
        ));
    }
}

/// A pair's label files: present, readable, describing an image of the pair's size, and (where
/// the manifest records it) with the fingerprint they were written with.
fn check_labels(out: &Path, r: &Record, limits: &DecodeLimits, problems: &mut Vec<String>) {
    if let Some(info) = &r.labels_info {
        for (f, fp) in [
            (&r.labels, &info.labels_fingerprint),
            (&r.mask, &info.mask_fingerprint),
        ] {
            if let (Some(f), Some(fp)) = (f, fp)
                && let Ok(bytes) = std::fs::read(out.join(f))
                && uwnr_render::record::fingerprint(&bytes) != *fp
            {
                problems.push(format!(
                    "{f} (pair {}) was changed after it was written (its fingerprint is not the \
                     manifest's)",
                    r.id
                ));
            }
        }
    }
    if let Some(f) = &r.labels {
        let path = out.join(f);
        match std::fs::read(&path) {
            Err(_) => problems.push(format!("{f} (pair {}) is missing", r.id)),
            Ok(bytes) if f.ends_with(".txt") => {
                if let Err(e) = std::str::from_utf8(&bytes)
                    .map_err(|e| e.to_string())
                    .and_then(yolo::parse)
                {
                    problems.push(format!("{f}: {e}"));
                }
            }
            Ok(bytes) => match serde_json::from_slice::<serde_json::Value>(&bytes) {
                Err(e) => problems.push(format!("{f} is not JSON: {e}")),
                Ok(v) => {
                    let image = &v["image"];
                    let expect = serde_json::json!({
                        "id": r.index + 1, "width": r.width, "height": r.height,
                        "file_name": r.underwater,
                    });
                    if ["id", "width", "height", "file_name"]
                        .iter()
                        .any(|k| image[k] != expect[k])
                        || !v["annotations"].is_array()
                    {
                        problems.push(format!(
                            "{f} does not describe pair {} (image id {}, {}x{}, {})",
                            r.id,
                            r.index + 1,
                            r.width,
                            r.height,
                            r.underwater
                        ));
                    }
                }
            },
        }
    }
    if let Some(f) = &r.mask {
        match LabelImage::read(&out.join(f), limits) {
            Err(e) => problems.push(format!("{f} (pair {}) does not decode: {e}", r.id)),
            Ok(m) if (m.width, m.height) != (r.width, r.height) => problems.push(format!(
                "{f} is {}x{}, the manifest says {}x{}",
                m.width, m.height, r.width, r.height
            )),
            Ok(_) => {}
        }
    }
}

/// `coco.json` of a merged dataset with COCO labels: present and listing exactly its pairs.
fn check_coco(
    out: &Path,
    settings: &Settings,
    manifests: &[String],
    records: &[Record],
    problems: &mut Vec<String>,
) {
    let coco = settings
        .labels
        .as_ref()
        .is_some_and(|l| l["format"] == "coco");
    if !coco || manifests != ["manifest.jsonl"] {
        return;
    }
    let path = out.join(COCO_FILE);
    let v: serde_json::Value = match std::fs::read(&path)
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice(&b).map_err(|e| e.to_string()))
    {
        Ok(v) => v,
        Err(e) => {
            problems.push(format!(
                "{COCO_FILE} is missing or unreadable ({e}): run the same command again"
            ));
            return;
        }
    };
    let mut sorted: Vec<Record> = records.to_vec();
    sorted.sort_by_key(|r| r.index);
    if let Ok(Some(expect)) = crate::labels::coco_bytes(out, settings.labels.as_ref(), &sorted)
        && std::fs::read(&path).is_ok_and(|b| b != expect)
    {
        problems.push(format!(
            "{COCO_FILE} differs from its pairs' labels files (edited after it was written?): run \
             the same command again to write it anew"
        ));
    }
    let mut ids: Vec<u64> = v["images"]
        .as_array()
        .map(|a| a.iter().filter_map(|i| i["id"].as_u64()).collect())
        .unwrap_or_default();
    ids.sort_unstable();
    let mut expect: Vec<u64> = records.iter().map(|r| r.index + 1).collect();
    expect.sort_unstable();
    if ids != expect {
        problems.push(format!(
            "{COCO_FILE} lists {} images, the manifest {} pairs: run the same command again",
            ids.len(),
            expect.len()
        ));
    }
}

/// `webdataset/`, when present: its index and shards hold exactly the manifest's pairs.
fn check_webdataset(out: &Path, records: &[Record], problems: &mut Vec<String>) {
    let dir = out.join(WEBDATASET_DIR);
    if !dir.join(INDEX_FILE).is_file() {
        return;
    }
    let stale = |why: String| {
        format!("{WEBDATASET_DIR}/ is out of date ({why}): run `uwnr dataset export` again")
    };
    let index = match Index::read(&dir) {
        Ok(i) => i,
        Err(e) => return problems.push(e.to_string()),
    };
    let mut keys = Vec::new();
    for s in &index.shards {
        let p = dir.join(&s.file);
        match std::fs::metadata(&p) {
            Ok(m) if m.len() == s.bytes => {}
            _ => {
                problems.push(stale(format!(
                    "{} is missing or not {} bytes",
                    s.file, s.bytes
                )));
                return;
            }
        }
        match tar_members(&p) {
            Ok(members) => {
                for (name, _) in members {
                    if let Some(k) = name.strip_suffix(".json").filter(|k| !k.contains('.')) {
                        keys.push(k.to_string());
                    }
                }
            }
            Err(e) => return problems.push(e.to_string()),
        }
    }
    let mut sorted: Vec<&Record> = records.iter().collect();
    sorted.sort_by_key(|r| r.index);
    let expect: Vec<String> = sorted.iter().map(|r| key(r)).collect();
    if keys != expect {
        problems.push(stale(format!(
            "{} pairs packed, {} in the manifest",
            keys.len(),
            expect.len()
        )));
    }
}
