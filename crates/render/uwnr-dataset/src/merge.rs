//! `uwnr dataset merge`: joins the shards of a dataset into one `manifest.jsonl`.
//!
//! Shards either wrote into one shared folder (a shared filesystem: each shard has its own
//! `manifest.shard-I-of-N.jsonl`) or into folders of their own, which are then named as
//! sources and whose pair files are copied in. Merging refuses when a shard is missing or
//! unfinished, or when two shards disagree about a pair, and writes nothing in that case. The
//! result is the folder an unsharded run with the same settings makes.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use crate::error::{DatasetError, Result, io_err};
use crate::manifest::{
    Failure, Record, Settings, failed_ids, metadata_files, read_failures, read_manifest,
    shard_of_file, write_failures, write_manifest,
};
use crate::plan::Shard;

/// What a merge did.
#[derive(Debug, Default)]
pub struct MergeReport {
    /// Pairs in the merged manifest.
    pub pairs: usize,
    /// Shards found (N), if the dataset was sharded.
    pub shards: Option<usize>,
    /// Pair files copied in from source folders.
    pub copied: usize,
    /// Pairs accounted for by failure lists.
    pub failed: usize,
}

/// Merges the shards found in `out` and in `sources` into `out`. A refused merge leaves no empty
/// `out` behind when it made it.
pub fn merge(out: &Path, sources: &[PathBuf], gallery: bool) -> Result<MergeReport> {
    let existed = out.exists();
    let merged = merge_into(out, sources, gallery);
    if merged.is_err() && !existed {
        // Only an empty folder is removed: nothing merge wrote is lost.
        let _ = std::fs::remove_dir(out);
    }
    merged
}

