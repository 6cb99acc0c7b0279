//! Files on disk for weights: the atomic write of a finished file, and the temporary file a
//! PyTorch checkpoint given as bytes is read from (its reader needs a seekable file).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::error::{ModelError, Result};

/// Writes `bytes` to `path` by uwnr-core's atomic, durable rule ([`uwnr_core::io::write_atomic`]:
/// a synced temporary file in the same directory renamed into place).
pub(super) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    uwnr_core::io::write_atomic_bytes(path, bytes).map_err(|e| match e {
        uwnr_core::CoreError::Io { path, source } => ModelError::Io { path, source },
        other => ModelError::Core(other),
    })
}

/// A temporary file removed on drop (for checkpoints given as bytes).
pub(super) struct TempFile {
    pub path: PathBuf,
}

impl TempFile {
    pub fn write(bytes: &[u8]) -> Result<Self> {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path =
            std::env::temp_dir().join(format!("uwnr-weights-{}-{n}.pth.tmp", std::process::id()));
        let file = Self { path };
        let mut f = std::fs::File::create(&file.path).map_err(|source| ModelError::Io {
            path: file.path.clone(),
            source,
        })?;
        f.write_all(bytes).map_err(|source| ModelError::Io {
            path: file.path.clone(),
            source,
        })?;
        Ok(file)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
