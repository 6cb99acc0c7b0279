//! The files that describe a dataset folder:
//! - `dataset.json`, the settings and the inputs of the run ([`Settings`]), written once and
//!   compared on every resume, so a resumed run cannot mix two configurations;
//! - `manifest.jsonl` (`manifest.shard-I-of-N.jsonl` for a shard), one [`Record`] per complete
//!   pair, appended only after the pair's files are in place;
//! - `failed.jsonl` (`failed.shard-I-of-N.jsonl`), the items the last run could not make.

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, Result, io_err};
use crate::labels::info::LabelsInfo;
use crate::plan::Shard;
use uwnr_render::MethodRecord;

mod settings;
pub use settings::{PlannedPair, Settings, first_difference};

/// Name of the settings file.
pub const SETTINGS_FILE: &str = "dataset.json";
/// Format tag written into [`Settings::format`].
pub const FORMAT: &str = "uwnr-dataset/1";
/// Folder of the rendered underwater images.
pub const UNDERWATER_DIR: &str = "underwater";
/// Folder of the clean images exactly as rendered.
pub const CLEAN_DIR: &str = "clean";
/// Folder of the depth maps (16-bit grey PNG, bright = far).
pub const DEPTH_DIR: &str = "depth";
/// Folder of the light-field maps the network saw, at the pair's size.
pub const LIGHTFIELD_DIR: &str = "lightfield";
/// Folder of the pairs' label files (`NAME_k.json` for COCO, `NAME_k.txt` for YOLO).
pub const LABELS_DIR: &str = "labels";
/// Folder of the pairs' label masks.
pub const MASKS_DIR: &str = "masks";
/// Every folder that holds pair files.
pub const PAIR_DIRS: [&str; 6] = [
    UNDERWATER_DIR,
    CLEAN_DIR,
    DEPTH_DIR,
    LIGHTFIELD_DIR,
    LABELS_DIR,
    MASKS_DIR,
];

/// One complete pair, one line of the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// `NAME_k`.
    pub id: String,
    /// Global pair index, `clean_index * K + k`.
    pub index: u64,
    /// The clean image the pair was made from.
    pub clean_source: String,
    /// The reference it was rendered after (`null` for methods that use none).
    pub reference_source: Option<String>,
    /// The method.
    pub method: String,
    /// The method's parameters for this pair (sampled values included).
    pub params: MethodRecord,
    /// The pair's seed.
    pub seed: u64,
    /// Pair size in pixels.
    pub width: usize,
    pub height: usize,
    /// Files of the pair, relative to the dataset folder.
    pub underwater: String,
    pub clean: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lightfield: Option<String>,
    /// The pair's labels: `labels/NAME_k.json` (COCO) or `labels/NAME_k.txt` (YOLO).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<String>,
    /// The pair's label mask, `masks/NAME_k.png`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask: Option<String>,
    /// PSNR(underwater, clean) of the stored pair, dB (absent in folders made before it was
    /// recorded, and for identical sides).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strength_db: Option<f32>,
    /// The pair's labels: annotations dropped and fingerprints of the files written (absent
    /// without labels, and in folders made before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels_info: Option<LabelsInfo>,
}

impl Record {
    /// The pair's files, relative to the dataset folder.
    pub fn files(&self) -> impl Iterator<Item = &str> {
        self.images().chain(
            [self.labels.as_ref(), self.mask.as_ref()]
                .into_iter()
                .flatten()
                .map(String::as_str),
        )
    }

    /// The pair's images (what decodes as a picture at the pair's size): underwater, clean,
    /// depth and light field.
    pub fn images(&self) -> impl Iterator<Item = &str> {
        [
            Some(&self.underwater),
            Some(&self.clean),
            self.depth.as_ref(),
            self.lightfield.as_ref(),
        ]
        .into_iter()
        .flatten()
        .map(String::as_str)
    }

    /// One manifest line, newline included.
    #[must_use]
    pub fn to_line(&self) -> String {
        // A struct of strings, numbers and JSON values always serialises.
        let mut s = serde_json::to_string(self).unwrap_or_default();
        s.push('\n');
        s
    }
}

/// The manifest file of a run: `manifest.jsonl`, or `manifest.shard-I-of-N.jsonl`.
#[must_use]
pub fn manifest_name(shard: Option<Shard>) -> String {
    match shard {
        Some(s) => format!("manifest.shard-{}.jsonl", s.tag()),
        None => "manifest.jsonl".into(),
    }
}

/// The failure list of a run: `failed.jsonl`, or `failed.shard-I-of-N.jsonl`.
#[must_use]
pub fn failed_name(shard: Option<Shard>) -> String {
    match shard {
        Some(s) => format!("failed.shard-{}.jsonl", s.tag()),
        None => "failed.jsonl".into(),
    }
}

