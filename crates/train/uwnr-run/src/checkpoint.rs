//! Checkpoints of a training run, written atomically, for exact resume.
//!
//! A checkpoint is a directory:
//! - `model.bpk`: the network in burn's burnpack format, full precision, with burn's parameter
//!   ids (the optimiser state is keyed by them);
//! - `optimizer.bpk`: the optimiser state (moments and step counts per parameter);
//! - `state.json`: [`RunState`] (step, epoch, position in the epoch, best score...);
//! - the network's own weights file, written by its task (e.g. `generator.safetensors` under the
//!   authors' key names, the file `uwnr render --weights` takes).
//!
//! The directory is written as `NAME.tmp` and renamed into place (the previous one is moved to
//! `NAME.old` for the instant between the two renames and then removed), so a crash or Ctrl-C
//! at any moment leaves a complete checkpoint under `NAME` or `NAME.old`;
//! [`find_checkpoint`] looks at both. The data order and augmentation are pure functions of
//! `(seed, epoch, position)`, so `(epoch, batch_in_epoch)` is the whole state of the sampler.

use std::path::{Path, PathBuf};

use burn::optim::ModuleOptimizer;
use burn::store::{BurnpackStore, ModuleSnapshot};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RunError};

/// Folder of the checkpoints inside the run folder.
pub const CHECKPOINTS_DIR: &str = "checkpoints";
/// The latest checkpoint (for resuming).
pub const LAST: &str = "last";
/// The checkpoint with the best validation PSNR.
pub const BEST: &str = "best";
/// Model file of a checkpoint.
pub const MODEL_FILE: &str = "model.bpk";
/// Optimiser file of a checkpoint.
pub const OPTIMIZER_FILE: &str = "optimizer.bpk";
/// State file of a checkpoint.
pub const STATE_FILE: &str = "state.json";
/// Version of [`RunState`]'s layout.
pub const STATE_VERSION: u32 = 1;
/// Suffix of a checkpoint being written.
const TMP_SUFFIX: &str = "tmp";
/// Suffix of the checkpoint being replaced.
const OLD_SUFFIX: &str = "old";

/// Where a run stands.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// [`STATE_VERSION`].
    pub version: u32,
    /// Optimisation steps done.
    pub step: usize,
    /// Epoch of the next batch (0-based).
    pub epoch: usize,
    /// Index of the next batch within that epoch.
    pub batch_in_epoch: usize,
    /// Batches per epoch (checked on resume: the data must not have changed).
    pub steps_per_epoch: usize,
    /// Training pairs (checked on resume).
    pub pairs: usize,
    /// Seed of the run.
    pub seed: u64,
    /// Best validation PSNR so far and the step it was reached at.
    pub best: Option<(f64, usize)>,
    /// Wall-clock seconds spent training, over all sessions.
    pub train_secs: f64,
}

impl RunState {
    /// The state of a run that has not taken a step.
    #[must_use]
    pub fn start(steps_per_epoch: usize, pairs: usize, seed: u64) -> Self {
        Self {
            version: STATE_VERSION,
            step: 0,
            epoch: 0,
            batch_in_epoch: 0,
            steps_per_epoch,
            pairs,
            seed,
            best: None,
            train_secs: 0.0,
        }
    }

    /// Checks that the checkpoint in `dir` holding this state can continue with the data and
    /// seed of this session (a resumed run must see the same batches).
    pub fn check_resumable(
        &self,
        dir: &Path,
        steps_per_epoch: usize,
        pairs: usize,
        seed: u64,
    ) -> Result<()> {
        if self.steps_per_epoch != steps_per_epoch || self.pairs != pairs || self.seed != seed {
            return Err(RunError::Checkpoint {
                path: dir.to_path_buf(),
                reason: format!(
                    "written for {} pairs / {} steps per epoch / seed {}, the data now gives {} / {} / {}",
                    self.pairs, self.steps_per_epoch, self.seed, pairs, steps_per_epoch, seed
                ),
            });
        }
        Ok(())
    }
}

