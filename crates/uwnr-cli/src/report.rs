//! Batch bookkeeping: progress bar, failed items, the closing summary.

use std::path::PathBuf;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

/// An error and its context chain in one line, each cause once (`uwnr_core::error::one_line`).
pub fn line(err: &anyhow::Error) -> String {
    uwnr_core::error::one_line(err.chain().map(ToString::to_string))
}

/// Tracks a batch: a progress bar (hidden when stderr is not a terminal), failures, timing.
pub struct Batch {
    bar: ProgressBar,
    total: usize,
    failures: Vec<(PathBuf, String)>,
    done: usize,
    start: Instant,
}

impl Batch {
    /// A batch of `total` items; the bar is shown only for more than one item.
    pub fn new(total: usize, what: &str) -> Self {
        let bar = if total > 1 {
            ProgressBar::new(total as u64)
        } else {
            ProgressBar::hidden()
        };
        if let Ok(style) = ProgressStyle::with_template(&format!(
            "{{spinner}} {what} {{pos}}/{{len}} [{{bar:30}}] {{per_sec}} eta {{eta}} {{msg}}"
        )) {
            bar.set_style(style.progress_chars("=> "));
        }
        Self {
            bar,
            total,
            failures: Vec::new(),
            done: 0,
            start: Instant::now(),
        }
    }

    /// Prints a line above the bar.
    pub fn note(&self, line: &str) {
        self.bar.suspend(|| eprintln!("{line}"));
    }

    /// Records one finished item.
    pub fn ok(&mut self) {
        self.done += 1;
        self.bar.inc(1);
    }

    /// Records one failed item with its one-line reason; the batch goes on.
    pub fn fail(&mut self, item: PathBuf, err: &anyhow::Error) {
        let msg = line(err);
        if self.total == 1 {
            // A single item: its error is the one line the user sees.
            eprintln!("uwnr: error: {}: {msg}", item.display());
        } else {
            self.bar
                .suspend(|| eprintln!("uwnr: failed: {}: {msg}", item.display()));
        }
        self.failures.push((item, msg));
        self.bar.inc(1);
    }

    /// Ends the bar, prints the summary and the failure list. Returns whether all succeeded.
    pub fn finish(self, what: &str) -> bool {
        self.bar.finish_and_clear();
        let secs = self.start.elapsed().as_secs_f64();
        let total = self.done + self.failures.len();
        if total > 1 {
            eprintln!(
                "{what}: {} done, {} failed in {secs:.1} s ({:.2} images/s)",
                self.done,
                self.failures.len(),
                self.done as f64 / secs.max(1e-9)
            );
        }
        if total > 1 && !self.failures.is_empty() {
            eprintln!("failed items:");
            for (p, m) in &self.failures {
                eprintln!("  {}: {m}", p.display());
            }
        }
        self.failures.is_empty()
    }
}
