//! The experiment's results: what `results.json` holds and how `results.md` shows it.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

/// Mean scores of one network on one test set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Pairs scored.
    pub images: usize,
    /// PSNR (dB) of the output against the clean reference.
    pub psnr: f64,
    /// SSIM of the output against the clean reference.
    pub ssim: f64,
    /// UIQM of the output (no reference).
    pub uiqm: f64,
    /// UCIQE of the output (no reference).
    pub uciqe: f64,
}

/// A real paired test set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TestSet {
    /// Short name (the folder's name, made unique).
    pub name: String,
    /// The folder, as given.
    pub path: String,
    /// Pairs in it.
    pub pairs: usize,
}

/// What a row's network was trained on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RowKind {
    /// No network: the underwater input scored as it is.
    NoEnhancement,
    /// A training set rendered by one method.
    Synthetic,
    /// Real paired images.
    Real,
}

/// One row of the table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// `none`, the method's name, or `real:FOLDER`.
    pub name: String,
    /// What it was trained on.
    pub kind: RowKind,
    /// Training pairs (none for the no-enhancement row).
    pub train_pairs: Option<usize>,
    /// Pairs the method failed to render (listed in the dataset's failure file).
    pub failed_pairs: Option<usize>,
    /// Training steps done.
    pub train_steps: Option<usize>,
    /// Seconds spent rendering the training set, summed over sessions.
    pub dataset_secs: f64,
    /// Seconds spent training: the trainer's own count behind its last checkpoint, summed over
    /// the sessions that made it.
    pub train_secs: f64,
    /// Seconds spent scoring, summed over sessions.
    pub eval_secs: f64,
    /// Scores per test set, in the order of [`Results::tests`].
    pub scores: Vec<Scores>,
}

/// Everything `results.json` records.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Results {
    /// The experiment's settings (as in `experiment.json`).
    pub settings: serde_json::Value,
    /// Parameters of the enhancer.
    pub enhancer_params: usize,
    /// The test sets, in column order.
    pub tests: Vec<TestSet>,
    /// The rows: no enhancement, each method, each real training set.
    pub rows: Vec<Row>,
}

/// Index of the best value of `values` (`None` entries skipped); ties go to the first.
fn best(values: &[f64]) -> Option<usize> {
    values
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .fold(None, |acc: Option<(usize, f64)>, (i, &v)| match acc {
            Some((_, b)) if b >= v => acc,
            _ => Some((i, v)),
        })
        .map(|(i, _)| i)
}

fn cell(value: f64, digits: usize, bold: bool) -> String {
    let s = format!("{value:.digits$}");
    if bold { format!("**{s}**") } else { s }
}

fn duration(secs: f64) -> String {
    let s = secs.round() as u64;
    if s >= 3600 {
        format!("{}h{:02}m", s / 3600, (s % 3600) / 60)
    } else {
        format!("{}m{:02}s", s / 60, s % 60)
    }
}