/// Writes a checkpoint directory atomically: the module (and `optimizer`, omitted for
/// export-only checkpoints such as the best model), `state`, and what `export(tmp_dir)` writes
/// into the directory being assembled (the network's own weights file).
pub fn save_checkpoint<M: ModuleSnapshot, E: From<RunError>>(
    dir: &Path,
    model: &M,
    optimizer: Option<&ModuleOptimizer>,
    state: &RunState,
    export: impl FnOnce(&Path) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let tmp = sibling(dir, TMP_SUFFIX);
    let old = sibling(dir, OLD_SUFFIX);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(RunError::io(&tmp))?;
    }
    std::fs::create_dir_all(&tmp).map_err(RunError::io(&tmp))?;
    let ck_err = |reason: String| RunError::Checkpoint {
        path: dir.to_path_buf(),
        reason,
    };
    let mut store = BurnpackStore::from_file(tmp.join(MODEL_FILE)).overwrite(true);
    model
        .save_into(&mut store)
        .map_err(|e| ck_err(format!("writing the model: {e}")))?;
    if let Some(opt) = optimizer {
        opt.save(tmp.join(OPTIMIZER_FILE))
            .map_err(|e| ck_err(format!("writing the optimiser state: {e}")))?;
    }
    export(&tmp)?;
    let json = serde_json::to_string_pretty(state).map_err(|e| ck_err(e.to_string()))?;
    let state_path = tmp.join(STATE_FILE);
    std::fs::write(&state_path, json).map_err(RunError::io(&state_path))?;
    sync_dir(&tmp);
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(RunError::io(&old))?;
    }
    if dir.exists() {
        std::fs::rename(dir, &old).map_err(RunError::io(dir))?;
    }
    std::fs::rename(&tmp, dir).map_err(RunError::io(dir))?;
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(RunError::io(&old))?;
    }
    if let Some(parent) = dir.parent() {
        sync_dir(parent);
    }
    Ok(())
}

/// The complete checkpoint named `dir`: `dir` itself, or `dir.old` when a crash happened
/// between the two renames of [`save_checkpoint`]. `None` when there is none.
#[must_use]
pub fn find_checkpoint(dir: &Path) -> Option<PathBuf> {
    [dir.to_path_buf(), sibling(dir, OLD_SUFFIX)]
        .into_iter()
        .find(|d| d.join(STATE_FILE).is_file() && d.join(MODEL_FILE).is_file())
}

/// Reads a checkpoint's state.
pub fn read_state(dir: &Path) -> Result<RunState> {
    let path = dir.join(STATE_FILE);
    let text = std::fs::read_to_string(&path).map_err(RunError::io(&path))?;
    let state: RunState = serde_json::from_str(&text).map_err(|e| RunError::Checkpoint {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    if state.version != STATE_VERSION {
        return Err(RunError::Checkpoint {
            path,
            reason: format!(
                "state version {} (this build reads {STATE_VERSION})",
                state.version
            ),
        });
    }
    Ok(state)
}

/// Loads a checkpoint for training: `model` (freshly built with the run's config on the
/// training device) is overwritten with the stored tensors and parameter ids, the optimiser
/// state is read into `optimizer`, and the run state is returned beside them.
pub fn load_checkpoint<M: ModuleSnapshot>(
    dir: &Path,
    mut model: M,
    optimizer: ModuleOptimizer,
) -> Result<(M, ModuleOptimizer, RunState)> {
    let state = read_state(dir)?;
    let ck_err = |reason: String| RunError::Checkpoint {
        path: dir.to_path_buf(),
        reason,
    };
    let mut store = BurnpackStore::from_file(dir.join(MODEL_FILE));
    model
        .load_from(&mut store)
        .map_err(|e| ck_err(format!("reading the model: {e}")))?;
    let opt_path = dir.join(OPTIMIZER_FILE);
    if !opt_path.is_file() {
        return Err(ck_err(format!("{OPTIMIZER_FILE} is missing")));
    }
    let optimizer = optimizer
        .load(&opt_path)
        .map_err(|e| ck_err(format!("reading the optimiser state: {e}")))?;
    Ok((model, optimizer, state))
}

fn sibling(dir: &Path, suffix: &str) -> PathBuf {
    let mut name = dir
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".");
    name.push(suffix);
    dir.with_file_name(name)
}

/// Flushes a directory's files and entries to disk where the platform allows it (best effort:
/// a failure only weakens the crash guarantee, it does not corrupt anything).
fn sync_dir(dir: &Path) {
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            if let Ok(f) = std::fs::File::open(e.path())
                && e.path().is_file()
            {
                let _ = f.sync_all();
            }
        }
    }
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}
