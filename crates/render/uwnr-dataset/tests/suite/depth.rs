//! Depth in a dataset run: maps found beside the clean images (`X/rgb/` + `X/depth/`), read in
//! their unit, fitted with the image, trusted; the scene scale drawn per pair and recorded;
//! the whole deterministic; an older folder without a depth policy is not resumed with new
//! renders.

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::{save_gray16, save_rgb};
use uwnr_dataset::{Renderer, Size};
use uwnr_depth::DepthUnit;
use uwnr_model::weights::keys::seeded_tensors;
use uwnr_model::{Backend, GeneratorConfig, Network, RenderOptions};
use uwnr_render::DepthPolicy;

use crate::common::{assert_same_tree, opts, run, spec, texture};

/// A fresh anchored network (its output is the anchor, then the depth stage).
fn network() -> Renderer {
    let config = GeneratorConfig::anchored(8);
    let (net, _) =
        Network::from_tensors(&config, seeded_tensors(&config, 1), &Backend::Engine).unwrap();
    Renderer::network(net, RenderOptions::default(), "fresh".into(), b"fresh")
}

/// `root/set/rgb/rgb_0000K.png` with `root/set/depth/sync_depth_0000K.png` (16-bit millimetres,
/// 1 m in the left quarter, 3 m elsewhere; zeros along the top row are holes), and one clean image
/// without depth in `root/plain/`. Returns the references' folder.
fn rgbd_inputs(root: &Path) -> std::path::PathBuf {
    let (rgb, depth, plain, refs) = (
        root.join("set/rgb"),
        root.join("set/depth"),
        root.join("plain"),
        root.join("refs"),
    );
    for d in [&rgb, &depth, &plain, &refs] {
        std::fs::create_dir_all(d).unwrap();
    }
    let (w, h) = (40, 24);
    for k in 0..2 {
        save_rgb(
            &rgb.join(format!("rgb_0000{k}.png")),
            &texture(w, h, k, [1.0, 0.9, 0.8]),
        )
        .unwrap();
        let mm: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let v = if y == 0 {
                    0.0
                } else if x < w / 4 {
                    1000.0
                } else {
                    3000.0
                };
                v / 65535.0
            })
            .collect();
        save_gray16(
            &depth.join(format!("sync_depth_0000{k}.png")),
            &Image::from_planar(w, h, 1, mm).unwrap(),
        )
        .unwrap();
    }
    save_rgb(&plain.join("p.png"), &texture(w, h, 9, [0.9, 0.9, 0.7])).unwrap();
    for j in 0..2 {
        save_rgb(
            &refs.join(format!("r{j}.png")),
            &texture(32, 24, 50 + j, [0.2, 0.6, 0.7]),
        )
        .unwrap();
    }
    refs
}

fn records(out: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(out.join("manifest.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn measured_depth_beside_the_photos_is_read_in_metres_and_recorded() {
    let tmp = tempfile::tempdir().unwrap();
    let refs = rgbd_inputs(tmp.path());
    let mut s = spec(&tmp.path().join("set"), &refs, 2);
    s.clean.push(tmp.path().join("plain"));
    s.save_lightfield = false;
    s.depth_policy = DepthPolicy {
        unit: DepthUnit::Millimetres,
        ..DepthPolicy::default()
    };
    let renderer = network();
    let out = tmp.path().join("out");
    let summary = run(&out, &s, &renderer, &opts(2));
    assert!(summary.ok(), "{:?}", summary.failures);
    // The depth maps are not taken for photos: 2 RGB-D images and the plain one.
    assert_eq!(summary.rendered, 6);
    let recs = records(&out);
    let (lo, hi) = DepthPolicy::default().scene_scale_m;
    let mut scales = Vec::new();
    for r in &recs {
        let depth = &r["params"]["depth"];
        if r["clean_source"].as_str().unwrap().contains("rgb_") {
            // Metres: the map's farthest is 3 m (holes filled, not read as 0 m).
            assert_eq!(depth["scale"], "metric", "{r}");
            assert_eq!(depth["max_m"], 3.0);
            assert_eq!(depth["trust"], 1.0);
        } else {
            assert_eq!(depth["scale"], "relative", "{r}");
            let m = depth["scene_m"].as_f64().unwrap() as f32;
            assert!((lo..=hi).contains(&m), "{m}");
            scales.push(m);
            assert_eq!(
                depth["trust"].as_f64().unwrap(),
                f64::from(uwnr_dataset::DATASET_PRIOR_TRUST)
            );
        }
    }
    assert_eq!(scales.len(), 2);
    assert_ne!(scales[0], scales[1], "the scene scale is drawn per pair");
    // The saved map is the one used: the near quarter darker (nearer) than the rest.
    let saved = uwnr_core::io::load_gray(
        &out.join(recs[0]["depth"].as_str().unwrap()),
        &uwnr_core::io::DecodeLimits::default(),
    )
    .unwrap();
    let (w, h) = saved.size();
    let at = |x: usize, y: usize| saved.plane(0)[y * w + x];
    assert!(
        at(2, h / 2) < 0.5 && at(w - 3, h / 2) > 0.9,
        "{:?}",
        saved.plane(0)
    );
    let settings = std::fs::read_to_string(out.join("dataset.json")).unwrap();
    assert!(settings.contains("\"depth_policy\""), "{settings}");

    // The same command gives the same bytes.
    let again = tmp.path().join("again");
    run(&again, &s, &renderer, &opts(1));
    assert_same_tree(&out, &again);
}

#[test]
fn maps_are_fitted_with_their_image() {
    let tmp = tempfile::tempdir().unwrap();
    let refs = rgbd_inputs(tmp.path());
    let mut s = spec(&tmp.path().join("set"), &refs, 1);
    s.save_lightfield = false;
    // 40x24 covered to 24x24 keeps columns 8..32: only the first 2 are near (a map squeezed to
    // the fitted image instead would be near over its first 6).
    s.size = Size::Fixed {
        width: 24,
        height: 24,
    };
    s.depth_policy = DepthPolicy {
        unit: DepthUnit::Millimetres,
        ..DepthPolicy::default()
    };
    let out = tmp.path().join("out");
    assert!(run(&out, &s, &network(), &opts(1)).ok());
    let rec = &records(&out)[0];
    let saved = uwnr_core::io::load_gray(
        &out.join(rec["depth"].as_str().unwrap()),
        &uwnr_core::io::DecodeLimits::default(),
    )
    .unwrap();
    assert_eq!(saved.size(), (24, 24));
    let row: Vec<f32> = saved.plane(0)[12 * 24..13 * 24].to_vec();
    assert!(row[0] < 0.6, "{row:?}");
    assert!(row[4..].iter().all(|&v| v > 0.9), "{row:?}");
}

#[test]
fn a_folder_made_before_depth_policies_is_not_resumed_with_new_renders() {
    let tmp = tempfile::tempdir().unwrap();
    let refs = rgbd_inputs(tmp.path());
    let mut s = spec(&tmp.path().join("plain"), &refs, 1);
    s.save_lightfield = false;
    let renderer = crate::common::reinhard();
    let out = tmp.path().join("out");
    assert!(run(&out, &s, &renderer, &opts(1)).ok());
    // As an older uwnr wrote it: no depth_policy field.
    let path = out.join("dataset.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("depth_policy");
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let stop = std::sync::atomic::AtomicBool::new(false);
    let err = uwnr_dataset::generate(&out, &s, &renderer, &opts(1), &stop, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("depth_policy"), "{err}");
}
