//! `uwnr water fit`: the waters of real pairs and the regressor that predicts a reference's
//! water ([`uwnr_model::water`]).

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result};
use rayon::prelude::*;
use uwnr_core::io::{DecodeLimits, load_rgb, write_atomic_bytes};
use uwnr_model::water::{BankEntry, Regressor, WaterBank, bank_entry, pair_psnr};

use crate::cli::{WaterAction, WaterArgs, WaterFitArgs};

pub fn run(a: &WaterArgs) -> Result<ExitCode> {
    match &a.action {
        WaterAction::Fit(f) => fit(f),
    }
}

/// The bank entries of one paired folder, named `FOLDER/NAME`.
fn entries(dir: &Path) -> Result<Vec<BankEntry>> {
    let found = uwnr_run::pairs::discover_pairs(dir, None)
        .with_context(|| format!("reading pairs of {}", dir.display()))?;
    let set = dir.file_name().map_or_else(
        || dir.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let limits = DecodeLimits::default();
    found
        .pairs
        .par_iter()
        .map(|p| {
            let clean = load_rgb(&p.clean, &limits)
                .with_context(|| format!("reading {}", p.clean.display()))?;
            let under = load_rgb(&p.underwater, &limits)
                .with_context(|| format!("reading {}", p.underwater.display()))?;
            bank_entry(format!("{set}/{}", p.name), &clean, &under)
                .with_context(|| format!("fitting the water of {}", p.underwater.display()))
        })
        .collect()
}

/// How the regressor's waters reproduce the pairs of `dir`: PSNR(predicted water on the clean
/// side, underwater side), and the strength of the rendered and the real pairs.
fn score(dir: &Path, regressor: &Regressor) -> Result<(usize, f64, f64, f64)> {
    let found = uwnr_run::pairs::discover_pairs(dir, None)
        .with_context(|| format!("reading pairs of {}", dir.display()))?;
    let limits = DecodeLimits::default();
    let rows: Vec<(f64, f64, f64)> = found
        .pairs
        .par_iter()
        .map(|p| -> Result<(f64, f64, f64)> {
            let clean = load_rgb(&p.clean, &limits)?;
            let under = load_rgb(&p.underwater, &limits)?;
            let u = uwnr_core::resize::fit_within(&under, uwnr_model::water::WATER_SIDE)?;
            let (w, h) = u.size();
            let c = uwnr_core::resize::resize_bilinear(&clean, w, h)?;
            let water = regressor.predict(&uwnr_model::water::water_features(&under)?);
            let render = water.apply(&c)?;
            Ok((
                f64::from(pair_psnr(&render, &u)?),
                f64::from(pair_psnr(&render, &c)?),
                f64::from(pair_psnr(&u, &c)?),
            ))
        })
        .collect::<Result<_>>()?;
    let n = rows.len().max(1) as f64;
    let mean = |f: fn(&(f64, f64, f64)) -> f64| rows.iter().map(f).sum::<f64>() / n;
    Ok((rows.len(), mean(|r| r.0), mean(|r| r.1), mean(|r| r.2)))
}

fn fit(a: &WaterFitArgs) -> Result<ExitCode> {
    let mut all = Vec::new();
    for dir in &a.pairs {
        let e = entries(dir)?;
        eprintln!("{}: {} pairs", dir.display(), e.len());
        all.extend(e);
    }
    let sources = a.pairs.iter().map(|p| p.display().to_string()).collect();
    let bank = WaterBank::fit(sources, all).context("fitting the water regressor")?;
    let json = serde_json::to_string_pretty(&bank)?;
    write_atomic_bytes(&a.output, json.as_bytes())
        .with_context(|| format!("writing {}", a.output.display()))?;
    println!(
        "set\tpairs\tpredicted water vs underwater (dB)\tstrength rendered (dB)\tstrength real (dB)"
    );
    for (dir, held_out) in a
        .pairs
        .iter()
        .map(|d| (d, false))
        .chain(a.check.iter().map(|d| (d, true)))
    {
        let (n, fit, rendered, real) = score(dir, &bank.regressor)?;
        println!(
            "{}{}\t{n}\t{fit:.2}\t{rendered:.2}\t{real:.2}",
            dir.display(),
            if held_out { " (held out)" } else { "" }
        );
    }
    eprintln!(
        "water bank of {} pairs written to {}",
        bank.entries.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