/// Parses `manifest.shard-I-of-N.jsonl` (or `failed.shard-...`) names.
#[must_use]
pub fn shard_of_file(name: &str, prefix: &str) -> Option<Shard> {
    let rest = name.strip_prefix(prefix)?.strip_prefix(".shard-")?;
    let rest = rest.strip_suffix(".jsonl")?;
    let (i, n) = rest.split_once("-of-")?;
    let (index, count) = (i.parse().ok()?, n.parse().ok()?);
    (index < count).then_some(Shard { index, count })
}

/// The manifests and failure lists of a dataset folder: `manifest.jsonl` and any
/// `manifest.shard-I-of-N.jsonl` (likewise `failed*.jsonl`).
pub fn metadata_files(out: &Path) -> Result<(Vec<String>, Vec<String>)> {
    let mut manifests = Vec::new();
    let mut failed = Vec::new();
    for entry in std::fs::read_dir(out).map_err(io_err(out))? {
        let name = entry
            .map_err(io_err(out))?
            .file_name()
            .to_string_lossy()
            .into_owned();
        if name == "manifest.jsonl" || shard_of_file(&name, "manifest").is_some() {
            manifests.push(name);
        } else if name == "failed.jsonl" || shard_of_file(&name, "failed").is_some() {
            failed.push(name);
        }
    }
    manifests.sort();
    failed.sort();
    Ok((manifests, failed))
}

/// A manifest as read from disk.
#[derive(Debug, Default)]
pub struct ManifestContents {
    /// Lines that parsed, in file order, with their 1-based line numbers.
    pub records: Vec<(usize, Record)>,
    /// Lines that did not parse: line number and reason.
    pub bad_lines: Vec<(usize, String)>,
    /// The file ended in the middle of a line (a run was killed while appending).
    pub torn_tail: bool,
    /// Lines whose record names a file outside the dataset folder (an absolute path or one with
    /// `..`): line number and the path. No crash writes such a line; it is refused, never read.
    pub unsafe_paths: Vec<(usize, String)>,
}

impl ManifestContents {
    /// Refuses the manifest at `path` if any line names a file outside the dataset folder.
    pub fn refuse_unsafe_paths(&self, path: &Path) -> Result<()> {
        match self.unsafe_paths.first() {
            Some((line, file)) => Err(DatasetError::Corrupt {
                path: path.to_path_buf(),
                reason: unsafe_path_reason(*line, file),
            }),
            None => Ok(()),
        }
    }
}

/// The one-line reason for a manifest line that names a file outside the dataset folder.
#[must_use]
pub fn unsafe_path_reason(line: usize, file: &str) -> String {
    format!("line {line}: file path {file:?} is absolute or leaves the dataset folder")
}

/// Reads a manifest; a missing file reads as empty.
pub fn read_manifest(path: &Path) -> Result<ManifestContents> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(ManifestContents::default());
        }
        Err(e) => return Err(io_err(path)(e)),
    };
    let mut out = ManifestContents::default();
    let mut rest: &[u8] = &bytes;
    let mut line_no = 0;
    while !rest.is_empty() {
        line_no += 1;
        let (line, next) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], &rest[i + 1..]),
            None => {
                out.torn_tail = true;
                break;
            }
        };
        rest = next;
        if line.iter().all(u8::is_ascii_whitespace) {
            out.bad_lines.push((line_no, "empty line".into()));
            continue;
        }
        match serde_json::from_slice::<Record>(line) {
            Ok(r) => {
                let outside = r
                    .files()
                    .find(|f| !uwnr_core::io::stays_inside(Path::new(f)))
                    .map(str::to_string);
                match outside {
                    Some(f) => out.unsafe_paths.push((line_no, f)),
                    None => out.records.push((line_no, r)),
                }
            }
            Err(e) => out
                .bad_lines
                .push((line_no, format!("not a pair record: {e}"))),
        }
    }
    Ok(out)
}

/// Writes `records` as a manifest, atomically, in index order.
pub fn write_manifest(path: &Path, records: &mut [Record]) -> Result<()> {
    records.sort_by_key(|r| r.index);
    let mut text = String::new();
    for r in records.iter() {
        text.push_str(&r.to_line());
    }
    uwnr_core::io::write_atomic_bytes(path, text.as_bytes())?;
    Ok(())
}

/// Appends complete records to a manifest, one whole line per `write` call, flushed at once,
/// so a killed run leaves at most one torn last line, which the next run drops.
pub struct ManifestWriter {
    file: std::fs::File,
    path: PathBuf,
}

