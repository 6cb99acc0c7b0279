//! What a resumed run keeps of the folder it finds: the manifest's pairs that are still this
//! run's and whole on disk, and no temporary file of a killed run.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use crate::error::{Result, io_err};
use crate::manifest::{ManifestContents, PAIR_DIRS, PlannedPair, Record, temp_target};

/// The files a pair of this run has besides its two images.
#[derive(Clone, Copy, Debug)]
pub(super) struct PairFiles {
    pub depth: bool,
    pub lightfield: bool,
    pub labels: bool,
    pub mask: bool,
}

/// The records of `existing` a resumed run keeps: planned for it at the same index, not seen
/// before, with the files this run writes and every one of them on disk. Returns them, their
/// ids, and how many lines were dropped (torn, unreadable, or failing the checks): those pairs
/// are made again.
pub(super) fn kept_pairs(
    out: &Path,
    existing: ManifestContents,
    planned: &HashMap<&str, &PlannedPair>,
    wants: PairFiles,
) -> (Vec<Record>, HashSet<String>, usize) {
    let mut kept: Vec<Record> = Vec::new();
    let mut done: HashSet<String> = HashSet::new();
    let mut dropped = existing.bad_lines.len() + usize::from(existing.torn_tail);
    for (_, r) in existing.records {
        let valid = planned
            .get(r.id.as_str())
            .is_some_and(|p| p.index == r.index)
            && !done.contains(&r.id)
            && r.depth.is_some() == wants.depth
            && r.lightfield.is_some() == wants.lightfield
            && r.labels.is_some() == wants.labels
            && r.mask.is_some() == wants.mask
            && r.files().all(|f| out.join(f).is_file());
        if valid {
            done.insert(r.id.clone());
            kept.push(r);
        } else {
            dropped += 1;
        }
    }
    (kept, done, dropped)
}

/// Removes temporary files left by killed runs: in an unsharded run all of them; in a shard only
/// those of its own pairs (another shard may be writing the rest right now).
pub(super) fn remove_stale_temps(
    out: &Path,
    dirs: &[&str],
    owned: &HashMap<&str, &PlannedPair>,
    all: bool,
) -> Result<()> {
    for d in PAIR_DIRS.iter().filter(|d| dirs.contains(d)) {
        let dir = out.join(d);
        for entry in std::fs::read_dir(&dir).map_err(io_err(&dir))? {
            let entry = entry.map_err(io_err(&dir))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some(target) = temp_target(&name) else {
                continue;
            };
            // `NAME_k.png`, `NAME_k.json`...: the pair's id is the name without its extension.
            let id = target.rsplit_once('.').map_or(target, |(id, _)| id);
            if all || owned.contains_key(id) {
                let p = entry.path();
                std::fs::remove_file(&p).map_err(io_err(&p))?;
            }
        }
    }
    Ok(())
}
