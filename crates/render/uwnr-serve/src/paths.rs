//! The image folders a server may read, and the checks that keep every request inside them.
//!
//! A request names an image by its index in a folder's list or by a path relative to the folder.
//! A relative path must have only normal components (no `..`, no root, no drive: what
//! [`uwnr_core::io::stays_inside`] checks), and the file it resolves to, symlinks followed, must
//! lie under the folder's own resolved path; the same holds for the listed files themselves, so a
//! symlink in the folder that points elsewhere is listed (its index is the one a dataset gives it)
//! but never read.
//!
//! The check is made again each time a file is read ([`Library::read`], [`read_inside`]). Before
//! the file is opened, its resolved path must lie under the folder and be a regular file:
//! opening a FIFO waits for a writer (a handler thread stuck for good), and opening a device can
//! act on it, so neither is opened. It is then opened without waiting (`O_NONBLOCK`, and
//! `O_NOCTTY`: a terminal swapped in never becomes the server's), and the file actually opened
//! must again be a regular file under the folder (on Linux, the path `/proc/self/fd` gives;
//! elsewhere, the resolved path whose device and inode match the opened file's), so a file
//! swapped for a symlink or a FIFO after the checks, or after the folder was listed, is refused,
//! not followed.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{Result, ServeError};

/// Largest file read from a folder, bytes (a 24-megapixel 16-bit PNG is about 150 MB).
pub const MAX_FILE_BYTES: u64 = 512 * 1024 * 1024;

/// One image folder: its images in the order `uwnr dataset` lists them.
#[derive(Debug)]
pub struct Library {
    what: &'static str,
    /// The folder as given (what commands shown to the user name).
    given: PathBuf,
    /// The folder with every symlink resolved.
    root: PathBuf,
    files: Vec<Entry>,
}

#[derive(Debug)]
struct Entry {
    path: PathBuf,
    /// The path relative to the folder, with `/` separators.
    rel: String,
    /// Whether the file, symlinks followed, lies inside the folder.
    inside: bool,
}

impl Library {
    /// Lists the images under `dir` (recursively, sorted, an RGB-D layout's `depth/` skipped:
    /// `uwnr_dataset::plan::discover_images`, so indices are the dataset's). `what` names the
    /// folder in messages ("clean", "reference").
    pub fn open(dir: &Path, what: &'static str) -> Result<Self> {
        let root_err = |reason: String| ServeError::Root {
            what,
            path: dir.to_path_buf(),
            reason,
        };
        if !dir.is_dir() {
            return Err(root_err("not a folder".into()));
        }
        let root = dir.canonicalize().map_err(|e| root_err(e.to_string()))?;
        let listed = uwnr_dataset::plan::discover_images(&[dir.to_path_buf()], what, None)
            .map_err(|e| root_err(e.to_string()))?;
        let files = listed
            .into_iter()
            .map(|path| {
                let rel = path
                    .strip_prefix(dir)
                    .unwrap_or(&path)
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect::<Vec<_>>()
                    .join("/");
                let inside = path.canonicalize().is_ok_and(|p| p.starts_with(&root));
                Entry { path, rel, inside }
            })
            .collect();
        Ok(Self {
            what,
            given: dir.to_path_buf(),
            root,
            files,
        })
    }

    /// How many images are listed.
    #[must_use]
    pub fn len(&self) -> usize {
        self.files.len()
    }

