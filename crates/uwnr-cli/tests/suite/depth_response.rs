//! The bundled model responds to depth as water does: the same scene farther away is closer to
//! the water's veiling light (the quadtree estimate of the reference's, as UISA uses it) and has
//! less contrast, monotonically, and the change from depth 0 to depth 1 is large. Checked on the
//! bundled samples at small sizes (fast) and, when `../shared/data/rgbd` is present, on real
//! RGB-D photos with their measured depth.

use std::path::{Path, PathBuf};

use crate::common::{root, sample};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::{Depth, DepthUnit};
use uwnr_model::{DepthResponse, Network, RenderOptions};

/// Smallest mean change between depth 0 and depth 1, in code values.
const MIN_CHANGE: f64 = 15.0;
const DEPTHS: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];

fn bundled() -> Network {
    uwnr_model::bundled_network()
        .expect("this build bundles the default model")
        .unwrap()
}

fn small(path: &Path, long_side: usize) -> Image {
    let img = load_rgb(path, &DecodeLimits::default()).unwrap();
    let (w, h) = img.size();
    let s = long_side as f64 / w.max(h) as f64;
    let (nw, nh) = (
        ((w as f64 * s).round() as usize).max(1),
        ((h as f64 * s).round() as usize).max(1),
    );
    resize_bilinear(&img, nw, nh).unwrap()
}

fn luminance_std(img: &Image) -> f64 {
    let n = img.width() * img.height();
    let l: Vec<f64> = (0..n)
        .map(|i| {
            0.299 * f64::from(img.plane(0)[i])
                + 0.587 * f64::from(img.plane(1)[i])
                + 0.114 * f64::from(img.plane(2)[i])
        })
        .collect();
    let m = l.iter().sum::<f64>() / n as f64;
    (l.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n as f64).sqrt()
}

/// Mean RGB distance to `veil` over the pixels `keep` selects.
fn distance_to(img: &Image, veil: [f64; 3], keep: impl Fn(usize) -> bool) -> f64 {
    let n = img.width() * img.height();
    let (mut sum, mut count) = (0.0, 0usize);
    for i in (0..n).filter(|&i| keep(i)) {
        let d2: f64 = (0..3)
            .map(|c| (f64::from(img.plane(c)[i]) - veil[c]).powi(2))
            .sum();
        sum += d2.sqrt();
        count += 1;
    }
    sum / count.max(1) as f64
}

/// The veiling light the model's water stage moves far scenes towards: the reference's water's
/// (for the water anchor `b / (1 - a)` of its gain and offset; for the Reinhard anchor the
/// quadtree search's).
fn model_veil(style: &uwnr_model::ReferenceStyle) -> [f64; 3] {
    style
        .water
        .as_ref()
        .expect("the anchored model has a water")
        .veil
        .map(f64::from)
}

fn mean_change(a: &Image, b: &Image) -> f64 {
    a.data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| f64::from((x - y).abs()))
        .sum::<f64>()
        / a.data().len() as f64
        * 255.0
}

/// Renders `clean` at every constant depth of [`DEPTHS`] and checks the response.
fn check_constant_depths(net: &Network, clean: &Image, reference: &Image, what: &str) {
    let style = net.style(reference).unwrap();
    let veil = model_veil(&style);
    let (w, h) = clean.size();
    // Constant maps are absolute depths (a scene that far away), not relative ones.
    let absolute = RenderOptions {
        depth: uwnr_model::DepthResponse::absolute(),
        ..Default::default()
    };
    let renders: Vec<Image> = DEPTHS
        .iter()
        .map(|&d| {
            net.render(clean, &Image::filled(w, h, 1, d), &style, &absolute)
                .unwrap()
        })
        .collect();
    let change = mean_change(&renders[0], &renders[DEPTHS.len() - 1]);
    let stds: Vec<f64> = renders.iter().map(luminance_std).collect();
    let dists: Vec<f64> = renders
        .iter()
        .map(|r| distance_to(r, veil, |_| true))
        .collect();
    eprintln!(
        "{what}: change 0->1 {change:.1}/255, luminance std {stds:.3?}, distance to veil {dists:.3?}"
    );
    assert!(
        change >= MIN_CHANGE,
        "{what}: depth 0 vs 1 changes {change:.1}/255"
    );
    for k in 1..DEPTHS.len() {
        assert!(
            stds[k] < stds[k - 1],
            "{what}: contrast rises at depth {}",
            DEPTHS[k]
        );
        assert!(
            dists[k] < dists[k - 1],
            "{what}: moves away from the veil at depth {}",
            DEPTHS[k]
        );
    }
}

