//! Images dropped into the page, kept in the server's private folder (0700, files 0600), the
//! last [`KEPT_UPLOADS`] of them. The engine keeps one only once it has checked that it decodes
//! within the limits and the memory budget ([`crate::Engine::store_upload`]).

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

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

impl Upload {
    /// The dropped file's bytes (a file the server kept: its loss is the server's failure).
    pub(crate) fn read(&self) -> Result<Vec<u8>> {
        std::fs::read(&self.path).map_err(|e| ServeError::ServerFile {
            what: format!("dropped image {}", self.name),
            reason: format!("the server lost its copy ({}); drop it again", e.kind()),
        })
    }
}

/// The dropped images: the private folder they are kept in, the number of the next one and the
/// last [`KEPT_UPLOADS`] by id.
pub(crate) struct Uploads {
    dir: tempfile::TempDir,
    kept: Mutex<(u64, VecDeque<(String, Upload)>)>,
}

impl Uploads {
    /// No dropped image yet, in a new private folder.
    pub(crate) fn new() -> Result<Self> {
        Ok(Self {
            dir: private_dir()?,
            kept: Mutex::new((1, VecDeque::new())),
        })
    }

    /// The folder dropped images are kept in.
    pub(crate) fn dir(&self) -> &Path {
        self.dir.path()
    }

    fn lock(&self) -> MutexGuard<'_, (u64, VecDeque<(String, Upload)>)> {
        self.kept.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The dropped image `id`, while it is kept.
    pub(crate) fn get(&self, id: &str) -> Result<Upload> {
        self.lock()
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

    /// Keeps `bytes` (an image the caller has checked) as a new file readable by this user only,
    /// under the name `name` ([`display_name`]); deletes the oldest beyond [`KEPT_UPLOADS`].
    /// Returns the new image's id.
    pub(crate) fn keep(&self, bytes: &[u8], name: &str, depth: bool) -> Result<String> {
        let mut g = self.lock();
        let id = format!("u{}", g.0);
        g.0 += 1;
        let ext = Path::new(name)
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .filter(|e| uwnr_core::io::IMAGE_EXTENSIONS.contains(&e.as_str()))
            .unwrap_or_else(|| "png".into());
        let path = self.dir.path().join(format!("{id}.{ext}"));
        write_private(&path, bytes).map_err(ServeError::io("saving a dropped image"))?;
        g.1.push_back((
            id.clone(),
            Upload {
                path,
                name: name.to_owned(),
                depth,
            },
        ));
        while g.1.len() > KEPT_UPLOADS {
            if let Some((_, old)) = g.1.pop_front() {
                let _ = std::fs::remove_file(old.path);
            }
        }
        Ok(id)
    }

    /// Removes the folder of dropped images before the process ends (a signal handler's job:
    /// destructors do not run then). Dropped images are written while the lock is held, so this
    /// waits for one being written and removes it with the rest; one written after finds no
    /// folder and fails, so nothing is left behind.
    pub(crate) fn remove_all(&self) -> std::io::Result<()> {
        let _writes = self.lock();
        std::fs::remove_dir_all(self.dir.path())
    }
}

/// The name a dropped file is shown under: its file name, without the folders it came from.
pub(crate) fn display_name(name: &str) -> String {
    Path::new(name)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "dropped.png".into())
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
