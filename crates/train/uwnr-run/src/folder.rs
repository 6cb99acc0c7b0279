//! The run folder: its file names, when it counts as holding a run, claiming it, and the
//! run's config kept in it (refused resumes name the fields that changed).
//!
//! ```text
//! config.json          the run's config (a resumed run must be given the same)
//! data-report.txt      pairs used, files skipped, images upscaled/padded/resized
//! metrics.csv          step, epoch, lr, each loss term, secs_per_step (mean per log window)
//! val.csv              step, epoch, PSNR, SSIM, secs of each validation
//! curves.png           loss terms (log) and validation PSNR against the step
//! val/step-NNNNNNN.png contact sheets of the validation pairs
//! checkpoints/last/    model + optimiser + state (resume from here)
//! checkpoints/best/    the network with the best validation PSNR
//! ```

use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::checkpoint::{CHECKPOINTS_DIR, LAST, find_checkpoint};
use crate::error::{Result, RunError};

/// Name of the config file in the run folder.
pub const CONFIG_FILE: &str = "config.json";
/// Name of the data report in the run folder.
pub const DATA_REPORT_FILE: &str = "data-report.txt";
/// Name of the loss log.
pub const METRICS_FILE: &str = "metrics.csv";
/// Name of the validation log.
pub const VAL_FILE: &str = "val.csv";
/// Name of the curve picture.
pub const CURVES_FILE: &str = "curves.png";
/// Folder of the validation contact sheets.
pub const VAL_DIR: &str = "val";

/// Whether the folder `run` holds a training run. A run begins with its first checkpoint: a
/// folder with none (a first session that failed or was killed before it) is not one, so it may
/// be started again and cannot be resumed.
#[must_use]
pub fn holds_run(run: &Path) -> bool {
    find_checkpoint(&run.join(CHECKPOINTS_DIR).join(LAST)).is_some()
}

/// Checks the run folder before anything is loaded: a fresh start refuses a folder that holds a
/// run ([`RunError::RunExists`]), a resume needs one. Nothing is written: the folder is claimed
/// ([`claim_run_folder`]) only once the data has loaded, so a failed start leaves nothing that
/// would block the next one.
pub fn check_run_folder(run: &Path, resume: bool) -> Result<()> {
    match (resume, holds_run(run)) {
        (false, true) => Err(RunError::RunExists {
            dir: run.to_path_buf(),
        }),
        (true, false) => Err(RunError::Checkpoint {
            path: run.join(CHECKPOINTS_DIR).join(LAST),
            reason: "no checkpoint to resume from (the run never wrote one: start it again \
                     without --resume)"
                .into(),
        }),
        _ => Ok(()),
    }
}

/// Creates the run folder and writes its `config.json`; called on a fresh start once the data
/// has loaded ([`check_run_folder`] has refused a folder holding a run, so what it replaces is
/// what a failed start left).
pub fn claim_run_folder(run: &Path, config_json: &str) -> Result<()> {
    std::fs::create_dir_all(run).map_err(RunError::io(run))?;
    write_text(&run.join(CONFIG_FILE), config_json)
}

/// Writes a text file atomically.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    uwnr_core::io::write_atomic(path, |out| out.write_all(text.as_bytes()))?;
    Ok(())
}

