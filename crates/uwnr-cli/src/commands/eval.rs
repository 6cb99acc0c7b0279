//! `uwnr eval`: score images with the field's metrics.
//!
//! - full reference: `--pred DIR --target DIR` pairs files by stem and reports PSNR and SSIM
//!   (RGB, data range 1 on u8/255 values, as scikit-image on the u8 arrays with data_range=255),
//!   plus UIQM and UCIQE of the predictions;
//! - no reference: `--images DIR` reports UIQM and UCIQE per image, and with `--real DIR` the
//!   Fréchet distance and KID between the two sets on the built-in colour-texture features
//!   (FD-ct) or, with `--inception FILE.onnx`, on InceptionV3 pool3 features (FID).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;

use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use serde_json::json;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, write_atomic};
use uwnr_metrics::{
    ColorTextureFeatures, FeatureExtractor, KID_SUBSET_SIZE, KID_SUBSETS, frechet_distance, kid,
    psnr, psnr_gray, ssim, ssim_gray, uciqe, uiqm,
};

use crate::cli::EvalArgs;
use crate::inputs::expand_images;
use crate::report::Batch;

/// Scores of one image (absent entries are metrics not computed for it).
#[derive(Debug, Default, Clone)]
struct Row {
    name: String,
    scores: BTreeMap<&'static str, f64>,
}