impl ManifestWriter {
    /// Opens `path` for appending (created if missing).
    pub fn open(path: &Path) -> Result<Self> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(io_err(path))?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
        })
    }

    /// Appends one record.
    pub fn append(&mut self, record: &Record) -> Result<()> {
        self.file
            .write_all(record.to_line().as_bytes())
            .and_then(|()| self.file.flush())
            .map_err(io_err(&self.path))
    }

    /// Flushes the file to disk.
    pub fn sync(&mut self) -> Result<()> {
        self.file.sync_all().map_err(io_err(&self.path))
    }
}

/// One item a run could not make.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Failure {
    /// The clean image or reference at fault.
    pub source: String,
    /// The pairs it cost (empty for a reference that was skipped in favour of another).
    pub ids: Vec<String>,
    /// One-line reason.
    pub reason: String,
}

/// Writes the failure list (removes the file when there are none).
pub fn write_failures(path: &Path, failures: &[Failure]) -> Result<()> {
    if failures.is_empty() {
        return match std::fs::remove_file(path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(io_err(path)(e)),
        };
    }
    let mut text = String::new();
    for f in failures {
        text.push_str(&serde_json::to_string(f).unwrap_or_default());
        text.push('\n');
    }
    uwnr_core::io::write_atomic_bytes(path, text.as_bytes())?;
    Ok(())
}

/// Reads a failure list; a missing file reads as empty.
pub fn read_failures(path: &Path) -> Result<Vec<Failure>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io_err(path)(e)),
    };
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            serde_json::from_str(l).map_err(|e| DatasetError::Corrupt {
                path: path.to_path_buf(),
                reason: format!("not a failure record: {e}"),
            })
        })
        .collect()
}

/// Ids of the pairs that failures account for.
#[must_use]
pub fn failed_ids(failures: &[Failure]) -> HashSet<String> {
    failures
        .iter()
        .flat_map(|f| f.ids.iter().cloned())
        .collect()
}

