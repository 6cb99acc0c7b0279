//! WebDataset shards of a dataset folder: the pairs of `manifest.jsonl`, in pair order, packed
//! into POSIX tar files of a chosen size, which PyTorch (`webdataset`), Ray and other streaming
//! loaders read sequentially.
//!
//! ```text
//! OUT/webdataset/uwnr-000000.tar, uwnr-000001.tar, ...
//! OUT/webdataset/index.json     the shards, their pair counts and sizes, the brace pattern
//! ```
//! Each pair is one sample, its members named by WebDataset's convention `KEY.EXT` with the key
//! `INDEX-NAME_k` (the 8-digit pair index, then the pair's name with dots made `_`, since
//! loaders split the key at the first dot):
//! `KEY.json` (the manifest line), `KEY.underwater.png`, `KEY.clean.png`, and as the dataset
//! has them `KEY.depth.png`, `KEY.lightfield.png`, `KEY.labels.json` or `KEY.labels.txt`,
//! `KEY.mask.png`. A sample never spans two shards.
//!
//! The tars are written with the `tar` crate and are deterministic: members in a fixed order,
//! mode 0644, owner 0, time 0, ustar headers (a GNU long-name entry before names of 100 bytes or
//! more, which Python's `tarfile` and so WebDataset read), so the same folder always packs to the
//! same bytes. Every shard is written to a temporary name and renamed; the index is written last.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, Result, io_err};
use crate::manifest::{Record, Settings, read_manifest};

/// Folder of the shards inside a dataset folder.
pub const WEBDATASET_DIR: &str = "webdataset";
/// The shards' index.
pub const INDEX_FILE: &str = "index.json";
/// Format tag of the index.
pub const INDEX_FORMAT: &str = "uwnr-webdataset/1";
/// Default shard size: 512 MiB.
pub const DEFAULT_SHARD_BYTES: u64 = 512 << 20;
/// Smallest shard size accepted.
const MIN_SHARD_BYTES: u64 = 64 << 10;

const BLOCK: u64 = 512;

/// One shard in the index.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardEntry {
    pub file: String,
    pub pairs: usize,
    pub bytes: u64,
    /// Keys of the first and last samples.
    pub first: String,
    pub last: String,
}

/// `index.json`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Index {
    pub format: String,
    /// Pairs in all shards.
    pub pairs: usize,
    /// The shards as a brace pattern (`uwnr-{000000..000003}.tar`), as WebDataset takes them.
    pub pattern: String,
    pub shards: Vec<ShardEntry>,
}

impl Index {
    /// Reads `dir/index.json`.
    pub fn read(dir: &Path) -> Result<Self> {
        let p = dir.join(INDEX_FILE);
        let text = std::fs::read_to_string(&p).map_err(io_err(&p))?;
        serde_json::from_str(&text).map_err(|e| DatasetError::Corrupt {
            path: p,
            reason: format!("not a WebDataset index: {e}"),
        })
    }
}

/// What an export did.
#[derive(Debug)]
pub struct ExportReport {
    /// The shards' folder.
    pub dir: PathBuf,
    pub index: Index,
    /// Bytes written.
    pub bytes: u64,
    pub secs: f64,
}

/// Parses a size: bytes, or with `K`, `M`, `G` (powers of 1024; a trailing `B`/`iB` allowed).
pub fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim().to_ascii_uppercase();
    let t = t.trim_end_matches("IB").trim_end_matches('B');
    let (num, mult) = match t.chars().last() {
        Some('K') => (&t[..t.len() - 1], 1u64 << 10),
        Some('M') => (&t[..t.len() - 1], 1 << 20),
        Some('G') => (&t[..t.len() - 1], 1 << 30),
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("expected a size such as 512M or 2G, got {s:?}"))?;
    let bytes = (v * mult as f64).round();
    if !(bytes >= MIN_SHARD_BYTES as f64 && bytes < 1e15) {
        return Err(format!("shard sizes go from 64K up, got {s:?}"));
    }
    Ok(bytes as u64)
}