pub fn run(a: &EvalArgs) -> Result<ExitCode> {
    let limits = DecodeLimits::default();
    let mut problems: Vec<String> = Vec::new();
    let (rows, set_metrics) = match (&a.pred, &a.target, &a.images) {
        (Some(pred), Some(target), None) => (
            full_reference(pred, target, a.gray, &limits, &mut problems)?,
            BTreeMap::new(),
        ),
        (None, None, Some(images)) => no_reference(a, images, &limits, &mut problems)?,
        _ => bail!("give either --pred DIR --target DIR, or --images DIR [--real DIR]"),
    };
    if rows.is_empty() {
        bail!("no image could be scored");
    }
    print_table(&rows, &set_metrics);
    if let Some(path) = &a.json {
        write_json(path, &rows, &set_metrics, &problems)?;
    }
    if let Some(path) = &a.csv {
        write_csv(path, &rows)?;
    }
    if !problems.is_empty() {
        eprintln!("{} item(s) not scored:", problems.len());
        for p in &problems {
            eprintln!("  {p}");
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A scored file: its table row and its features (when a feature metric is asked for), or why it failed.
type ScoredFile = Result<(Row, Option<Vec<f64>>), String>;

fn stem_map(files: &[PathBuf]) -> BTreeMap<String, PathBuf> {
    files
        .iter()
        .filter_map(|p| {
            p.file_stem()
                .map(|s| (s.to_string_lossy().into_owned(), p.clone()))
        })
        .collect()
}

fn full_reference(
    pred: &Path,
    target: &Path,
    gray: bool,
    limits: &DecodeLimits,
    problems: &mut Vec<String>,
) -> Result<Vec<Row>> {
    let preds = stem_map(&expand_images(&[pred.to_path_buf()], "prediction")?);
    let targets = stem_map(&expand_images(&[target.to_path_buf()], "target")?);
    for name in targets.keys().filter(|k| !preds.contains_key(*k)) {
        problems.push(format!("{name}: no prediction for this target"));
    }
    let pairs: Vec<(String, PathBuf, PathBuf)> = preds
        .iter()
        .filter_map(|(name, p)| match targets.get(name) {
            Some(t) => Some((name.clone(), p.clone(), t.clone())),
            None => {
                problems.push(format!("{name}: no target for this prediction"));
                None
            }
        })
        .collect();
    let batch = Mutex::new(Batch::new(pairs.len(), "scoring"));
    let results: Vec<Result<Row, String>> = pairs
        .par_iter()
        .map(|(name, p, t)| {
            let r = score_pair(name, p, t, gray, limits);
            if let Ok(mut b) = batch.lock() {
                match &r {
                    Ok(_) => b.ok(),
                    Err(e) => b.fail(p.clone(), e),
                }
            }
            r.map_err(|e| format!("{name}: {}", crate::report::line(&e)))
        })
        .collect();
    if let Ok(b) = batch.into_inner() {
        b.finish("eval");
    }
    Ok(split(results, problems))
}

fn score_pair(name: &str, p: &Path, t: &Path, gray: bool, limits: &DecodeLimits) -> Result<Row> {
    let pred = load_rgb(p, limits).with_context(|| format!("reading {}", p.display()))?;
    let target = load_rgb(t, limits).with_context(|| format!("reading {}", t.display()))?;
    if pred.size() != target.size() {
        bail!(
            "size mismatch: prediction {}x{}, target {}x{}",
            pred.width(),
            pred.height(),
            target.width(),
            target.height()
        );
    }
    let mut row = Row {
        name: name.to_string(),
        ..Row::default()
    };
    if gray {
        row.scores.insert("psnr", psnr_gray(&pred, &target, 1.0)?);
        row.scores.insert("ssim", ssim_gray(&pred, &target, 1.0)?);
    } else {
        row.scores.insert("psnr", psnr(&pred, &target, 1.0)?);
        row.scores.insert("ssim", ssim(&pred, &target, 1.0)?);
    }
    row.scores.insert("uiqm", uiqm(&pred)?);
    row.scores.insert("uciqe", uciqe(&pred)?);
    Ok(row)
}

fn split(results: Vec<Result<Row, String>>, problems: &mut Vec<String>) -> Vec<Row> {
    let mut rows = Vec::new();
    for r in results {
        match r {
            Ok(row) => rows.push(row),
            Err(e) => problems.push(e),
        }
    }
    rows
}

type SetMetrics = BTreeMap<String, f64>;

fn no_reference(
    a: &crate::cli::EvalArgs,
    dir: &Path,
    limits: &DecodeLimits,
    problems: &mut Vec<String>,
) -> Result<(Vec<Row>, SetMetrics)> {
    let files = expand_images(&[dir.to_path_buf()], "image")?;
    let extractor: Option<Box<dyn FeatureExtractor>> = match (&a.real, &a.inception) {
        (None, _) => None,
        (Some(_), Some(model)) => Some(inception(model)?),
        (Some(_), None) => Some(Box::new(ColorTextureFeatures::new())),
    };
    let batch = Mutex::new(Batch::new(files.len(), "scoring"));
    let results: Vec<ScoredFile> = files
        .par_iter()
        .map(|p| {
            let r = score_single(p, limits, extractor.as_deref());
            if let Ok(mut b) = batch.lock() {
                match &r {
                    Ok(_) => b.ok(),
                    Err(e) => b.fail(p.clone(), e),
                }
            }
            r.map_err(|e| format!("{}: {}", p.display(), crate::report::line(&e)))
        })
        .collect();
    if let Ok(b) = batch.into_inner() {
        b.finish("eval");
    }
    let mut rows = Vec::new();
    let mut feats = Vec::new();
    for r in results {
        match r {
            Ok((row, f)) => {
                rows.push(row);
                feats.extend(f);
            }
            Err(e) => problems.push(e),
        }
    }
    let mut set = SetMetrics::new();
    if let (Some(real), Some(ex)) = (&a.real, extractor.as_deref()) {
        let real_files = expand_images(std::slice::from_ref(real), "real image")?;
        let real_feats: Vec<Vec<f64>> = real_files
            .par_iter()
            .filter_map(|p| {
                load_rgb(p, limits)
                    .map_err(anyhow::Error::from)
                    .and_then(|img| ex.extract(&img).map_err(anyhow::Error::from))
                    .ok()
            })
            .collect();
        if real_feats.len() < real_files.len() {
            problems.push(format!(
                "{} real image(s) unreadable and left out of the distances",
                real_files.len() - real_feats.len()
            ));
        }
        if feats.len() < 2 || real_feats.len() < 2 {
            bail!("the distances need at least 2 readable images on each side");
        }
        let label = if a.inception.is_some() {
            "fid"
        } else {
            "fd_ct"
        };
        set.insert(label.to_string(), frechet_distance(&feats, &real_feats)?);
        let (m, s) = kid(&feats, &real_feats, KID_SUBSETS, KID_SUBSET_SIZE, a.seed)?;
        let kid_label = if a.inception.is_some() {
            "kid"
        } else {
            "kid_ct"
        };
        set.insert(kid_label.to_string(), m);
        set.insert(format!("{kid_label}_std"), s);
        set.insert("n_images".to_string(), feats.len() as f64);
        set.insert("n_real".to_string(), real_feats.len() as f64);
        eprintln!("features: {} ({}-d)", ex.name(), ex.dim());
    }
    Ok((rows, set))
}

fn score_single(
    p: &Path,
    limits: &DecodeLimits,
    extractor: Option<&dyn FeatureExtractor>,
) -> Result<(Row, Option<Vec<f64>>)> {
    let img: Image = load_rgb(p, limits).with_context(|| format!("reading {}", p.display()))?;
    let mut row = Row {
        name: p
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        ..Row::default()
    };
    row.scores.insert("uiqm", uiqm(&img)?);
    row.scores.insert("uciqe", uciqe(&img)?);
    let f = extractor.map(|e| e.extract(&img)).transpose()?;
    Ok((row, f))
}

fn columns(rows: &[Row]) -> Vec<&'static str> {
    let mut cols: Vec<&'static str> = Vec::new();
    for r in rows {
        for k in r.scores.keys() {
            if !cols.contains(k) {
                cols.push(k);
            }
        }
    }
    let order = ["psnr", "ssim", "uiqm", "uciqe"];
    cols.sort_by_key(|c| order.iter().position(|o| o == c).unwrap_or(order.len()));
    cols
}

fn mean_of(rows: &[Row], col: &str) -> Option<f64> {
    let v: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.scores.get(col).copied())
        .filter(|v| v.is_finite())
        .collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn print_table(rows: &[Row], set: &SetMetrics) {
    let cols = columns(rows);
    let header: String = cols.iter().map(|c| format!("{c:>9}")).collect();
    println!("{:<24}{header}", "image");
    let mut sorted: Vec<&Row> = rows.iter().collect();
    sorted.sort_by(|a, b| a.name.cmp(&b.name));
    for r in sorted {
        let line: String = cols
            .iter()
            .map(|c| match r.scores.get(c) {
                Some(v) => format!("{v:>9.4}"),
                None => format!("{:>9}", "-"),
            })
            .collect();
        println!("{:<24}{line}", truncate(&r.name, 23));
    }
    let mean: String = cols
        .iter()
        .map(|c| match mean_of(rows, c) {
            Some(v) => format!("{v:>9.4}"),
            None => format!("{:>9}", "-"),
        })
        .collect();
    println!("{:<24}{mean}", format!("mean ({})", rows.len()));
    for (k, v) in set {
        println!("{k}: {v:.4}");
    }
}

fn truncate(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        s.chars().take(n).collect()
    }
}

fn write_json(path: &Path, rows: &[Row], set: &SetMetrics, problems: &[String]) -> Result<()> {
    let cols = columns(rows);
    let means: BTreeMap<&str, Option<f64>> = cols.iter().map(|c| (*c, mean_of(rows, c))).collect();
    let per_image: Vec<_> = rows
        .iter()
        .map(|r| json!({"image": r.name, "scores": r.scores}))
        .collect();
    let doc = json!({
        "count": rows.len(),
        "mean": means,
        "sets": set,
        "images": per_image,
        "not_scored": problems,
    });
    let text = serde_json::to_string_pretty(&doc)?;
    write_atomic(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let cols = columns(rows);
    let mut text = String::from("image");
    for c in &cols {
        text.push(',');
        text.push_str(c);
    }
    text.push('\n');
    let mut sorted: Vec<&Row> = rows.iter().collect();
    sorted.sort_by(|a, b| a.name.cmp(&b.name));
    for r in sorted {
        // Names are file stems; quote them so commas survive.
        text.push_str(&format!("\"{}\"", r.name.replace('"', "\"\"")));
        for c in &cols {
            text.push(',');
            if let Some(v) = r.scores.get(c) {
                text.push_str(&format!("{v}"));
            }
        }
        text.push('\n');
    }
    write_atomic(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

/// The user's InceptionV3 ONNX model (`--inception`).
#[cfg(feature = "onnx")]
fn inception(model: &Path) -> Result<Box<dyn FeatureExtractor>> {
    Ok(Box::new(
        uwnr_metrics::OnnxInception::load(model)
            .with_context(|| format!("loading Inception model {}", model.display()))?,
    ))
}

/// `--inception` in a build without ONNX models.
#[cfg(not(feature = "onnx"))]
fn inception(model: &Path) -> Result<Box<dyn FeatureExtractor>> {
    bail!(
        "{}: this build reads no ONNX models (build with the `onnx` feature, on by default)",
        model.display()
    )
}