/// Whether `name` is a temporary file left by [`uwnr_core::io::write_atomic`]
/// (`.NAME.PID-N.tmp`), and the name it was going to become.
#[must_use]
pub fn temp_target(name: &str) -> Option<&str> {
    let inner = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (target, _pid_n) = inner.rsplit_once('.')?;
    Some(target)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(id: &str, index: u64) -> Record {
        Record {
            id: id.into(),
            index,
            clean_source: "c.jpg".into(),
            reference_source: Some("r.jpg".into()),
            method: "reinhard".into(),
            params: serde_json::from_str(
                r#"{"match_std":true,"method":"reinhard","reference_mean":[0.1,0.2,0.3],
                    "reference_std":[0.01,0.02,0.03],"space":"lalphabeta"}"#,
            )
            .unwrap(),
            seed: 1,
            width: 8,
            height: 6,
            underwater: format!("underwater/{id}.png"),
            clean: format!("clean/{id}.png"),
            depth: None,
            lightfield: None,
            labels: None,
            mask: None,
            strength_db: None,
            labels_info: None,
        }
    }

    /// A manifest read back (resume, `merge`) and written again keeps every number's digits: the
    /// merged folder of a sharded run is byte-identical to the unsharded one. These values, from
    /// a bundled-model dataset, came back one unit in the last place off without serde_json's
    /// `float_roundtrip`.
    #[test]
    fn numbers_survive_a_read_and_a_write_unchanged() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("manifest.jsonl");
        let mut r = record("a_0", 0);
        r.params = serde_json::from_str(
            r#"{"depth":{"scale":"relative","scene_m":5.0,"trust":1.0},
                "strength":{"renders":2,"scale":0.9729539752006531,"target":"t",
                            "target_db":12.820460319519043},
                "water":{"gain":[0.5,0.6,0.7],
                         "offset":[0.20839132368564606,0.24237442016601562,0.9583044648170471]},
                "weights":"bundled model"}"#,
        )
        .unwrap();
        assert!(matches!(r.params, MethodRecord::Uwnr(_)), "{:?}", r.params);
        let line = r.to_line();
        std::fs::write(&path, &line).unwrap();
        let mut again: Vec<Record> = read_manifest(&path)
            .unwrap()
            .records
            .into_iter()
            .map(|(_, r)| r)
            .collect();
        write_manifest(&path, &mut again).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), line);
        assert!(line.contains("0.9729539752006531,"), "{line}");
    }

    /// Each method's record is typed on the way in, and written out as it was read: the keys in
    /// sorted order, the tags where they were. A record of another shape (an earlier version's)
    /// is kept as read.
    #[test]
    fn records_read_typed_and_write_out_unchanged() {
        let lines = [
            r#"{"beta":[0.1,0.2,0.3],"depth_scale_m":5.0,"method":"haze","veil":[0.1,0.4,0.5]}"#,
            r#"{"backlight":[0.10000000149011612,0.20000000298023224,0.30000001192092896],"beta":[0.5,0.25,0.125],"gain":1.5,"vignette":[-0.10000000149011612,0.0,0.0],"weights":"g.safetensors","z_seed":7}"#,
            r#"{"b_inf_rgb":[0.1,0.4,0.5],"beta_b_per_m_rgb":[0.1,0.1,0.1],"beta_d_per_m_rgb":[0.3,0.1,0.05],"coefficients":{"mode":"given"},"depth_scale_m":4.0,"forward_scatter":0.3,"medium":0.1,"method":"revised","seed":3}"#,
            r#"{"background_depth_m":8.0,"background_gain":0.8,"background_rgb":[0.1,0.5,0.6],"depth_scale_m":5.0,"illuminate_scene":false,"method":"jerlov","seed":2,"transmittance_per_m_rgb":[0.805,0.961,0.982],"water_type":"I"}"#,
        ];
        for line in lines {
            let typed: MethodRecord = serde_json::from_str(line).unwrap();
            assert!(!matches!(typed, MethodRecord::Earlier(_)), "{line}");
            assert_eq!(serde_json::to_string(&typed).unwrap(), line);
        }
        let earlier = r#"{"lightfield":"old","weights":"w"}"#;
        let kept: MethodRecord = serde_json::from_str(earlier).unwrap();
        assert!(matches!(kept, MethodRecord::Earlier(_)));
        assert_eq!(serde_json::to_string(&kept).unwrap(), earlier);
    }

    #[test]
    fn torn_tail_and_bad_lines_are_reported() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("manifest.jsonl");
        let mut text = record("a_0", 0).to_line();
        text.push_str("garbage\n");
        text.push_str(&record("a_1", 1).to_line());
        text.push_str("{\"id\": \"a_2\", \"ind");
        std::fs::write(&path, text).unwrap();
        let m = read_manifest(&path).unwrap();
        assert_eq!(m.records.len(), 2);
        assert_eq!(m.records[1].0, 3);
        assert_eq!(m.bad_lines.len(), 1);
        assert_eq!(m.bad_lines[0].0, 2);
        assert!(m.torn_tail);
    }

    #[test]
    fn records_naming_files_outside_the_folder_are_set_apart() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("manifest.jsonl");
        let mut text = record("a_0", 0).to_line();
        let mut escape = record("a_1", 1);
        escape.underwater = "../secret.txt".into();
        text.push_str(&escape.to_line());
        let mut absolute = record("a_2", 2);
        absolute.depth = Some("/etc/passwd".into());
        text.push_str(&absolute.to_line());
        std::fs::write(&path, text).unwrap();
        let m = read_manifest(&path).unwrap();
        assert_eq!(m.records.len(), 1);
        assert_eq!(
            m.unsafe_paths,
            [
                (2, "../secret.txt".to_string()),
                (3, "/etc/passwd".to_string())
            ]
        );
        let err = m.refuse_unsafe_paths(&path).unwrap_err().to_string();
        assert!(
            err.contains("manifest.jsonl") && err.contains("line 2"),
            "{err}"
        );
        assert_eq!(err.lines().count(), 1);
    }

    /// A value whose serialisation fails (as a map with non-string keys would).
    struct Unserialisable;

    impl Serialize for Unserialisable {
        fn serialize<S: serde::Serializer>(&self, _: S) -> std::result::Result<S::Ok, S::Error> {
            Err(serde::ser::Error::custom("no JSON form"))
        }
    }

    #[test]
    fn settings_that_cannot_be_serialised_never_compare_equal() {
        let err = first_difference(&Unserialisable, &Unserialisable).unwrap_err();
        assert!(err.to_string().contains("no JSON form"), "{err}");
        // Fields present on one side only are differences too.
        let a = serde_json::json!({"seed": 1});
        let b = serde_json::json!({"seed": 1, "extra": true});
        assert_eq!(first_difference(&a, &b).unwrap().unwrap().0, "extra");
        assert_eq!(first_difference(&a, &a).unwrap(), None);
        assert!(first_difference(&1, &2).unwrap().is_some());
    }

    #[test]
    fn shard_file_names_round_trip() {
        let s = Shard { index: 2, count: 5 };
        assert_eq!(shard_of_file(&manifest_name(Some(s)), "manifest"), Some(s));
        assert_eq!(shard_of_file(&failed_name(Some(s)), "failed"), Some(s));
        assert_eq!(shard_of_file("manifest.jsonl", "manifest"), None);
    }

    #[test]
    fn temp_names_map_to_their_target() {
        assert_eq!(temp_target(".a_0.png.1234-7.tmp"), Some("a_0.png"));
        assert_eq!(temp_target("a_0.png"), None);
    }
}