    /// Whether the folder lists no image.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    /// The folder as given on the command line (what the page's commands name, so that they
    /// run where `uwnr serve` was started).
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.given
    }

    /// The folder with symlinks resolved (absolute: what path checks compare against).
    #[must_use]
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The relative path of image `index` (`/`-separated).
    pub fn rel(&self, index: usize) -> Result<&str> {
        self.entry(index).map(|e| e.rel.as_str())
    }

    /// The file of image `index`, refused when it resolves outside the folder.
    pub fn path(&self, index: usize) -> Result<&Path> {
        let e = self.entry(index)?;
        if !e.inside {
            return Err(ServeError::OutsideRoot {
                what: self.what,
                path: e.rel.clone(),
            });
        }
        Ok(&e.path)
    }

    /// The bytes of image `index`, read only if the file opened lies inside the folder (module
    /// docs).
    pub fn read(&self, index: usize) -> Result<Vec<u8>> {
        let path = self.path(index)?;
        let rel = self.rel(index)?;
        read_inside(&self.root, path, self.what, rel)
    }

    /// The index of the image at `rel`, a path relative to the folder, after the checks of the
    /// module docs.
    pub fn find(&self, rel: &str) -> Result<usize> {
        let resolved = resolve_inside(&self.root, rel, self.what)?;
        self.files
            .iter()
            .position(|e| e.inside && e.path.canonicalize().is_ok_and(|p| p == resolved))
            .ok_or_else(|| ServeError::NotFound {
                what: self.what,
                path: rel.to_string(),
            })
    }

    fn entry(&self, index: usize) -> Result<&Entry> {
        self.files.get(index).ok_or(ServeError::UnknownIndex {
            what: self.what,
            index,
            count: self.files.len(),
        })
    }
}

/// `rel` joined onto `root` (itself resolved), refused when `rel` is empty, absolute or has a
/// `..`, or when the file it names, symlinks followed, is not under `root`.
pub fn resolve_inside(root: &Path, rel: &str, what: &'static str) -> Result<PathBuf> {
    let outside = || ServeError::OutsideRoot {
        what,
        path: rel.to_string(),
    };
    let rel_path = Path::new(rel);
    if rel.contains('\0') || !uwnr_core::io::stays_inside(rel_path) {
        return Err(outside());
    }
    let joined = root.join(rel_path);
    let resolved = joined.canonicalize().map_err(|_| ServeError::NotFound {
        what,
        path: rel.to_string(),
    })?;
    if !resolved.starts_with(root) {
        return Err(outside());
    }
    Ok(resolved)
}

/// The bytes of the file at `path`, read only if the file opened lies under `root` (resolved);
/// `what` and `shown` name it in messages (never the path itself).
pub fn read_inside(root: &Path, path: &Path, what: &'static str, shown: &str) -> Result<Vec<u8>> {
    let failed = |reason: String| ServeError::ServerFile {
        what: format!("{what} image {shown}"),
        reason,
    };
    let outside = || ServeError::OutsideRoot {
        what,
        path: shown.to_string(),
    };
    let not_a_file = || failed("not a regular file".into());
    // Checked before opening: where it resolves to, then what it is.
    let resolved = path
        .canonicalize()
        .map_err(|e| failed(format!("cannot open it: {}", e.kind())))?;
    if !resolved.starts_with(root) {
        return Err(outside());
    }
    let before = std::fs::metadata(&resolved)
        .map_err(|e| failed(format!("cannot read it: {}", e.kind())))?;
    if !before.is_file() {
        return Err(not_a_file());
    }
    let file = open_without_waiting(&resolved)
        .map_err(|e| failed(format!("cannot open it: {}", e.kind())))?;
    // Checked again on what was opened: the path may have been swapped since.
    let meta = file
        .metadata()
        .map_err(|e| failed(format!("cannot read it: {}", e.kind())))?;
    if !meta.is_file() {
        return Err(not_a_file());
    }
    let opened = opened_path(&file, &resolved)
        .map_err(|e| failed(format!("cannot tell where it lies: {e}")))?;
    if !opened.starts_with(root) {
        return Err(outside());
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(failed(format!(
            "{} bytes, more than the {MAX_FILE_BYTES} bytes the page reads",
            meta.len()
        )));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(meta.len()).unwrap_or(0));
    file.take(MAX_FILE_BYTES)
        .read_to_end(&mut bytes)
        .map_err(|e| failed(format!("cannot read it: {}", e.kind())))?;
    Ok(bytes)
}

/// `path` opened for reading without waiting for a FIFO's writer and without making a terminal
/// the process's own.
fn open_without_waiting(path: &Path) -> std::io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY);
    }
    options.open(path)
}

