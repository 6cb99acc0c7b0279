//! How distance acts within a render, measured on real RGB-D photos: the depth effect of
//! `uwnr_metrics::depth_effect` (far/near contrast kept with the real map over the same with a
//! constant map at the map's mean; 1 = distance does nothing, below 1 = farther is hazier) for
//! every method, over the dense photos of `../shared/data/rgbd` (NYU-v2, Redwood, SUN RGB-D)
//! and four real underwater references of different waters. Also: whether the far parts move
//! towards the reference's veiling light, and the photos' measured distances. Prints Markdown.
//!
//! Run from the repository root with `../shared/data` present:
//! `cargo run --release -p uwnr-cli --example depth_effect`

use std::path::{Path, PathBuf};
use std::sync::Arc;

use uwnr_baselines::{BackgroundPick, Method, RenderInput, quadtree_background};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_depth::{Depth, DepthUnit};
use uwnr_model::{DepthResponse, RenderOptions, style};
use uwnr_render::{MethodKind, MethodSpec, PreparedReference, Renderer};

const DATA: &str = "../shared/data";
/// Photos with dense measured depth, and the unit their maps are stored in (SUN RGB-D's sample
/// stores its millimetres bit-rotated, so it is read as a relative map).
const PHOTOS: [(&str, DepthUnit); 3] = [
    ("nyu", DepthUnit::Millimetres),
    ("redwood", DepthUnit::Millimetres),
    ("sunrgbd", DepthUnit::Relative),
];
/// References of four waters: blue, green, hazy, and an ordinary RUIE scene.
const REFERENCES: [&str; 4] = [
    "references/ruie-uccs/blue/blue_00.jpg",
    "references/ruie-uccs/green/green_00.jpg",
    "references/u45/haze/31.png",
    "references/ruie-uiqs-a/A_00380.jpg",
];

/// One photo: the clean image, its measured depth as the method reads it (metric where the unit
/// is), and the same normalised per image.
struct Photo {
    name: String,
    clean: Image,
    metric: Depth,
    relative: Depth,
}

