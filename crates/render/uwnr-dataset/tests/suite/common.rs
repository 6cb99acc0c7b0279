//! Small synthetic inputs and helpers shared by the dataset tests.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use uwnr_baselines::{Method, ReinhardParams};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, save_rgb};
use uwnr_dataset::{Renderer, RunOptions, Size, Spec, Summary};
use uwnr_depth::DepthSource;

/// A textured RGB image whose content depends on `seed`.
pub fn texture(width: usize, height: usize, seed: u64, tint: [f32; 3]) -> Image {
    let mut img = Image::filled(width, height, 3, 0.0);
    for (c, &tint) in tint.iter().enumerate() {
        let plane = img.plane_mut(c);
        for y in 0..height {
            for x in 0..width {
                let v = ((x as f32 * 0.37 + y as f32 * 0.21 + seed as f32 * 1.3 + c as f32).sin()
                    * 0.5
                    + 0.5)
                    * tint;
                plane[y * width + x] = v.clamp(0.0, 1.0);
            }
        }
    }
    img
}

/// Writes `n_clean` clean images (two subfolders, varied sizes) and `n_ref` bluish-green
/// references; returns (clean root, reference root).
pub fn inputs(root: &Path, n_clean: usize, n_ref: usize) -> (PathBuf, PathBuf) {
    let clean = root.join("clean-in");
    let refs = root.join("refs-in");
    for sub in ["a", "b"] {
        std::fs::create_dir_all(clean.join(sub)).unwrap();
    }
    std::fs::create_dir_all(&refs).unwrap();
    for i in 0..n_clean {
        let sub = if i % 2 == 0 { "a" } else { "b" };
        let (w, h) = (24 + 4 * (i % 3), 20 + 2 * (i % 4));
        save_rgb(
            &clean.join(sub).join(format!("img{i:02}.png")),
            &texture(w, h, i as u64, [1.0, 0.9, 0.8]),
        )
        .unwrap();
    }
    for j in 0..n_ref {
        save_rgb(
            &refs.join(format!("ref{j:02}.png")),
            &texture(32, 24, 100 + j as u64, [0.2, 0.6 + 0.05 * j as f32, 0.7]),
        )
        .unwrap();
    }
    (clean, refs)
}

pub fn spec(clean: &Path, refs: &Path, k: usize) -> Spec {
    Spec {
        clean: vec![clean.to_path_buf()],
        references: vec![refs.to_path_buf()],
        per_image: k,
        seed: 11,
        size: Size::Native,
        save_depth: true,
        save_lightfield: true,
        depth: DepthSource::Builtin,
        depth_policy: uwnr_render::DepthPolicy::default(),
        labels: uwnr_dataset::LabelInputs::default(),
        target: None,
        camera: uwnr_render::Camera::NONE,
    }
}

pub fn reinhard() -> Renderer {
    Renderer::baseline(Method::Reinhard(ReinhardParams::default()))
}

pub fn opts(jobs: usize) -> RunOptions {
    RunOptions {
        shard: None,
        jobs,
        limits: DecodeLimits::default(),
        gallery: true,
    }
}

pub fn run(out: &Path, spec: &Spec, renderer: &Renderer, opts: &RunOptions) -> Summary {
    let stop = AtomicBool::new(false);
    uwnr_dataset::generate(out, spec, renderer, opts, &stop, &mut |_| {}).unwrap()
}

/// Every file under `dir` (recursively), relative path -> bytes.
pub fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(base: &Path, dir: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(base, &p, out);
            } else {
                let rel = p.strip_prefix(base).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// Asserts two dataset folders hold the same files with the same bytes.
pub fn assert_same_tree(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    let ka: Vec<&String> = ta.keys().collect();
    let kb: Vec<&String> = tb.keys().collect();
    assert_eq!(
        ka,
        kb,
        "different files in {} and {}",
        a.display(),
        b.display()
    );
    for (k, v) in &ta {
        assert!(
            v == &tb[k],
            "{k} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}