/// The WebDataset key of a pair.
#[must_use]
pub fn key(r: &Record) -> String {
    format!("{:08}-{}", r.index, r.id.replace('.', "_"))
}

/// The member extension of a pair file (`underwater/a_0.png` -> `underwater.png`).
fn member_ext(file: &str) -> Result<String> {
    let (dir, name) = file.split_once('/').unwrap_or(("", file));
    let ext = Path::new(name)
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let role = match dir {
        crate::manifest::MASKS_DIR => "mask",
        d if crate::manifest::PAIR_DIRS.contains(&d) => d,
        _ => {
            return Err(DatasetError::Invalid(format!(
                "{file} is not in a pair folder"
            )));
        }
    };
    Ok(format!("{role}.{ext}"))
}

/// One sample: (member name, source: a file of the folder or bytes).
struct Sample {
    key: String,
    members: Vec<(String, Member)>,
    bytes: u64,
}

enum Member {
    File(PathBuf),
    Bytes(Vec<u8>),
}

fn padded(n: u64) -> u64 {
    n.div_ceil(BLOCK) * BLOCK
}

/// The header of a member: mode 0644, owner 0, time 0, no user or group names (so the same
/// folder packs to the same bytes).
fn header(size: u64) -> tar::Header {
    let mut h = tar::Header::new_ustar();
    h.set_mode(0o644);
    h.set_uid(0);
    h.set_gid(0);
    h.set_mtime(0);
    h.set_size(size);
    h.set_entry_type(tar::EntryType::Regular);
    h
}

/// Bytes a member takes in the tar: its header(s) (a GNU long-name entry first for names of 100
/// bytes or more) and its padded data; measured by writing the headers, so it is exact.
fn member_bytes(name: &str, size: u64) -> Result<u64> {
    let mut b = tar::Builder::new(Vec::new());
    b.append_data(&mut header(0), name, std::io::empty())
        .map_err(|e| DatasetError::Invalid(format!("{name}: {e}")))?;
    let headers = b.get_ref().len() as u64;
    Ok(headers + padded(size))
}

fn write_member<W: Write>(w: &mut tar::Builder<W>, name: &str, data: &[u8]) -> Result<()> {
    w.append_data(&mut header(data.len() as u64), name, data)
        .map_err(|e| DatasetError::Io {
            path: PathBuf::from(name),
            source: e,
        })
}

/// The records of a finished (merged) dataset folder, in pair order.
fn finished_records(out: &Path) -> Result<Vec<Record>> {
    let path = out.join("manifest.jsonl");
    if !path.is_file() {
        let (m, _) = crate::manifest::metadata_files(out)?;
        return Err(DatasetError::Invalid(if m.is_empty() {
            format!(
                "{} has no manifest.jsonl: no pair was made yet",
                out.display()
            )
        } else {
            format!(
                "{} holds shard manifests ({}): `uwnr dataset merge` them first",
                out.display(),
                m.join(", ")
            )
        }));
    }
    let contents = read_manifest(&path)?;
    contents.refuse_unsafe_paths(&path)?;
    if let Some((line, reason)) = contents.bad_lines.first() {
        return Err(DatasetError::Corrupt {
            path,
            reason: format!("line {line}: {reason}"),
        });
    }
    if contents.torn_tail {
        return Err(DatasetError::Corrupt {
            path,
            reason: "ends in a torn line (an interrupted run): run the same command again".into(),
        });
    }
    let mut records: Vec<Record> = contents.records.into_iter().map(|(_, r)| r).collect();
    records.sort_by_key(|r| r.index);
    Ok(records)
}

