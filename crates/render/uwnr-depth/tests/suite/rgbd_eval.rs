//! How well the built-in prior ranks true depth, compared with the plain vertical ramp, on the
//! RGB-D images of `../shared/data/rgbd` (NYU-v2 and Redwood: 16-bit millimetres; KITTI: sparse
//! LiDAR, metres x 256; SUN RGB-D: 16-bit). Pixels without depth (0, or 65535) are skipped.
//!
//! Run: `cargo test -p uwnr-depth --test suite rgbd_eval -- --ignored --nocapture`
//! (fails, naming the folder, when the data folder is absent).

use std::path::{Path, PathBuf};
use std::time::Instant;

use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_gray, load_rgb};
use uwnr_depth::builtin_depth;

/// Sub-folders of `rgbd/`, each with `rgb/` and `depth/` listed in the same order.
const DATASETS: [&str; 4] = ["nyu", "redwood", "kitti", "sunrgbd"];

fn data_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/data/rgbd")
}

fn sorted_images(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p| is_image_path(p));
    files.sort();
    files
}

/// Ranks with ties averaged (1-based).
fn ranks(values: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut out = vec![0.0; values.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && values[order[j + 1]] == values[order[i]] {
            j += 1;
        }
        let rank = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            out[k] = rank;
        }
        i = j + 1;
    }
    out
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

fn spearman(a: &[f64], b: &[f64]) -> f64 {
    pearson(&ranks(a), &ranks(b))
}

/// `1 - (y + 0.5) / h`: the plain ground-plane ramp, far at the top.
fn vertical_ramp(width: usize, height: usize) -> Image {
    let data = (0..height)
        .flat_map(|y| std::iter::repeat_n(1.0 - (y as f32 + 0.5) / height as f32, width))
        .collect();
    Image::from_planar(width, height, 1, data).unwrap()
}

/// (Spearman, Pearson) of `pred` with the valid pixels of `truth`.
fn correlations(pred: &Image, truth: &Image) -> (f64, f64) {
    let (mut p, mut t) = (Vec::new(), Vec::new());
    for (&d, &v) in pred.plane(0).iter().zip(truth.plane(0)) {
        if v > 0.0 && v < 1.0 {
            p.push(f64::from(d));
            t.push(f64::from(v));
        }
    }
    (spearman(&p, &t), pearson(&p, &t))
}

/// Correlations of one image: (Spearman, Pearson) for each map.
struct Row {
    set: &'static str,
    ramp: (f64, f64),
    builtin: (f64, f64),
}

#[test]
#[ignore = "needs ../shared/data/rgbd; run with --ignored --nocapture to print the table"]
fn builtin_against_vertical_ramp() {
    let root = data_root();
    assert!(root.is_dir(), "{} not found", root.display());
    let limits = DecodeLimits::default();
    let mut rows = Vec::new();
    println!(
        "{:<10} {:<22} {:>9} {:>9} {:>9} {:>9} {:>8}",
        "dataset", "image", "ramp rho", "ramp r", "built rho", "built r", "ms"
    );
    for set in DATASETS {
        let rgb = sorted_images(&root.join(set).join("rgb"));
        let depth = sorted_images(&root.join(set).join("depth"));
        assert_eq!(rgb.len(), depth.len(), "{set}: rgb and depth counts differ");
        for (rgb_path, depth_path) in rgb.iter().zip(&depth) {
            let clean = load_rgb(rgb_path, &limits).unwrap();
            let truth = load_gray(depth_path, &limits).unwrap();
            assert_eq!(clean.size(), truth.size(), "{}", rgb_path.display());
            let start = Instant::now();
            let built = builtin_depth(&clean).unwrap();
            let ms = start.elapsed().as_secs_f64() * 1e3;
            let ramp = vertical_ramp(clean.width(), clean.height());
            let (rs, rp) = correlations(&ramp, &truth);
            let (bs, bp) = correlations(&built, &truth);
            let name = rgb_path.file_name().unwrap().to_string_lossy().into_owned();
            println!("{set:<10} {name:<22} {rs:>9.3} {rp:>9.3} {bs:>9.3} {bp:>9.3} {ms:>8.1}");
            rows.push(Row {
                set,
                ramp: (rs, rp),
                builtin: (bs, bp),
            });
        }
    }
    for (label, indoor_only) in [("all", false), ("indoor", true)] {
        let kept: Vec<&Row> = rows
            .iter()
            .filter(|r| !indoor_only || r.set != "kitti")
            .collect();
        let mean = |f: fn(&Row) -> f64| kept.iter().map(|r| f(r)).sum::<f64>() / kept.len() as f64;
        println!(
            "mean over {label:<6} ({:>2} images): ramp rho {:.3} r {:.3} | builtin rho {:.3} r {:.3}",
            kept.len(),
            mean(|r| r.ramp.0),
            mean(|r| r.ramp.1),
            mean(|r| r.builtin.0),
            mean(|r| r.builtin.1),
        );
    }
    let mean = |f: fn(&Row) -> f64| rows.iter().map(f).sum::<f64>() / rows.len() as f64;
    let (ramp_rho, built_rho) = (mean(|r| r.ramp.0), mean(|r| r.builtin.0));
    // The prior must rank depth clearly better than chance and not far below the ramp.
    assert!(built_rho > 0.4, "builtin mean Spearman {built_rho}");
    assert!(
        built_rho > ramp_rho - 0.05,
        "builtin {built_rho} vs ramp {ramp_rho}"
    );
}

#[test]
fn rank_helpers() {
    assert_eq!(ranks(&[3.0, 1.0, 2.0, 1.0]), vec![4.0, 1.5, 3.0, 1.5]);
    assert!((spearman(&[1.0, 2.0, 3.0], &[1.0, 4.0, 9.0]) - 1.0).abs() < 1e-12);
    assert!((pearson(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
}
