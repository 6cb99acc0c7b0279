//! Self-reconstruction scores of the anchored variant's output stage alone (the network's
//! correction at zero, i.e. a fresh model) for several within-image depth strengths, with the
//! built-in depth prior: how much the depth response costs or gains where the reference is the
//! target. Prints PSNR / SSIM means per strength.
//!
//! `cargo run --release -p uwnr-model --example depth_strength -- PAIRS_DIR...`
//! (each with `clean/` and `underwater/`, matched by file name).

use std::path::Path;

use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_model::style::{anchor, colour_transfer, estimate_water, finish_with};

fn main() {
    let strengths = [0.0f32, 0.05, 0.1, 0.25, 0.5, 1.0];
    for dir in std::env::args().skip(1) {
        let dir = Path::new(&dir);
        let mut names: Vec<_> = std::fs::read_dir(dir.join("underwater"))
            .expect("underwater/")
            .filter_map(|e| e.ok().map(|e| e.file_name()))
            .collect();
        names.sort();
        let mut sums = vec![(0.0, 0.0); strengths.len()];
        let mut extra = vec![(0.0, 0.0); 3];
        let limits = DecodeLimits::default();
        for name in &names {
            let under = load_rgb(&dir.join("underwater").join(name), &limits).unwrap();
            let clean = load_rgb(&dir.join("clean").join(name), &limits).unwrap();
            let depth = uwnr_depth::builtin_depth(&clean).unwrap();
            let water = estimate_water(&under).unwrap();
            let (w, h) = clean.size();
            let lf_ref = uwnr_core::lightfield::light_field_for_with(
                &under,
                w,
                h,
                uwnr_core::lightfield::LightFieldMap::Absolute,
            )
            .unwrap();
            let a = anchor(&clean, &water, &lf_ref, |im| {
                Ok(uwnr_core::lightfield::light_field_for_with(
                    im,
                    w,
                    h,
                    uwnr_core::lightfield::LightFieldMap::Absolute,
                )?)
            })
            .unwrap();
            let a0 = colour_transfer(&clean, &water).unwrap();
            let raw = uwnr_core::Image::filled(w, h, 6, 0.0);
            {
                use uwnr_core::lightfield::{LightFieldMap, light_field_for_with};
                let lf_t = light_field_for_with(&under, w, h, LightFieldMap::Absolute).unwrap();
                let lf_a = light_field_for_with(&a0, w, h, LightFieldMap::Absolute).unwrap();
                let range = 2.40654f32;
                let mut corrected = a0.clone();
                for c in 0..3 {
                    let (t, s) = (lf_t.plane(c).to_vec(), lf_a.plane(c).to_vec());
                    for (i, v) in corrected.plane_mut(c).iter_mut().enumerate() {
                        let ratio = 10f32.powf((t[i] - s[i]) * range).clamp(0.5, 2.0);
                        *v = (*v * ratio).clamp(0.0, 1.0);
                    }
                }
                let restat = uwnr_baselines::reinhard::transfer_to_stats(
                    &corrected,
                    water.stats,
                    uwnr_baselines::ColourSpace::LAlphaBeta,
                )
                .unwrap();
                for (k, img) in [&a0, &corrected, &restat].iter().enumerate() {
                    extra[k].0 += uwnr_metrics::psnr(img, &under, 1.0).unwrap();
                    extra[k].1 += uwnr_metrics::ssim(img, &under, 1.0).unwrap();
                }
            }
            for (k, &s) in strengths.iter().enumerate() {
                let out = finish_with(&raw, &a, &depth, &water, None, s).unwrap();
                sums[k].0 += uwnr_metrics::psnr(&out, &under, 1.0).unwrap();
                sums[k].1 += uwnr_metrics::ssim(&out, &under, 1.0).unwrap();
            }
        }
        let n = names.len() as f64;
        println!("{} ({} pairs)", dir.display(), names.len());
        for (k, v) in extra.iter().enumerate() {
            println!(
                "  {}: {:.2} dB / {:.3}",
                ["anchor", "lf-corrected", "lf-corrected + restat"][k],
                v.0 / n,
                v.1 / n
            );
        }
        for (k, s) in strengths.iter().enumerate() {
            println!(
                "  local {s:.2}: {:.2} dB / {:.3}",
                sums[k].0 / n,
                sums[k].1 / n
            );
        }
    }
}
