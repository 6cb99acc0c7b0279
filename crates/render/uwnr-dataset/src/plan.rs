//! The plan of a dataset: which clean images, which references each pair draws, pair names and
//! seeds, and which shard owns which pairs. Everything here is a pure function of the sorted
//! input lists and the seed, so every worker, every shard and every resumed run agrees on it.

use std::collections::HashSet;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, Result, io_err};

/// Size of the pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Size {
    /// Each clean image at its own resolution.
    Native,
    /// Every pair `width x height`: the clean image is scaled to cover it (aspect kept) and
    /// centre-cropped, never stretched.
    Fixed { width: usize, height: usize },
}

impl fmt::Display for Size {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Native => f.write_str("native"),
            Self::Fixed { width, height } => write!(f, "{width}x{height}"),
        }
    }
}

impl FromStr for Size {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s.eq_ignore_ascii_case("native") {
            return Ok(Self::Native);
        }
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| format!("expected native or WxH, got {s:?}"))?;
        let parse = |v: &str| -> std::result::Result<usize, String> {
            match v.trim().parse::<usize>() {
                Ok(n) if (16..=16384).contains(&n) => Ok(n),
                _ => Err(format!("sizes go from 16 to 16384 pixels, got {s:?}")),
            }
        };
        Ok(Self::Fixed {
            width: parse(w)?,
            height: parse(h)?,
        })
    }
}

/// One slice of a sharded run: shard `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Whether this shard renders the pairs of clean image `clean_index` (round robin over the
    /// sorted clean list, so shards get equal shares of every input folder).
    #[must_use]
    pub fn owns(&self, clean_index: usize) -> bool {
        clean_index % self.count == self.index
    }

    /// `I-of-N`, the tag of this shard's files.
    #[must_use]
    pub fn tag(&self) -> String {
        format!("{}-of-{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("expected I/N (e.g. 0/4), got {s:?}"))?;
        let index: usize = i
            .trim()
            .parse()
            .map_err(|_| format!("bad shard index in {s:?}"))?;
        let count: usize = n
            .trim()
            .parse()
            .map_err(|_| format!("bad shard count in {s:?}"))?;
        if count == 0 || index >= count {
            return Err(format!("shard I/N needs 0 <= I < N, got {s:?}"));
        }
        Ok(Self { index, count })
    }
}

/// Image files under `paths`: files as given, folders searched recursively (skipping the folder
/// `exclude`, a dataset being written inside an input folder, and the `depth/` folder of an
/// RGB-D layout, `X/rgb/` beside `X/depth/`, whose maps are not photos); each folder's images
/// sorted by path. Files given explicitly are kept whatever their extension, so a bad file is reported,
/// not hidden.
pub fn discover_images(
    paths: &[PathBuf],
    what: &str,
    exclude: Option<&Path>,
) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let before = out.len();
            walk(p, exclude, &mut out)?;
            out[before..].sort();
            if out.len() == before {
                return Err(DatasetError::Invalid(format!(
                    "{what} folder {} holds no images",
                    p.display()
                )));
            }
        } else if p.exists() {
            out.push(p.clone());
        } else {
            return Err(DatasetError::Invalid(format!(
                "{what} {} does not exist",
                p.display()
            )));
        }
    }
    Ok(out)
}

fn walk(dir: &Path, exclude: Option<&Path>, out: &mut Vec<PathBuf>) -> Result<()> {
    if exclude.is_some_and(|x| dir.canonicalize().is_ok_and(|d| d == x)) {
        return Ok(());
    }
    let rgbd = dir.join("rgb").is_dir() && dir.join("depth").is_dir();
    for entry in std::fs::read_dir(dir).map_err(io_err(dir))? {
        let path = entry.map_err(io_err(dir))?.path();
        if path.is_dir() {
            if rgbd && path.file_name().is_some_and(|n| n == "depth") {
                continue;
            }
            walk(&path, exclude, out)?;
        } else if path.is_file() && uwnr_core::io::is_image_path(&path) {
            out.push(path);
        }
    }
    Ok(())
}