/// Packs the pairs of the dataset folder `out` into shards of at most `shard_bytes` (a single
/// pair larger than that gets a shard of its own) in `dest` (default `out/webdataset`).
/// `progress(done, total)` counts pairs written.
pub fn export(
    out: &Path,
    dest: Option<&Path>,
    shard_bytes: u64,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<ExportReport> {
    let start = Instant::now();
    Settings::read(out)?;
    let records = finished_records(out)?;
    if records.is_empty() {
        return Err(DatasetError::Invalid(format!(
            "{} has no pairs to pack",
            out.display()
        )));
    }
    let dir = dest.map_or_else(|| out.join(WEBDATASET_DIR), Path::to_path_buf);
    std::fs::create_dir_all(&dir).map_err(io_err(&dir))?;

    // Plan: samples with their sizes, cut into shards.
    let mut samples = Vec::with_capacity(records.len());
    for r in &records {
        let key = key(r);
        let line = r.to_line().into_bytes();
        let mut bytes = member_bytes(&format!("{key}.json"), line.len() as u64)?;
        let mut members = vec![(format!("{key}.json"), Member::Bytes(line))];
        for f in r.files() {
            let p = out.join(f);
            let len = std::fs::metadata(&p).map_err(io_err(&p))?.len();
            let name = format!("{key}.{}", member_ext(f)?);
            bytes += member_bytes(&name, len)?;
            members.push((name, Member::File(p)));
        }
        samples.push(Sample {
            key,
            members,
            bytes,
        });
    }
    let mut shards: Vec<Vec<Sample>> = vec![Vec::new()];
    let mut used = 0;
    for s in samples {
        if used > 0 && used + s.bytes > shard_bytes.saturating_sub(2 * BLOCK) {
            shards.push(Vec::new());
            used = 0;
        }
        used += s.bytes;
        if let Some(v) = shards.last_mut() {
            v.push(s);
        }
    }
    let name = |i: usize| format!("uwnr-{i:06}.tar");

    let done = AtomicUsize::new(0);
    let total = records.len();
    let entries: Vec<ShardEntry> = shards
        .par_iter()
        .enumerate()
        .map(|(i, samples)| {
            let path = dir.join(name(i));
            let mut failure: Option<DatasetError> = None;
            let written = uwnr_core::io::write_atomic(&path, |w| {
                let mut w = tar::Builder::new(std::io::BufWriter::with_capacity(1 << 20, w));
                for s in samples {
                    for (member, source) in &s.members {
                        let data = match source {
                            Member::Bytes(b) => std::borrow::Cow::Borrowed(b.as_slice()),
                            Member::File(p) => match std::fs::read(p) {
                                Ok(b) => std::borrow::Cow::Owned(b),
                                Err(e) => {
                                    failure = Some(io_err(p)(e));
                                    return Err(std::io::Error::other("a pair file is unreadable"));
                                }
                            },
                        };
                        if let Err(e) = write_member(&mut w, member, &data) {
                            failure = Some(e);
                            return Err(std::io::Error::other("writing a member failed"));
                        }
                    }
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                }
                // The two zero blocks that end an archive.
                w.into_inner()?.flush()
            });
            if let Some(e) = failure {
                return Err(e);
            }
            written?;
            let bytes = std::fs::metadata(&path).map_err(io_err(&path))?.len();
            Ok(ShardEntry {
                file: name(i),
                pairs: samples.len(),
                bytes,
                first: samples.first().map(|s| s.key.clone()).unwrap_or_default(),
                last: samples.last().map(|s| s.key.clone()).unwrap_or_default(),
            })
        })
        .collect::<Result<_>>()?;

    // Shards of an earlier, larger export go; then the index, last.
    for entry in std::fs::read_dir(&dir).map_err(io_err(&dir))? {
        let p = entry.map_err(io_err(&dir))?.path();
        let stale = p
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| {
                n.strip_prefix("uwnr-")?
                    .strip_suffix(".tar")?
                    .parse::<usize>()
                    .ok()
            })
            .is_some_and(|i| i >= entries.len());
        if stale {
            std::fs::remove_file(&p).map_err(io_err(&p))?;
        }
    }
    let last = entries.len() - 1;
    let index = Index {
        format: INDEX_FORMAT.into(),
        pairs: total,
        pattern: if last == 0 {
            name(0)
        } else {
            format!("uwnr-{{{:06}..{last:06}}}.tar", 0)
        },
        shards: entries,
    };
    let text = serde_json::to_string_pretty(&index)
        .map_err(|e| DatasetError::Invalid(format!("cannot write the index: {e}")))?;
    uwnr_core::io::write_atomic_bytes(&dir.join(INDEX_FILE), format!("{text}\n").as_bytes())?;
    Ok(ExportReport {
        dir,
        bytes: index.shards.iter().map(|s| s.bytes).sum(),
        index,
        secs: start.elapsed().as_secs_f64(),
    })
}

