//! The run's CSV logs: `metrics.csv` (training losses every few steps) and `val.csv`
//! (validation scores). Rows are appended as the run goes; on resume, rows written after the
//! checkpoint being resumed are dropped, so the files describe one uninterrupted run.

use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Result, RunError};

/// Header of `val.csv`.
pub const VAL_HEADER: &str = "step,epoch,psnr,ssim,secs";

/// Header of `metrics.csv` for a task whose loss columns are `terms`.
#[must_use]
pub fn metrics_header(terms: &[&str]) -> String {
    format!("step,epoch,lr,{},secs_per_step", terms.join(","))
}

/// An append-only CSV file whose first column is the step.
#[derive(Debug)]
pub struct CsvLog {
    path: PathBuf,
}

impl CsvLog {
    /// Opens (creating with `header` when missing) the log at `path`; rows whose step is
    /// above `keep_up_to` are removed.
    pub fn open(path: &Path, header: &str, keep_up_to: Option<usize>) -> Result<Self> {
        let io = |source| RunError::Io {
            path: path.to_path_buf(),
            source,
        };
        if path.is_file() {
            if let Some(limit) = keep_up_to {
                let text = std::fs::read_to_string(path).map_err(io)?;
                let mut kept = String::new();
                for (i, line) in text.lines().enumerate() {
                    let step = line.split(',').next().and_then(|s| s.parse::<usize>().ok());
                    if i == 0 || step.is_some_and(|s| s <= limit) {
                        kept.push_str(line);
                        kept.push('\n');
                    }
                }
                uwnr_core::io::write_atomic(path, |out| out.write_all(kept.as_bytes()))?;
            }
        } else {
            std::fs::write(path, format!("{header}\n")).map_err(io)?;
        }
        Ok(Self {
            path: path.to_path_buf(),
        })
    }

    /// Appends one row.
    pub fn append(&self, fields: &[String]) -> Result<()> {
        let io = |source| RunError::Io {
            path: self.path.clone(),
            source,
        };
        let mut f = OpenOptions::new()
            .append(true)
            .open(&self.path)
            .map_err(io)?;
        writeln!(f, "{}", fields.join(",")).map_err(io)
    }

    /// The numeric rows (header skipped; unparsable fields become NaN).
    pub fn rows(&self) -> Result<Vec<Vec<f64>>> {
        let text = std::fs::read_to_string(&self.path).map_err(|source| RunError::Io {
            path: self.path.clone(),
            source,
        })?;
        Ok(text
            .lines()
            .skip(1)
            .filter(|l| !l.trim().is_empty())
            .map(|l| {
                l.split(',')
                    .map(|v| v.trim().parse().unwrap_or(f64::NAN))
                    .collect()
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resume_drops_rows_after_the_checkpoint() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.csv");
        let log = CsvLog::open(&p, "step,v", None).unwrap();
        for s in [10, 20, 30] {
            log.append(&[s.to_string(), "1.5".into()]).unwrap();
        }
        let log = CsvLog::open(&p, "step,v", Some(20)).unwrap();
        assert_eq!(log.rows().unwrap(), vec![vec![10.0, 1.5], vec![20.0, 1.5]]);
        assert!(std::fs::read_to_string(&p).unwrap().starts_with("step,v\n"));
    }
}
