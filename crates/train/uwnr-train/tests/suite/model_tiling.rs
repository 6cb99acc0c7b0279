//! Tiled against whole-image rendering, with the width-8 parity weights (random weights with
//! non-trivial activations, from `tools/torch_parity.py`).

use std::path::Path;
use uwnr_train::burn_render::render;
use uwnr_train::{Device, load_generator};

use uwnr_core::Image;
use uwnr_model::{ModelError, RenderOptions};

/// Tiled and whole renders with an overlap of at least 2 x 76 + 32 px agree up to float
/// rounding: every blended pixel is more than the receptive radius from a cut edge, and the
/// channel means are the whole image's (summed over tiles in a different order). Measured:
/// max abs 1.4e-6. Letting each tile pool its own channel means instead gives 1.4e-3 here, so
/// this bound catches a tiling that loses the global pooling.
const EXACT_TOL: f32 = 1e-4;
/// With small tiles (64 px, overlap 32 px, far inside the 76 px receptive radius) the tiles
/// see zero padding where the whole image has content, so only closeness can be asked for.
/// Measured: max abs 0.113, mean abs 0.0082 (outputs span [0, 0.74] after clamping, mean abs
/// deviation 0.12). The bound is about 3.5x the measured mean.
const SMALL_TILE_MEAN_TOL: f32 = 0.03;

/// A deterministic, structured test scene: gradients, stripes and a disc.
fn scene(w: usize, h: usize) -> (Image, Image, Image) {
    let mut clean = Vec::with_capacity(3 * w * h);
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
                let stripes = (0.5 + 0.5 * ((x + 2 * y) as f32 * 0.21 + c as f32).sin()) * 0.4;
                let disc = if (fx - 0.6).powi(2) + (fy - 0.4).powi(2) < 0.05 {
                    0.4
                } else {
                    0.0
                };
                clean.push((0.2 * c as f32 * fx + 0.3 * fy + stripes + disc).min(1.0));
            }
        }
    }
    let depth: Vec<f32> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (y as f32 / h as f32) * 0.8 + 0.1 * (x % 7) as f32 / 7.0))
        .collect();
    let lf: Vec<f32> = (0..3)
        .flat_map(|c| {
            (0..h).flat_map(move |y| {
                (0..w).map(move |x| 0.3 + 0.2 * c as f32 + 0.1 * ((x + y) as f32 * 0.05).cos())
            })
        })
        .collect();
    (
        Image::from_planar(w, h, 3, clean).unwrap(),
        Image::from_planar(w, h, 1, depth).unwrap(),
        Image::from_planar(w, h, 3, lf).unwrap(),
    )
}

fn diff(a: &Image, b: &Image) -> (f32, f32) {
    let d: Vec<f32> = a
        .data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| (x - y).abs())
        .collect();
    let max = d.iter().copied().fold(0.0, f32::max);
    (max, d.iter().sum::<f32>() / d.len() as f32)
}

#[test]
fn tiled_matches_whole_image() {
    let device = Device::flex();
    let weights = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../render/uwnr-model/tests/fixtures/parity_w8.safetensors");
    let (g, _, _) = load_generator(&weights, &device).unwrap();
    // 190 x 150 is not a multiple of 16: exercises the reflect padding and the crop.
    let (w, h) = (190, 150);
    let (clean, depth, lf) = scene(w, h);
    let whole = render(&g, &clean, &depth, &lf, &RenderOptions::default(), &device).unwrap();
    assert_eq!(whole.size(), (w, h));
    assert_eq!(whole.channels(), 3);
    assert!(whole.data().iter().all(|v| (0.0..=1.0).contains(v)));
    // Not a flat image: the comparison below means something.
    let mean = whole.data().iter().sum::<f32>() / whole.data().len() as f32;
    let spread =
        whole.data().iter().map(|v| (v - mean).abs()).sum::<f32>() / whole.data().len() as f32;
    assert!(spread > 0.02, "{spread}");
    let (lo, hi) = whole
        .data()
        .iter()
        .fold((1.0f32, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)));
    println!("whole render: values in [{lo:.3}, {hi:.3}], mean abs deviation {spread:.3}");

    let exact = RenderOptions {
        max_tile_pixels: 0,
        tile: 256,
        overlap: 192,
        ..Default::default()
    };
    let tiled = render(&g, &clean, &depth, &lf, &exact, &device).unwrap();
    let (max, mean) = diff(&whole, &tiled);
    println!("tile 256 / overlap 192 (3x3 tiles): max abs {max:.3e}, mean abs {mean:.3e}");
    assert!(max < EXACT_TOL, "{max}");

    let small = RenderOptions {
        max_tile_pixels: 0,
        tile: 64,
        overlap: 32,
        ..Default::default()
    };
    let tiled = render(&g, &clean, &depth, &lf, &small, &device).unwrap();
    let (max, mean) = diff(&whole, &tiled);
    println!("tile 64 / overlap 32: max abs {max:.3e}, mean abs {mean:.3e}");
    assert!(mean < SMALL_TILE_MEAN_TOL, "{mean}");
    assert!(
        max > 0.0,
        "small tiles cannot be exact: is tiling really happening?"
    );
}

#[test]
fn inputs_are_checked() {
    let device = Device::flex();
    let weights = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../render/uwnr-model/tests/fixtures/parity_w8.safetensors");
    let (g, _, _) = load_generator(&weights, &device).unwrap();
    let (clean, depth, lf) = scene(40, 30);
    let opts = RenderOptions::default();
    let err = render(&g, &clean, &clean, &lf, &opts, &device).unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::Channels {
                what: "depth map",
                expected: 1,
                got: 3
            }
        ),
        "{err}"
    );
    let (_, _, small_lf) = scene(40, 31);
    let err = render(&g, &clean, &depth, &small_lf, &opts, &device).unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::ImageSize {
                what: "light-field map",
                ..
            }
        ),
        "{err}"
    );
    // A tiny image (smaller than one 16-pixel cell) still renders, through reflection.
    let (c, d, l) = scene(5, 3);
    let out = render(&g, &c, &d, &l, &opts, &device).unwrap();
    assert_eq!(out.size(), (5, 3));
}