/// The member names of a tar file, in order, with their sizes (long-name entries applied).
pub fn tar_members(path: &Path) -> Result<Vec<(String, u64)>> {
    let f = std::fs::File::open(path).map_err(io_err(path))?;
    let corrupt = |e: std::io::Error| DatasetError::Corrupt {
        path: path.to_path_buf(),
        reason: format!("not a readable tar: {e}"),
    };
    let mut archive = tar::Archive::new(std::io::BufReader::new(f));
    let mut out = Vec::new();
    for entry in archive.entries().map_err(corrupt)? {
        let entry = entry.map_err(corrupt)?;
        let name = entry
            .path()
            .map_err(corrupt)?
            .to_string_lossy()
            .into_owned();
        out.push((name, entry.header().size().map_err(corrupt)?));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("2G"), Ok(2 << 30));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("100000"), Ok(100_000));
        assert!(parse_size("1K").is_err());
        assert!(parse_size("lots").is_err());
    }

    #[test]
    fn headers_are_ustar_owned_by_nobody_at_time_zero() {
        let mut w = tar::Builder::new(Vec::new());
        write_member(&mut w, "00000001-a_0.underwater.png", &[7; 1234]).unwrap();
        let bytes = w.into_inner().unwrap();
        assert_eq!(bytes.len(), 512 + 1536 + 1024);
        let h = &bytes[..512];
        assert_eq!(&h[257..263], b"ustar\0");
        assert_eq!(&h[100..108], b"0000644\0");
        assert_eq!(&h[124..136], b"00000002322\0");
        assert_eq!(&h[136..148], b"00000000000\0");
        let stored = u32::from_str_radix(
            std::str::from_utf8(&h[148..155])
                .unwrap()
                .trim_end_matches('\0'),
            8,
        )
        .unwrap();
        let mut blank = h.to_vec();
        blank[148..156].copy_from_slice(b"        ");
        assert_eq!(stored, blank.iter().map(|&b| u32::from(b)).sum::<u32>());
    }

    #[test]
    fn long_names_read_back_and_sizes_are_exact() {
        let long = format!("00000001-{}.underwater.png", "n".repeat(120));
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.tar");
        let mut w = tar::Builder::new(Vec::new());
        write_member(&mut w, &long, b"hello").unwrap();
        write_member(&mut w, "short.json", b"{}").unwrap();
        let buf = w.into_inner().unwrap();
        assert_eq!(
            buf.len() as u64,
            member_bytes(&long, 5).unwrap() + member_bytes("short.json", 2).unwrap() + 1024
        );
        assert_eq!(member_bytes("short.json", 2).unwrap(), 1024);
        std::fs::write(&p, &buf).unwrap();
        assert_eq!(
            tar_members(&p).unwrap(),
            [(long, 5), ("short.json".to_string(), 2)]
        );
    }

    #[test]
    fn member_names_follow_the_folders() {
        assert_eq!(
            member_ext("underwater/a.b_0.png").unwrap(),
            "underwater.png"
        );
        assert_eq!(member_ext("labels/a_0.json").unwrap(), "labels.json");
        assert_eq!(member_ext("masks/a_0.png").unwrap(), "mask.png");
        assert!(member_ext("elsewhere/a_0.png").is_err());
    }
}