/// The table of `results.md`: one row per network, four columns (PSNR, SSIM, UIQM, UCIQE) per
/// test set, the best value of each column in bold (highest; the no-enhancement row competes
/// too), then the training set sizes, steps and times.
#[must_use]
pub fn write_markdown(r: &Results, title: &str, preamble: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# {title}\n");
    if !preamble.is_empty() {
        let _ = writeln!(md, "{preamble}\n");
    }
    let mut header = String::from("| trained on |");
    let mut rule = String::from("|---|");
    for t in &r.tests {
        for m in ["PSNR", "SSIM", "UIQM", "UCIQE"] {
            let _ = write!(header, " {} {m} |", t.name);
            rule.push_str("---:|");
        }
    }
    let _ = writeln!(md, "{header}\n{rule}");
    // Best per column.
    let columns = r.tests.len() * 4;
    let value = |row: &Row, col: usize| -> f64 {
        row.scores.get(col / 4).map_or(f64::NAN, |s| match col % 4 {
            0 => s.psnr,
            1 => s.ssim,
            2 => s.uiqm,
            _ => s.uciqe,
        })
    };
    let bests: Vec<Option<usize>> = (0..columns)
        .map(|c| {
            best(
                &r.rows
                    .iter()
                    .map(|row| {
                        // Rounded as shown, so equal-looking cells tie.
                        let d = if c % 4 == 0 { 2 } else { 3 };
                        let p = 10f64.powi(d);
                        (value(row, c) * p).round() / p
                    })
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    for (i, row) in r.rows.iter().enumerate() {
        let label = match row.kind {
            RowKind::NoEnhancement => "no enhancement (input as is)".to_string(),
            RowKind::Synthetic => format!("synthetic: {}", row.name),
            RowKind::Real => format!("real pairs: {}", row.name.trim_start_matches("real:")),
        };
        let _ = write!(md, "| {label} |");
        for (c, b) in bests.iter().enumerate() {
            let v = value(row, c);
            if v.is_finite() {
                let digits = if c % 4 == 0 { 2 } else { 3 };
                let _ = write!(md, " {} |", cell(v, digits, *b == Some(i)));
            } else {
                md.push_str(" – |");
            }
        }
        md.push('\n');
    }
    let _ = writeln!(
        md,
        "\n| trained on | training pairs | failed renders | steps | render time | training time | scoring time |\n|---|---:|---:|---:|---:|---:|---:|"
    );
    for row in &r.rows {
        if row.kind == RowKind::NoEnhancement {
            continue;
        }
        let opt = |v: Option<usize>| v.map_or_else(|| "–".to_string(), |v| v.to_string());
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} |",
            row.name,
            opt(row.train_pairs),
            opt(row.failed_pairs),
            opt(row.train_steps),
            if row.kind == RowKind::Synthetic {
                duration(row.dataset_secs)
            } else {
                "–".into()
            },
            duration(row.train_secs),
            duration(row.eval_secs),
        );
    }
    let _ = writeln!(md, "\nTest sets:");
    for t in &r.tests {
        let _ = writeln!(md, "- `{}`: {} pairs ({})", t.name, t.pairs, t.path);
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scores(psnr: f64) -> Scores {
        Scores {
            images: 2,
            psnr,
            ssim: 0.5,
            uiqm: 1.0,
            uciqe: 0.4,
        }
    }

    #[test]
    fn table_has_one_line_per_row_and_bolds_the_best() {
        let row = |name: &str, kind, psnr| Row {
            name: name.into(),
            kind,
            train_pairs: (kind != RowKind::NoEnhancement).then_some(8),
            failed_pairs: Some(0),
            train_steps: Some(4),
            dataset_secs: 1.0,
            train_secs: 75.0,
            eval_secs: 2.0,
            scores: vec![scores(psnr), scores(psnr - 1.0)],
        };
        let r = Results {
            settings: serde_json::json!({}),
            enhancer_params: 1,
            tests: vec![
                TestSet {
                    name: "a".into(),
                    path: "x/a".into(),
                    pairs: 2,
                },
                TestSet {
                    name: "b".into(),
                    path: "x/b".into(),
                    pairs: 2,
                },
            ],
            rows: vec![
                row("none", RowKind::NoEnhancement, 15.0),
                row("uwnr", RowKind::Synthetic, 19.5),
                row("real:euvp", RowKind::Real, 18.0),
            ],
        };
        let md = write_markdown(&r, "T", "");
        let lines: Vec<&str> = md.lines().filter(|l| l.starts_with("| ")).collect();
        // Header, 3 score rows, header of the cost table, 2 cost rows.
        assert_eq!(lines.len(), 7, "{md}");
        assert!(lines[0].contains("a PSNR") && lines[0].contains("b UCIQE"));
        assert!(md.contains("| synthetic: uwnr | **19.50** |"), "{md}");
        assert!(
            md.contains("| no enhancement (input as is) | 15.00 |"),
            "{md}"
        );
        // Ties (SSIM is equal everywhere) go to the first row.
        assert!(md.contains("| no enhancement (input as is) | 15.00 | **0.500** |"));
        assert_eq!(lines[1].matches('|').count(), 10);
        assert!(
            md.contains("| uwnr | 8 | 0 | 4 | 0m01s | 1m15s | 0m02s |"),
            "{md}"
        );
    }
}