/// Where the file `file`, opened from `path`, really is.
fn opened_path(file: &File, path: &Path) -> std::io::Result<PathBuf> {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        if let Ok(p) = std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())) {
            return Ok(p);
        }
    }
    let resolved = path.canonicalize()?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let (a, b) = (file.metadata()?, std::fs::metadata(&resolved)?);
        if (a.dev(), a.ino()) != (b.dev(), b.ino()) {
            return Err(std::io::Error::other("it changed while it was opened"));
        }
    }
    #[cfg(not(unix))]
    let _ = file;
    Ok(resolved)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parent_and_absolute_paths_are_refused_before_any_lookup() {
        let dir = tempfile::tempdir().unwrap();
        for bad in ["../x.png", "a/../../x.png", "/etc/passwd", "", "."] {
            let e = resolve_inside(dir.path(), bad, "clean").unwrap_err();
            assert!(matches!(e, ServeError::OutsideRoot { .. }), "{bad}: {e}");
            assert_eq!(e.status(), 403);
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_file_swapped_for_a_symlink_after_listing_is_not_read() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("refs");
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(folder.join("a.png"), b"inside").unwrap();
        std::fs::write(dir.path().join("secret.png"), b"outside").unwrap();
        let lib = Library::open(&folder, "reference").unwrap();
        assert_eq!(lib.read(0).unwrap(), b"inside");
        std::fs::remove_file(folder.join("a.png")).unwrap();
        std::os::unix::fs::symlink(dir.path().join("secret.png"), folder.join("a.png")).unwrap();
        let e = lib.read(0).unwrap_err();
        assert!(matches!(e, ServeError::OutsideRoot { .. }), "{e}");
        // A symlink that stays inside is read.
        std::fs::write(folder.join("b.png"), b"other inside").unwrap();
        std::fs::remove_file(folder.join("a.png")).unwrap();
        std::os::unix::fs::symlink(folder.join("b.png"), folder.join("a.png")).unwrap();
        assert_eq!(lib.read(0).unwrap(), b"other inside");
        // A vanished file is the server's failure, named as listed.
        std::fs::remove_file(folder.join("a.png")).unwrap();
        let e = lib.read(0).unwrap_err();
        assert_eq!(e.status(), 500);
        assert!(
            e.to_string().contains("a.png") && !e.to_string().contains('/'),
            "{e}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_or_a_device_is_refused_without_being_opened() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("clean");
        std::fs::create_dir(&folder).unwrap();
        std::fs::write(folder.join("a.png"), b"a").unwrap();
        std::fs::write(folder.join("b.png"), b"b").unwrap();
        let lib = Library::open(&folder, "clean").unwrap();
        let mkfifo = |p: &Path| {
            let made = std::process::Command::new("mkfifo")
                .arg(p)
                .status()
                .unwrap();
            assert!(made.success());
        };
        // Swapped after listing: a FIFO in the folder, and a symlink to a FIFO outside it
        // (opening either for reading waits for a writer that never comes).
        std::fs::remove_file(folder.join("a.png")).unwrap();
        mkfifo(&folder.join("a.png"));
        let outside = dir.path().join("fifo.png");
        mkfifo(&outside);
        std::fs::remove_file(folder.join("b.png")).unwrap();
        std::os::unix::fs::symlink(&outside, folder.join("b.png")).unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let statuses = [0, 1].map(|i| lib.read(i).map_err(|e| (e.status(), e.to_string())));
            let _ = tx.send(statuses);
        });
        // A hang guard, not a timing assertion: the reads answer without waiting on anything.
        let [inside, behind] = rx
            .recv_timeout(std::time::Duration::from_secs(30))
            .expect("a read blocked on a FIFO");
        let (status, message) = inside.unwrap_err();
        assert_eq!(status, 500);
        assert!(message.contains("not a regular file"), "{message}");
        assert_eq!(behind.unwrap_err().0, 403);
    }
}