#[test]
fn the_bundled_model_responds_to_depth_on_the_samples() {
    let net = bundled();
    for clean in ["clean-room.jpg", "clean-statues.jpg"] {
        let c = small(&sample(clean), 160);
        for reference in ["ref-green.png", "ref-blue.jpg"] {
            let r = load_rgb(&sample(reference), &DecodeLimits::default()).unwrap();
            check_constant_depths(&net, &c, &r, &format!("{clean} with {reference}"));
        }
    }
}

fn rgbd_dir() -> PathBuf {
    root().join("../shared/data/rgbd")
}

/// Largest median depth effect (`uwnr_metrics::depth_effect`) allowed with measured depth:
/// inside the physical baselines' range (0.56-0.76 in `examples/depth_effect.rs`).
const MAX_DEPTH_EFFECT: f64 = 0.8;

#[test]
fn with_real_depth_far_parts_are_hazier_than_near_ones() {
    let dir = rgbd_dir();
    if !dir.is_dir() {
        eprintln!("skipped: {} is absent", dir.display());
        return;
    }
    let net = bundled();
    let limits = DecodeLimits::default();
    let cases = [
        ("nyu/rgb/rgb_00000.jpg", "nyu/depth/sync_depth_00000.png"),
        ("nyu/rgb/rgb_00050.jpg", "nyu/depth/sync_depth_00050.png"),
        ("nyu/rgb/rgb_00100.jpg", "nyu/depth/sync_depth_00100.png"),
    ];
    let mut effects = Vec::new();
    for reference in ["ref-green.png", "ref-blue.jpg"] {
        let reference = load_rgb(&sample(reference), &limits).unwrap();
        let style = net.style(&reference).unwrap();
        let veil = model_veil(&style);
        for (rgb, depth) in cases {
            let clean = small(&dir.join(rgb), 256);
            // NYU stores millimetres: the scene's metres act, fully trusted.
            let d = Depth::from_file(
                &dir.join(depth),
                clean.size(),
                DepthUnit::Millimetres,
                &limits,
            )
            .unwrap();
            let response = DepthResponse::for_depth(&d, 4.0, 0.0);
            assert_eq!(response.trust, 1.0, "a measured map is trusted");
            let opts = RenderOptions {
                depth: response,
                ..Default::default()
            };
            let real = net.render(&clean, &d.map, &style, &opts).unwrap();
            // The same scene with every pixel at the map's mean distance.
            let dv = d.map.plane(0);
            let mean = dv.iter().sum::<f32>() / dv.len() as f32;
            let (w, h) = clean.size();
            let flat = Image::filled(w, h, 1, mean);
            let still = net.render(&clean, &flat, &style, &opts).unwrap();
            let effect = uwnr_metrics::depth_effect(&clean, &real, &still, &d.map)
                .unwrap()
                .expect("measurable");
            // Relative to the scene at its mean depth: far parts move towards the veil, near
            // parts away from it.
            let (far, near) = (|i: usize| dv[i] > mean * 1.2, |i: usize| dv[i] < mean * 0.8);
            let far_shift = distance_to(&real, veil, far) - distance_to(&still, veil, far);
            let near_shift = distance_to(&real, veil, near) - distance_to(&still, veil, near);
            eprintln!(
                "{rgb}: depth effect {effect:.3}, far {far_shift:+.4}, near {near_shift:+.4}"
            );
            assert!(far_shift < 0.0, "{rgb}: far parts not hazier ({far_shift})");
            assert!(
                near_shift > 0.0,
                "{rgb}: near parts not clearer ({near_shift})"
            );
            effects.push(effect);
        }
    }
    effects.sort_by(f64::total_cmp);
    let median = effects[effects.len() / 2];
    assert!(
        median <= MAX_DEPTH_EFFECT,
        "median depth effect {median:.3} > {MAX_DEPTH_EFFECT}: {effects:?}"
    );
    // Constant maps still act as a scene that far away.
    let reference = load_rgb(&sample("ref-green.png"), &limits).unwrap();
    check_constant_depths(
        &net,
        &small(&dir.join(cases[0].0), 192),
        &reference,
        cases[0].0,
    );
}