/// A run's config as kept in its folder: JSON, compared field by field on resume.
pub trait RunConfig: Serialize + DeserializeOwned + PartialEq {
    /// Reads a config from JSON (fields not given keep their defaults where the type says so;
    /// unknown fields are refused where it says so).
    fn from_json_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(RunError::io(path))?;
        serde_json::from_str(&text).map_err(|e| RunError::ConfigFile {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// Pretty JSON of the config.
    fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(self).map_err(|e| RunError::ConfigFile {
            path: CONFIG_FILE.into(),
            reason: format!("cannot be written as JSON: {e}"),
        })
    }
}

impl<T: Serialize + DeserializeOwned + PartialEq> RunConfig for T {}

/// On resume, the run's `config.json` must equal `cfg`; the error names the changed fields.
pub fn check_saved_config<C: RunConfig>(cfg: &C, run: &Path) -> Result<()> {
    let path = run.join(CONFIG_FILE);
    let saved = C::from_json_file(&path)?;
    let fields = changed_fields(&saved, cfg)?;
    if fields.is_empty() && &saved == cfg {
        return Ok(());
    }
    Err(RunError::ConfigChanged {
        path,
        fields: if fields.is_empty() {
            vec!["config".into()]
        } else {
            fields
        },
    })
}

/// Reads the `config.json` at `path` as a `C` and checks that `C` writes it back the same: the
/// same keys and values (their order aside), so that what an earlier version wrote still reads
/// as the run it was. The error names the keys that would be written differently. The trainers'
/// tests run it on files their earlier versions wrote.
pub fn read_config_unchanged<C: RunConfig>(path: &Path) -> Result<C> {
    let cfg = C::from_json_file(path)?;
    let text = std::fs::read_to_string(path).map_err(RunError::io(path))?;
    let bad = |reason: String| RunError::ConfigFile {
        path: path.to_path_buf(),
        reason,
    };
    // Both sides from JSON text: an f32 written as text reads back as the f64 of its shortest
    // decimal, not as the f32's exact value that `serde_json::to_value` would give.
    let value = |text: &str| serde_json::from_str::<serde_json::Value>(text);
    let before = value(&text).map_err(|e| bad(e.to_string()))?;
    let now = value(&cfg.to_json()?).map_err(|e| bad(e.to_string()))?;
    let fields = changed_fields(&before, &now)?;
    if fields.is_empty() {
        Ok(cfg)
    } else {
        Err(bad(format!(
            "is not written back the same: {} would change",
            fields.join(", ")
        )))
    }
}

/// The dotted names of the fields that differ between two configs (e.g. `model.width`). A
/// config that cannot be serialised is an error, never "no difference".
pub fn changed_fields<C: Serialize>(a: &C, b: &C) -> Result<Vec<String>> {
    fn walk(prefix: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
        match (a, b) {
            (serde_json::Value::Object(x), serde_json::Value::Object(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                for k in keys {
                    let name = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    let null = serde_json::Value::Null;
                    walk(
                        &name,
                        x.get(k).unwrap_or(&null),
                        y.get(k).unwrap_or(&null),
                        out,
                    );
                }
            }
            _ if a != b => out.push(if prefix.is_empty() {
                "config".into()
            } else {
                prefix.to_string()
            }),
            _ => {}
        }
    }
    let value = |c: &C| {
        serde_json::to_value(c).map_err(|e| RunError::ConfigFile {
            path: CONFIG_FILE.into(),
            reason: format!("cannot be compared: {e}"),
        })
    };
    let mut out = Vec::new();
    walk("", &value(a)?, &value(b)?, &mut out);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    struct Inner {
        width: usize,
    }

    #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
    struct Cfg {
        epochs: usize,
        model: Inner,
        lr: f64,
    }

    #[test]
    fn changed_fields_are_named_with_their_path() {
        let a = Cfg {
            epochs: 1,
            model: Inner { width: 8 },
            lr: 0.1,
        };
        let b = Cfg {
            epochs: 3,
            model: Inner { width: 16 },
            lr: 0.1,
        };
        assert_eq!(changed_fields(&a, &b).unwrap(), ["epochs", "model.width"]);
        assert!(changed_fields(&a, &a).unwrap().is_empty());
    }

    #[test]
    fn a_config_that_cannot_be_serialised_is_never_equal() {
        // serde_json refuses maps with non-string keys.
        let mut a = std::collections::BTreeMap::new();
        a.insert((1, 2), 3);
        assert!(changed_fields(&a, &a).is_err());
    }

    #[test]
    fn a_config_file_reads_back_unchanged_or_names_what_would_change() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(CONFIG_FILE);
        let text = r#"{"lr": 0.1, "model": {"width": 8}, "epochs": 1}"#;
        std::fs::write(&path, text).unwrap();
        let read: Cfg = read_config_unchanged(&path).unwrap();
        assert_eq!(read.model.width, 8);
        // A key the type does not write back (here: ignored on reading) is named.
        std::fs::write(
            &path,
            r#"{"lr": 0.1, "model": {"width": 8, "depth": 2}, "epochs": 1}"#,
        )
        .unwrap();
        let err = read_config_unchanged::<Cfg>(&path).unwrap_err();
        assert!(err.to_string().contains("model.depth"), "{err}");
    }

    #[test]
    fn resume_refuses_another_config_by_field() {
        let dir = tempfile::tempdir().unwrap();
        let a = Cfg {
            epochs: 1,
            model: Inner { width: 8 },
            lr: 0.1,
        };
        claim_run_folder(dir.path(), &a.to_json().unwrap()).unwrap();
        check_saved_config(&a, dir.path()).unwrap();
        let b = Cfg { lr: 0.2, ..a };
        match check_saved_config(&b, dir.path()) {
            Err(RunError::ConfigChanged { fields, .. }) => assert_eq!(fields, ["lr"]),
            other => panic!("{other:?}"),
        }
    }
}
