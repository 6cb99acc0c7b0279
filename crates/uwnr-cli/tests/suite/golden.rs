//! The bundled model on the two bundled sample pairs stays within tolerance of the committed
//! golden renders (`assets/golden/`), through the binary exactly as a user runs it: no
//! `--weights`, native resolution, the default depth. `REGENERATE=1` rewrites the goldens (do
//! that only when the bundled model changes on purpose, and say so in the commit).
//!
//! Tolerance: the renders differ from the goldens only by floating-point reordering between
//! machines and SIMD paths, so at most a few code values anywhere and a tiny mean.

use std::path::PathBuf;

use crate::common::{root, s, sample, stderr, uwnr};
use uwnr_core::io::{DecodeLimits, load_rgb};

/// Largest allowed difference of any channel of any pixel, in code values.
const MAX_CODE_DIFF: f64 = 3.0;
/// Largest allowed mean absolute difference, in code values.
const MAX_MEAN_CODE_DIFF: f64 = 0.1;

/// (clean, reference, optional depth map, golden file).
const CASES: [(&str, &str, Option<&str>, &str); 2] = [
    (
        "clean-statues.jpg",
        "ref-blue.jpg",
        None,
        "statues-blue.png",
    ),
    (
        "clean-room.jpg",
        "ref-green.png",
        Some("clean-room-depth.png"),
        "room-green.png",
    ),
];

fn golden(name: &str) -> PathBuf {
    root().join("assets/golden").join(name)
}

#[test]
fn bundled_model_matches_the_golden_renders() {
    let dir = tempfile::tempdir().unwrap();
    let regenerate = std::env::var("REGENERATE").is_ok_and(|v| v == "1");
    for (clean, reference, depth, name) in CASES {
        let out = dir.path().join(name);
        let (c, r) = (sample(clean), sample(reference));
        let mut args = vec!["render", s(&c), "--reference", s(&r), "--output", s(&out)];
        let d = depth.map(sample);
        if let Some(d) = &d {
            args.extend(["--depth", s(d)]);
        }
        let o = uwnr(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        if regenerate {
            std::fs::create_dir_all(golden("")).unwrap();
            std::fs::copy(&out, golden(name)).unwrap();
            eprintln!("rewrote {}", golden(name).display());
            continue;
        }
        let limits = DecodeLimits::default();
        let got = load_rgb(&out, &limits).unwrap();
        let want = load_rgb(&golden(name), &limits)
            .unwrap_or_else(|e| panic!("{name}: {e} (REGENERATE=1 writes the goldens)"));
        assert_eq!(got.size(), want.size(), "{name}: size");
        assert_eq!(got.size(), load_rgb(&c, &limits).unwrap().size());
        let diffs: Vec<f64> = got
            .data()
            .iter()
            .zip(want.data())
            .map(|(a, b)| f64::from((a - b).abs()) * 255.0)
            .collect();
        let max = diffs.iter().copied().fold(0.0, f64::max);
        let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
        assert!(
            max <= MAX_CODE_DIFF + 1e-6 && mean <= MAX_MEAN_CODE_DIFF,
            "{name}: max diff {max:.1}, mean {mean:.3} code values"
        );
        // A render is not its input: the model changed the image.
        let input = load_rgb(&c, &limits).unwrap();
        let moved = input
            .data()
            .iter()
            .zip(got.data())
            .map(|(a, b)| f64::from((a - b).abs()) * 255.0)
            .sum::<f64>()
            / diffs.len() as f64;
        assert!(
            moved > 5.0,
            "{name}: render is within {moved:.1} of the input"
        );
    }
}
