//! Turning command-line paths into work items: directory expansion, pairing, output names.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cli::Pairing;

/// Expands files and directories (one level, sorted by name) into image files.
/// Files given explicitly are kept whatever their extension, so a bad file is reported, not hidden.
pub fn expand_images(paths: &[PathBuf], what: &str) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("reading {what} directory {}", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|e| e.is_file() && uwnr_core::io::is_image_path(e))
                .collect();
            found.sort();
            if found.is_empty() {
                bail!("{what} directory {} holds no images", p.display());
            }
            out.extend(found);
        } else if p.exists() {
            out.push(p.clone());
        } else {
            bail!("{what} {} does not exist", p.display());
        }
    }
    if out.is_empty() {
        bail!("no {what} images given");
    }
    Ok(out)
}

/// One render to do: indices into the clean and reference lists, and where it goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Job {
    pub clean: usize,
    /// `None` for methods that need no reference when none was given.
    pub reference: Option<usize>,
    pub output: PathBuf,
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".to_string())
}

/// Pairs clean images with references and names outputs inside `out_dir`.
/// Names are `STEM.EXT` (or `STEM__REFSTEM.EXT` with `--pairing all`); a taken name gets `-2`, `-3`...
/// With no references every clean image gets one job without a reference.
pub fn plan_jobs(
    cleans: &[PathBuf],
    refs: &[PathBuf],
    pairing: Pairing,
    seed: u64,
    out_dir: &Path,
    ext: &str,
) -> Vec<Job> {
    let mut pairs = Vec::new();
    if refs.is_empty() {
        pairs.extend((0..cleans.len()).map(|i| (i, None)));
    } else {
        match pairing {
            Pairing::Cycle => {
                for i in 0..cleans.len() {
                    pairs.push((i, Some(i % refs.len())));
                }
            }
            Pairing::All => {
                for i in 0..cleans.len() {
                    for j in 0..refs.len() {
                        pairs.push((i, Some(j)));
                    }
                }
            }
            Pairing::Random => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                for i in 0..cleans.len() {
                    pairs.push((i, Some(rng.random_range(0..refs.len()))));
                }
            }
        }
    }
    let mut taken: HashSet<String> = HashSet::new();
    pairs
        .into_iter()
        .map(|(i, j)| {
            let base = match (pairing, j) {
                (Pairing::All, Some(j)) => format!("{}__{}", stem(&cleans[i]), stem(&refs[j])),
                _ => stem(&cleans[i]),
            };
            // The first free name, so `x`, `x`, `x-2` become `x`, `x-2`, `x-2-2`.
            let name = (1..)
                .map(|n| {
                    if n == 1 {
                        format!("{base}.{ext}")
                    } else {
                        format!("{base}-{n}.{ext}")
                    }
                })
                .find(|c| !taken.contains(c))
                .unwrap_or_default();
            taken.insert(name.clone());
            Job {
                clean: i,
                reference: j,
                output: out_dir.join(name),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(PathBuf::from).collect()
    }

    #[test]
    fn cycle_pairs_by_index_and_dedupes_names() {
        let jobs = plan_jobs(
            &paths(&["a/x.jpg", "b/x.png", "c/y.jpg"]),
            &paths(&["r1.jpg", "r2.jpg"]),
            Pairing::Cycle,
            0,
            Path::new("out"),
            "png",
        );
        let got: Vec<_> = jobs.iter().map(|j| (j.clean, j.reference)).collect();
        assert_eq!(got, vec![(0, Some(0)), (1, Some(1)), (2, Some(0))]);
        assert_eq!(jobs[0].output, Path::new("out/x.png"));
        assert_eq!(jobs[1].output, Path::new("out/x-2.png"));
        let jobs = plan_jobs(
            &paths(&["a/x.jpg", "b/x.png", "c/x-2.jpg"]),
            &paths(&["r.jpg"]),
            Pairing::Cycle,
            0,
            Path::new("out"),
            "png",
        );
        assert_eq!(jobs[2].output, Path::new("out/x-2-2.png"));
    }

    #[test]
    fn no_references_give_one_job_per_clean_image() {
        let jobs = plan_jobs(
            &paths(&["x.jpg", "y.jpg"]),
            &[],
            Pairing::All,
            0,
            Path::new("o"),
            "png",
        );
        assert_eq!(jobs.len(), 2);
        assert!(jobs.iter().all(|j| j.reference.is_none()));
    }

    #[test]
    fn all_makes_every_combination() {
        let jobs = plan_jobs(
            &paths(&["x.jpg", "y.jpg"]),
            &paths(&["r1.jpg", "r2.jpg", "r3.jpg"]),
            Pairing::All,
            0,
            Path::new("o"),
            "jpg",
        );
        assert_eq!(jobs.len(), 6);
        assert_eq!(jobs[5].output, Path::new("o/y__r3.jpg"));
    }

    #[test]
    fn random_is_seeded() {
        let c = paths(&["a", "b", "c", "d", "e", "f", "g", "h"]);
        let r = paths(&["1", "2", "3", "4"]);
        let a = plan_jobs(&c, &r, Pairing::Random, 7, Path::new("o"), "png");
        let b = plan_jobs(&c, &r, Pairing::Random, 7, Path::new("o"), "png");
        let d = plan_jobs(&c, &r, Pairing::Random, 8, Path::new("o"), "png");
        assert_eq!(a, b);
        assert_ne!(
            a.iter().map(|j| j.reference).collect::<Vec<_>>(),
            d.iter().map(|j| j.reference).collect::<Vec<_>>()
        );
    }
}
