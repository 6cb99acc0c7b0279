//! Images dropped into the page: checked that they decode within the limits and the memory
//! budget, then kept in the server's private folder (0700, files 0600), the last
//! [`KEPT_UPLOADS`] of them.

use std::path::{Path, PathBuf};

use serde_json::{Value, json};
use uwnr_core::io::{check_decodes, probe_memory};

use crate::engine::{DECODE_WAIT, Engine, lock, reason};
use crate::error::{Result, ServeError};

/// Dropped images kept on disk (older ones are deleted).
pub const KEPT_UPLOADS: usize = 16;

/// An image dropped into the page, kept as a file in the server's private temporary folder.
#[derive(Clone, Debug)]
pub(crate) struct Upload {
    pub path: PathBuf,
    /// The name the user's file had (what commands and messages name).
    pub name: String,
    pub depth: bool,
}

impl Engine {
    pub(crate) fn upload(&self, id: &str) -> Result<Upload> {
        lock(&self.uploads)
            .1
            .iter()
            .find(|(k, _)| k == id)
            .map(|(_, u)| u.clone())
            .ok_or_else(|| {
                ServeError::Missing(format!(
                    "no dropped image {id:?} (the server keeps the last {KEPT_UPLOADS}); drop it again"
                ))
            })
    }

    /// A dropped file's bytes (a file the server kept: its loss is the server's failure).
    pub(crate) fn upload_bytes(&self, u: &Upload) -> Result<Vec<u8>> {
        std::fs::read(&u.path).map_err(|e| ServeError::ServerFile {
            what: format!("dropped image {}", u.name),
            reason: format!("the server lost its copy ({}); drop it again", e.kind()),
        })
    }

    /// Stores a dropped image, readable by this user only, after checking that it decodes
    /// within the limits (decoded as stored, within the memory budget).
    pub fn store_upload(&self, bytes: &[u8], name: &str, depth: bool) -> Result<Value> {
        let name: String = Path::new(name)
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "dropped.png".into());
        let bad = |reason: String| ServeError::BadImage {
            what: name.clone(),
            reason,
        };
        let (w, h, bpp) = probe_memory(bytes).map_err(|e| bad(reason(&e)))?;
        let pixels = u64::from(w) * u64::from(h);
        let _lease = if pixels <= self.limits.max_pixels && w.max(h) <= self.limits.max_dimension {
            Some(self.lease(2 * pixels * bpp, &name, DECODE_WAIT)?)
        } else {
            None
        };
        let (width, height) = check_decodes(bytes, &self.limits).map_err(|e| bad(reason(&e)))?;
        let mut g = lock(&self.uploads);
        let id = format!("u{}", g.0);
        g.0 += 1;
        let ext = Path::new(&name)
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .filter(|e| uwnr_core::io::IMAGE_EXTENSIONS.contains(&e.as_str()))
            .unwrap_or_else(|| "png".into());
        let path = self.upload_dir.path().join(format!("{id}.{ext}"));
        write_private(&path, bytes).map_err(ServeError::io("saving a dropped image"))?;
        g.1.push_back((
            id.clone(),
            Upload {
                path,
                name: name.clone(),
                depth,
            },
        ));
        while g.1.len() > KEPT_UPLOADS {
            if let Some((_, old)) = g.1.pop_front() {
                let _ = std::fs::remove_file(old.path);
            }
        }
        Ok(json!({ "id": id, "name": name, "width": width, "height": height }))
    }
}

impl Engine {
    /// Removes the folder of dropped images before the process ends (a signal handler's job:
    /// destructors do not run then). Dropped images are written while the uploads' lock is held,
    /// so this waits for one being written and removes it with the rest; one written after finds
    /// no folder and fails, so nothing is left behind.
    pub fn remove_uploads(&self) -> std::io::Result<()> {
        let _writes = lock(&self.uploads);
        std::fs::remove_dir_all(self.upload_dir.path())
    }
}

/// The folder for dropped images, readable by this user only (0700).
pub(crate) fn private_dir() -> Result<tempfile::TempDir> {
    let dir = tempfile::Builder::new()
        .prefix("uwnr-serve-")
        .tempdir()
        .map_err(ServeError::io("creating the folder for dropped images"))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o700)).map_err(
            ServeError::io("making the folder for dropped images private"),
        )?;
    }
    Ok(dir)
}

/// Writes a new file readable by this user only (0600).
fn write_private(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(0o600);
    }
    let mut f = options.open(path)?;
    f.write_all(bytes)?;
    f.sync_all()
}