fn merge_into(out: &Path, sources: &[PathBuf], gallery: bool) -> Result<MergeReport> {
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let mut settings = match Settings::read(out) {
        Ok(s) => Some(s),
        Err(DatasetError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            None
        }
        Err(e) => return Err(e),
    };
    // (folder, manifest file, shard) of every manifest, and failures likewise.
    let mut manifests: Vec<(PathBuf, String, Option<Shard>)> = Vec::new();
    let mut failures: Vec<Failure> = Vec::new();
    let mut folders: Vec<PathBuf> = vec![out.to_path_buf()];
    for s in sources {
        if s.canonicalize().ok() != out.canonicalize().ok() {
            folders.push(s.clone());
        }
    }
    for folder in &folders {
        if folder != out {
            let theirs = Settings::read(folder)?;
            match &settings {
                Some(ours) => {
                    if let Some((field, a, b)) = ours.first_difference(&theirs)? {
                        return Err(DatasetError::SettingsMismatch {
                            out: folder.clone(),
                            field,
                            existing: b,
                            requested: a,
                        });
                    }
                }
                None => settings = Some(theirs),
            }
        }
        let (m, f) = metadata_files(folder)?;
        for name in m {
            let shard = shard_of_file(&name, "manifest");
            manifests.push((folder.clone(), name, shard));
        }
        for name in f {
            failures.extend(read_failures(&folder.join(name))?);
        }
    }
    let settings = settings.ok_or_else(|| {
        DatasetError::Invalid(format!(
            "{} has no dataset.json and no source folder was given",
            out.display()
        ))
    })?;

    // Every shard of one count, all present.
    let counts: BTreeSet<usize> = manifests
        .iter()
        .filter_map(|(_, _, s)| s.map(|s| s.count))
        .collect();
    if counts.len() > 1 {
        return Err(DatasetError::Invalid(format!(
            "shard manifests of different shard counts ({counts:?}): one dataset, one --shard N"
        )));
    }
    let count = counts.first().copied();
    if let Some(n) = count {
        let present: BTreeSet<usize> = manifests
            .iter()
            .filter_map(|(_, _, s)| s.map(|s| s.index))
            .collect();
        let absent: Vec<String> = (0..n)
            .filter(|i| !present.contains(i))
            .map(|i| format!("{i}/{n}"))
            .collect();
        if !absent.is_empty() {
            return Err(DatasetError::Invalid(format!(
                "no manifest for shard(s) {}: run them (or name their folders) before merging",
                absent.join(", ")
            )));
        }
    }

    // Records, checked against each other and the plan.
    let planned: HashMap<String, u64> = settings
        .planned_pairs(None)
        .into_iter()
        .map(|p| (p.id, p.index))
        .collect();
    let mut merged: BTreeMap<u64, (Record, PathBuf)> = BTreeMap::new();
    for (folder, name, _) in &manifests {
        let contents = read_manifest(&folder.join(name))?;
        contents.refuse_unsafe_paths(&folder.join(name))?;
        if let Some((line, reason)) = contents.bad_lines.first() {
            return Err(DatasetError::Corrupt {
                path: folder.join(name),
                reason: format!("line {line}: {reason}"),
            });
        }
        if contents.torn_tail {
            return Err(DatasetError::Corrupt {
                path: folder.join(name),
                reason: "ends in a torn line: that shard was interrupted; run it again to finish"
                    .into(),
            });
        }
        for (line, r) in contents.records {
            if planned.get(&r.id) != Some(&r.index) {
                return Err(DatasetError::Corrupt {
                    path: folder.join(name),
                    reason: format!("line {line}: pair {} is not in the plan", r.id),
                });
            }
            match merged.get(&r.index) {
                Some((other, _)) if *other != r => {
                    return Err(DatasetError::Corrupt {
                        path: folder.join(name),
                        reason: format!(
                            "line {line}: pair {} differs from another shard's record of it",
                            r.id
                        ),
                    });
                }
                Some(_) => {}
                None => {
                    merged.insert(r.index, (r, folder.clone()));
                }
            }
        }
    }
    let failed = failed_ids(&failures);
    let missing: Vec<&String> = planned
        .keys()
        .filter(|id| {
            !failed.contains(*id) && !merged.contains_key(planned.get(*id).unwrap_or(&u64::MAX))
        })
        .collect();
    if !missing.is_empty() {
        let per_shard = match count {
            Some(n) => {
                let mut by: BTreeMap<usize, usize> = BTreeMap::new();
                for id in &missing {
                    let clean = (planned[*id] as usize) / settings.per_image.max(1);
                    *by.entry(clean % n).or_default() += 1;
                }
                by.iter()
                    .map(|(i, c)| format!("shard {i}/{n} lacks {c}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
            None => format!("{} pairs", missing.len()),
        };
        return Err(DatasetError::Invalid(format!(
            "{} of {} planned pairs are not finished ({per_shard}): run those shards again with \
             the same command, then merge",
            missing.len(),
            planned.len()
        )));
    }

    // Copy pair files in from source folders, then write the merged metadata.
    if !out.join(crate::manifest::SETTINGS_FILE).is_file() {
        settings.write(out)?;
    }
    let mut report = MergeReport {
        shards: count,
        failed: planned.keys().filter(|id| failed.contains(*id)).count(),
        ..MergeReport::default()
    };
    for (r, folder) in merged.values() {
        if folder == out {
            continue;
        }
        for f in r.files() {
            let (src, dst) = (folder.join(f), out.join(f));
            if let Some(parent) = dst.parent() {
                std::fs::create_dir_all(parent).map_err(io_err(parent))?;
            }
            let bytes = std::fs::read(&src).map_err(io_err(&src))?;
            uwnr_core::io::write_atomic_bytes(&dst, &bytes)?;
            report.copied += 1;
        }
    }
    let mut records: Vec<Record> = merged.into_values().map(|(r, _)| r).collect();
    for r in &records {
        for f in r.files() {
            if !out.join(f).is_file() {
                return Err(DatasetError::Invalid(format!(
                    "{f} (pair {}) is missing from {}",
                    r.id,
                    out.display()
                )));
            }
        }
    }
    report.pairs = records.len();
    write_manifest(&out.join("manifest.jsonl"), &mut records)?;
    // The finished folder's strength and the annotations its labels dropped, as an unsharded
    // run records them.
    let complete = records.len() == planned.len();
    if complete || settings.labels.is_some() || settings.masks.is_some() {
        settings.finished(&records, complete).write(out)?;
    }
    failures.sort_by(|a, b| a.source.cmp(&b.source));
    failures.dedup();
    write_failures(&out.join("failed.jsonl"), &failures)?;
    // Only now, with the merged files in place, the shard files in `out` go.
    for (folder, name, shard) in &manifests {
        if folder == out && shard.is_some() {
            let p = out.join(name);
            std::fs::remove_file(&p).map_err(io_err(&p))?;
            let f = out.join(crate::manifest::failed_name(*shard));
            if f.is_file() {
                std::fs::remove_file(&f).map_err(io_err(&f))?;
            }
        }
    }
    crate::labels::write_coco(out, settings.labels.as_ref(), &records)?;
    if gallery {
        crate::gallery::write(out, &records)?;
    }
    Ok(report)
}
