//! Self-reconstruction scores of the anchored variant's pipeline with the network's correction
//! at zero (a fresh model), with the built-in depth prior: the Reinhard transfer alone, with
//! light-field retention, with retention then the statistics matched again, with detail
//! retention after light-field retention (alone and with the shipped depth stage), and the full
//! pipeline without detail retention for several within-image depth strengths. Prints PSNR /
//! SSIM means.
//!
//! `cargo run --release -p uwnr-model --example depth_strength -- PAIRS_DIR...`
//! (each with `clean/` and `underwater/`, matched by file name).

use std::path::Path;

use uwnr_baselines::ColourSpace;
use uwnr_baselines::reinhard::transfer_to_stats;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_core::lightfield::{LightFieldMap, light_field_for_with};
use uwnr_model::style::{
    LOCAL_DEPTH_STRENGTH, anchor, colour_transfer, detail_share, estimate_water, finish_with,
    retain_detail,
};

const STRENGTHS: [f32; 6] = [0.0, 0.05, 0.1, 0.25, 0.5, 1.0];
const STEPS: [&str; 5] = [
    "Reinhard transfer",
    "+ light-field retention",
    "+ statistics again",
    "+ light-field and detail retention",
    "+ light-field and detail retention + depth stage (shipped strength)",
];

fn score(sum: &mut (f64, f64), out: &Image, target: &Image) {
    sum.0 += uwnr_metrics::psnr(out, target, 1.0).unwrap();
    sum.1 += uwnr_metrics::ssim(out, target, 1.0).unwrap();
}

fn main() {
    let limits = DecodeLimits::default();
    for dir in std::env::args().skip(1) {
        let dir = Path::new(&dir);
        let mut names: Vec<_> = std::fs::read_dir(dir.join("underwater"))
            .expect("underwater/")
            .filter_map(|e| e.ok().map(|e| e.file_name()))
            .collect();
        names.sort();
        let mut steps = [(0.0, 0.0); STEPS.len()];
        let mut strengths = [(0.0, 0.0); STRENGTHS.len()];
        for name in &names {
            let under = load_rgb(&dir.join("underwater").join(name), &limits).unwrap();
            let clean = load_rgb(&dir.join("clean").join(name), &limits).unwrap();
            let (w, h) = clean.size();
            let lf = |im: &Image| light_field_for_with(im, w, h, LightFieldMap::Absolute);
            let depth = uwnr_depth::builtin_depth(&clean).unwrap();
            let water = estimate_water(&under).unwrap();
            let reference_lf = lf(&under).unwrap();
            let transfer = colour_transfer(&clean, &water).unwrap();
            let a = anchor(&clean, &water, &reference_lf, |im| Ok(lf(im)?)).unwrap();
            let again = transfer_to_stats(&a, water.stats, ColourSpace::LAlphaBeta).unwrap();
            let detail = retain_detail(a.clone(), detail_share(&under)).unwrap();
            let raw = Image::filled(w, h, 6, 0.0);
            let detail_depth = finish_with(
                raw.clone(),
                detail.clone(),
                &depth,
                &water,
                None,
                LOCAL_DEPTH_STRENGTH,
            )
            .unwrap();
            for (sum, img) in steps
                .iter_mut()
                .zip([&transfer, &a, &again, &detail, &detail_depth])
            {
                score(sum, img, &under);
            }
            for (sum, &s) in strengths.iter_mut().zip(&STRENGTHS) {
                let out = finish_with(raw.clone(), a.clone(), &depth, &water, None, s).unwrap();
                score(sum, &out, &under);
            }
        }
        let n = names.len() as f64;
        println!("{} ({} pairs)", dir.display(), names.len());
        for (name, v) in STEPS.iter().zip(&steps) {
            println!("  {name}: {:.2} dB / {:.3}", v.0 / n, v.1 / n);
        }
        for (s, v) in STRENGTHS.iter().zip(&strengths) {
            println!(
                "  + depth stage, strength {s:.2}: {:.2} dB / {:.3}",
                v.0 / n,
                v.1 / n
            );
        }
    }
}