fn photos() -> Vec<Photo> {
    let limits = DecodeLimits::default();
    let mut out = Vec::new();
    for (set, unit) in PHOTOS {
        let dir = Path::new(DATA).join("rgbd").join(set);
        let mut rgbs: Vec<PathBuf> = std::fs::read_dir(dir.join("rgb"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        rgbs.sort();
        let maps: Vec<PathBuf> = std::fs::read_dir(dir.join("depth"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        for rgb in rgbs {
            let clean = load_rgb(&rgb, &limits).unwrap();
            let map = uwnr_depth::partner_map(&rgb, &maps).expect("a depth map");
            let metric = Depth::from_file(map, clean.size(), unit, &limits).unwrap();
            let relative =
                Depth::from_file(map, clean.size(), DepthUnit::Relative, &limits).unwrap();
            out.push(Photo {
                name: format!("{set}/{}", rgb.file_name().unwrap().to_string_lossy()),
                clean,
                metric,
                relative,
            });
        }
    }
    out
}

/// The same depth with every value at the map's mean.
fn constant(d: &Depth) -> Depth {
    let (w, h) = d.map.size();
    let m = d.map.plane(0).iter().map(|&v| f64::from(v)).sum::<f64>() / (w * h) as f64;
    Depth {
        map: Image::filled(w, h, 1, m as f32),
        ..d.clone()
    }
}

/// Mean RGB distance to `veil` over the farthest (`far`) or nearest quarter of pixels.
fn veil_distance(img: &Image, depth: &Image, veil: [f64; 3], far: bool) -> f64 {
    let d = depth.plane(0);
    let mut order: Vec<usize> = (0..d.len()).collect();
    order.sort_by(|&a, &b| d[a].total_cmp(&d[b]));
    let q = d.len() / 4;
    let part = if far {
        &order[d.len() - q..]
    } else {
        &order[..q]
    };
    part.iter()
        .map(|&i| {
            (0..3)
                .map(|c| (f64::from(img.plane(c)[i]) - veil[c]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .sum::<f64>()
        / q.max(1) as f64
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// A row of the table: how it renders a photo with a depth.
type RenderFn<'a> = Box<dyn Fn(&Image, &Depth, &Image, usize) -> Image + 'a>;

fn main() {
    if !Path::new(DATA).join("rgbd").is_dir() {
        eprintln!("skipped: {DATA}/rgbd is absent");
        return;
    }
    let limits = DecodeLimits::default();
    let photos = photos();
    let refs: Vec<Image> = REFERENCES
        .iter()
        .map(|r| load_rgb(&Path::new(DATA).join(r), &limits).unwrap())
        .collect();
    let net = uwnr_model::bundled_network()
        .expect("a build with the bundled model")
        .unwrap();
    let styles: Vec<_> = refs.iter().map(|r| net.style(r).unwrap()).collect();
    let (gan, _, _) = uwnr_gan::generator_or_bundled(None).unwrap();
    // The model's stages alone (no water's effects), as v5 rendered.
    let render_stages = |clean: &Image, depth: &Depth, r: usize, response: DepthResponse| {
        net.render(
            clean,
            &depth.map,
            &styles[r],
            &RenderOptions {
                depth: response,
                ..RenderOptions::default()
            },
        )
        .unwrap()
    };
    // What `uwnr render` runs: the bundled model with the water's effects after it.
    // UWNR_EFFECTS='{"particles": 0, ...}' measures another setting of the effects.
    let mut spec = MethodSpec::defaults(MethodKind::Uwnr, true);
    if let (Ok(json), MethodSpec::Uwnr(s)) = (std::env::var("UWNR_EFFECTS"), &mut spec) {
        s.effects = serde_json::from_str(&json).expect("UWNR_EFFECTS: a WaterEffects JSON");
        eprintln!("effects: {json}");
    }
    let uwnr = Renderer::load(spec).unwrap();
    let prepared: Vec<PreparedReference> = refs
        .iter()
        .map(|r| uwnr.prepare_reference(Arc::new(r.clone())).unwrap())
        .collect();
    let worker = uwnr.worker();
    let render_uwnr = |clean: &Image, depth: &Depth, r: usize, response: DepthResponse| {
        worker
            .render(
                clean,
                &depth.map,
                &response,
                Some(prepared[r].input()),
                r as u64,
            )
            .unwrap()
            .image
    };
    let baseline = |m: &Method, clean: &Image, depth: &Depth, reference: &Image, seed: u64| {
        let input = RenderInput {
            clean,
            depth: &depth.map,
            reference: Some(reference),
        };
        uwnr_baselines::render(m, &input, seed).unwrap().image
    };
    let scene = style::DEFAULT_SCENE_SCALE_M;
    // (row, reads the metric map, render)
    let methods: Vec<(&str, bool, RenderFn<'_>)> = vec![
        (
            "`uwnr`, metric map (`--depth-unit mm`), trusted",
            true,
            Box::new(|c, d, _, r| render_uwnr(c, d, r, DepthResponse::for_depth(d, scene, 1.0))),
        ),
        (
            "`uwnr`, metric map, trusted, the model's stages alone (no water's effects)",
            true,
            Box::new(|c, d, _, r| render_stages(c, d, r, DepthResponse::for_depth(d, scene, 1.0))),
        ),
        (
            "`uwnr`, normalised map (`--depth-normalize`), trusted, 4 m",
            false,
            Box::new(|c, d, _, r| render_uwnr(c, d, r, DepthResponse::for_depth(d, scene, 1.0))),
        ),
        (
            "`uwnr`, normalised map at the prior's trust (v4's response)",
            false,
            Box::new(|c, d, _, r| {
                render_uwnr(
                    c,
                    d,
                    r,
                    DepthResponse {
                        trust: style::PRIOR_TRUST,
                        ..DepthResponse::for_depth(d, scene, 1.0)
                    },
                )
            }),
        ),
        (
            "`reinhard`",
            false,
            Box::new(|c, d, reference, _| {
                baseline(&Method::Reinhard(Default::default()), c, d, reference, 0)
            }),
        ),
        (
            "`jerlov`",
            false,
            Box::new(|c, d, reference, r| {
                baseline(
                    &Method::Jerlov(Default::default()),
                    c,
                    d,
                    reference,
                    r as u64,
                )
            }),
        ),
        (
            "`uisa`",
            false,
            Box::new(|c, d, reference, _| {
                baseline(&Method::Uisa(Default::default()), c, d, reference, 0)
            }),
        ),
        (
            "`seathru` (from the reference)",
            false,
            Box::new(|c, d, reference, _| {
                let p = uwnr_baselines::SeathruParams {
                    coefficients: uwnr_baselines::SeathruCoefficients::FromReference(
                        Default::default(),
                    ),
                    ..Default::default()
                };
                baseline(&Method::Seathru(p), c, d, reference, 0)
            }),
        ),
        (
            "`uwgan`",
            false,
            Box::new(|c, d, _, r| uwnr_gan::render(&gan, c, &d.map, r as u64).unwrap()),
        ),
    ];

    println!(
        "| method | depth effect, median (min-max) | far part nearer the veil than near part, renders |"
    );
    println!("|---|---|---|");
    for (name, metric, render) in &methods {
        let (mut effects, mut towards, mut total) = (Vec::new(), 0usize, 0usize);
        for p in &photos {
            let depth = if *metric { &p.metric } else { &p.relative };
            let flat = constant(depth);
            for (r, reference) in refs.iter().enumerate() {
                let real = render(&p.clean, depth, reference, r);
                let still = render(&p.clean, &flat, reference, r);
                if let Some(e) =
                    uwnr_metrics::depth_effect(&p.clean, &real, &still, &depth.map).unwrap()
                {
                    effects.push(e);
                }
                let veil = quadtree_background(reference, 0.01, BackgroundPick::Mean).unwrap();
                // Relative to the constant-map render: far parts closer to the veil, near ones
                // farther from it.
                let far = veil_distance(&real, &depth.map, veil, true)
                    - veil_distance(&still, &depth.map, veil, true);
                let near = veil_distance(&real, &depth.map, veil, false)
                    - veil_distance(&still, &depth.map, veil, false);
                total += 1;
                towards += usize::from(far < near);
            }
        }
        let lo = effects.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = effects.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        println!(
            "| {name} | {:.2} ({lo:.2}-{hi:.2}) | {towards} of {total} |",
            median(effects.clone())
        );
    }

    println!();
    println!("| photo | measured depth (m) |");
    println!("|---|---|");
    for p in &photos {
        let range = p.metric.metric_max.map_or_else(
            || "relative".to_string(),
            |m| {
                let lo = p.metric.map.plane(0).iter().copied().fold(1.0f32, f32::min);
                format!("{:.1}-{:.1}", lo * m, m)
            },
        );
        println!("| {} | {range} |", p.name);
    }
}
