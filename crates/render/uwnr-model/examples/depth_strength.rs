//! Self-reconstruction scores of the anchored variant's pipeline with the network's correction
//! at zero (a fresh model), with the built-in depth prior: the Reinhard transfer alone, with
//! light-field retention, with retention then the statistics matched again, with detail
//! retention after light-field retention (alone and with the shipped depth stage), and the full
//! pipeline, with and without detail retention, for several trusts in the prior's depth
//! differences (`uwnr render --prior-trust`) at the default scene scale. Prints PSNR / SSIM
//! means.
//!
//! `cargo run --release -p uwnr-model --example depth_strength -- PAIRS_DIR...`
//! (each with `clean/` and `underwater/`, matched by file name).

use std::path::Path;

use uwnr_baselines::ColourSpace;
use uwnr_baselines::reinhard::transfer_to_stats;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_core::lightfield::{LightFieldMap, light_field_for_with};
use uwnr_model::finish::{DepthResponse, finish};
use uwnr_model::style::{anchor, colour_transfer, detail_share, estimate_water, retain_detail};

/// Trusts in the prior; 0.075 is the shipped one (`PRIOR_TRUST`).
const TRUSTS: [f32; 7] = [0.0, 0.075, 0.15, 0.375, 0.75, 1.0, 1.5];
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
        let mut trusts = [(0.0, 0.0); TRUSTS.len()];
        let mut detail_trusts = [(0.0, 0.0); TRUSTS.len()];
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
            let shipped = DepthResponse::default();
            let detail_depth =
                finish(raw.clone(), detail.clone(), &depth, &water, &shipped).unwrap();
            for (sum, img) in steps
                .iter_mut()
                .zip([&transfer, &a, &again, &detail, &detail_depth])
            {
                score(sum, img, &under);
            }
            for (k, &trust) in TRUSTS.iter().enumerate() {
                let response = DepthResponse { trust, ..shipped };
                let out = finish(raw.clone(), a.clone(), &depth, &water, &response).unwrap();
                score(&mut trusts[k], &out, &under);
                let out = finish(raw.clone(), detail.clone(), &depth, &water, &response).unwrap();
                score(&mut detail_trusts[k], &out, &under);
            }
        }
        let n = names.len() as f64;
        println!("{} ({} pairs)", dir.display(), names.len());
        for (name, v) in STEPS.iter().zip(&steps) {
            println!("  {name}: {:.2} dB / {:.3}", v.0 / n, v.1 / n);
        }
        for ((t, v), d) in TRUSTS.iter().zip(&trusts).zip(&detail_trusts) {
            println!(
                "  + depth stage, prior trust {t:.3}: {:.2} dB / {:.3}; with detail retention {:.2} dB / {:.3}",
                v.0 / n,
                v.1 / n,
                d.0 / n,
                d.1 / n
            );
        }
    }
}