/// Output names of the clean images: the file stem, with characters other than letters,
/// digits, `-`, `_` and `.` replaced by `_`, made unique over the whole list in list order by
/// `-2`, `-3`... (skipping names already taken, so `x`, `x`, `x-2` become `x`, `x-2`, `x-2-2`).
#[must_use]
pub fn clean_names(cleans: &[PathBuf]) -> Vec<String> {
    let mut taken: HashSet<String> = HashSet::new();
    cleans
        .iter()
        .map(|p| {
            let stem: String = p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "image".into())
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            let name = (1..)
                .map(|n| {
                    if n == 1 {
                        stem.clone()
                    } else {
                        format!("{stem}-{n}")
                    }
                })
                .find(|c| !taken.contains(c))
                .unwrap_or_default();
            taken.insert(name.clone());
            name
        })
        .collect()
}

/// The name of pair `k` of the clean image named `name`: `NAME_k`.
#[must_use]
pub fn pair_id(name: &str, k: usize) -> String {
    format!("{name}_{k}")
}

pub use uwnr_core::seed::mix;

/// The seed of the pair with global index `pair_index` (`clean_index * K + k`): what a
/// randomised method samples its parameters from.
#[must_use]
pub fn pair_seed(seed: u64, pair_index: u64) -> u64 {
    mix(mix(seed) ^ pair_index)
}

/// Mixed into the seed of the reference draw, so it is a different random stream from the pairs'
/// seeds.
const DRAW_STREAM: u64 = 0x005E_ED0F_2EF5;

/// The order in which clean image `clean_index` draws references: a seeded random permutation
/// of `0..n`, produced lazily (a Fisher-Yates shuffle one step per item), so taking the first K
/// readable ones draws K references without replacement whatever the thread count or shard.
pub struct ReferenceOrder {
    rng: ChaCha8Rng,
    items: Vec<usize>,
    next: usize,
}

impl ReferenceOrder {
    /// The draw order of clean image `clean_index` among `n` references.
    #[must_use]
    pub fn new(seed: u64, clean_index: usize, n: usize) -> Self {
        let s = mix(mix(seed ^ DRAW_STREAM) ^ clean_index as u64);
        Self {
            rng: ChaCha8Rng::seed_from_u64(s),
            items: (0..n).collect(),
            next: 0,
        }
    }
}

impl Iterator for ReferenceOrder {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        let n = self.items.len();
        if self.next >= n {
            return None;
        }
        let j = self.rng.random_range(self.next..n);
        self.items.swap(self.next, j);
        self.next += 1;
        Some(self.items[self.next - 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_shards_parse() {
        assert_eq!("native".parse::<Size>(), Ok(Size::Native));
        assert_eq!(
            "256x192".parse::<Size>(),
            Ok(Size::Fixed {
                width: 256,
                height: 192
            })
        );
        assert!("0x10".parse::<Size>().is_err());
        assert!("256".parse::<Size>().is_err());
        assert_eq!("1/4".parse::<Shard>(), Ok(Shard { index: 1, count: 4 }));
        assert!("4/4".parse::<Shard>().is_err());
        assert!("0/0".parse::<Shard>().is_err());
    }

    #[test]
    fn shards_partition_the_clean_list() {
        let shards: Vec<Shard> = (0..3).map(|index| Shard { index, count: 3 }).collect();
        for i in 0..20 {
            assert_eq!(shards.iter().filter(|s| s.owns(i)).count(), 1);
        }
    }

    #[test]
    fn names_are_unique_and_safe() {
        let names = clean_names(&[
            PathBuf::from("a/baby.jpg"),
            PathBuf::from("b/baby.png"),
            PathBuf::from("c/my photo.jpg"),
        ]);
        assert_eq!(names, ["baby", "baby-2", "my_photo"]);
        let names = clean_names(&[
            PathBuf::from("a/x.png"),
            PathBuf::from("b/x.png"),
            PathBuf::from("c/x-2.png"),
        ]);
        assert_eq!(names, ["x", "x-2", "x-2-2"]);
    }

    #[test]
    fn reference_order_is_a_seeded_permutation() {
        let a: Vec<usize> = ReferenceOrder::new(7, 3, 50).collect();
        let mut sorted = a.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..50).collect::<Vec<_>>());
        assert_eq!(a, ReferenceOrder::new(7, 3, 50).collect::<Vec<_>>());
        assert_ne!(a, ReferenceOrder::new(7, 4, 50).collect::<Vec<_>>());
        assert_ne!(a, ReferenceOrder::new(8, 3, 50).collect::<Vec<_>>());
        // Taking a prefix gives the same items as the full order's prefix.
        let first: Vec<usize> = ReferenceOrder::new(7, 3, 50).take(5).collect();
        assert_eq!(first, a[..5]);
    }
}
