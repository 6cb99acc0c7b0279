//! The image folders a server may read, and the checks that keep every request inside them.
//!
//! A request names an image by its index in a folder's list or by a path relative to the folder.
//! A relative path must have only normal components (no `..`, no root, no drive: what
//! [`uwnr_core::io::stays_inside`] checks), and the file it resolves to, symlinks followed, must
//! lie under the folder's own resolved path; the same holds for the listed files themselves, so a
//! symlink in the folder that points elsewhere is listed (its index is the one a dataset gives it)
//! but never read.

use std::path::{Path, PathBuf};

use crate::error::{Result, ServeError};

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
}
