//! The built-in depth prior: hand-derivable properties, invariants and pinned values.

use uwnr_core::Image;
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::{DepthSource, builtin_depth};

/// Planar RGB image from a per-pixel function.
fn image_from(width: usize, height: usize, f: impl Fn(usize, usize, usize) -> f32) -> Image {
    let mut data = Vec::with_capacity(3 * width * height);
    for c in 0..3 {
        for y in 0..height {
            for x in 0..width {
                data.push(f(c, x, y));
            }
        }
    }
    Image::from_planar(width, height, 3, data).unwrap()
}

/// A deterministic pseudo-random value in [0, 1) (64-bit LCG hashed by position).
fn noise(c: usize, x: usize, y: usize) -> f32 {
    let mut s = (c as u64 + 1)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((x as u64) << 20 | y as u64);
    s = s
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    (s >> 40) as f32 / (1u64 << 24) as f32
}

/// A smooth colour gradient with a high-contrast checkerboard in its lower right quarter.
fn scene(width: usize, height: usize) -> Image {
    image_from(width, height, |c, x, y| {
        let (fx, fy) = (x as f32 / width as f32, y as f32 / height as f32);
        let base = [0.3 + 0.4 * fx, 0.2 + 0.5 * fy, 0.6 - 0.3 * fx * fy][c];
        let square = width / 24;
        let in_board = fx >= 0.5 && fy >= 0.5;
        if in_board && (x / square + y / square).is_multiple_of(2) {
            base * 0.3
        } else {
            base
        }
    })
}

fn at(map: &Image, x: usize, y: usize) -> f32 {
    map.get(0, y, x)
}

#[test]
fn uniform_image_gives_the_symmetric_ramp() {
    let (w, h) = (90, 61);
    let map = builtin_depth(&Image::filled(w, h, 3, 0.4)).unwrap();
    assert_eq!((map.size(), map.channels()), ((w, h), 1));
    for y in 0..h {
        let row = &map.plane(0)[y * w..(y + 1) * w];
        // Columns are equal, the top is farthest and the map is antisymmetric about mid-height.
        assert!(row.iter().all(|&v| (v - row[0]).abs() < 1e-6));
        assert!((at(&map, 0, y) + at(&map, 0, h - 1 - y) - 1.0).abs() < 1e-5);
        if y > 0 {
            assert!(at(&map, 0, y) <= at(&map, 0, y - 1) + 1e-7);
        }
    }
    assert!((at(&map, 0, 0) - 1.0).abs() < 1e-6);
    assert!(at(&map, 0, h - 1).abs() < 1e-6);
    assert!((at(&map, 5, h / 2) - 0.5).abs() < 1e-5);
}

#[test]
fn output_spans_the_unit_range_and_is_deterministic() {
    let img = image_from(120, 80, noise);
    let a = builtin_depth(&img).unwrap();
    let b = builtin_depth(&img).unwrap();
    assert_eq!(a, b);
    let lo = a.data().iter().copied().fold(f32::INFINITY, f32::min);
    let hi = a.data().iter().copied().fold(f32::NEG_INFINITY, f32::max);
    assert!(lo.abs() < 1e-6 && (hi - 1.0).abs() < 1e-6, "[{lo}, {hi}]");
    assert!(a.data().iter().all(|v| (0.0..=1.0).contains(v)));
}

#[test]
fn noise_does_not_become_texture() {
    // Pixel noise must not show through: neighbouring pixels differ by little more than the
    // ramp's own slope.
    let (w, h) = (200, 150);
    let map = builtin_depth(&image_from(w, h, noise)).unwrap();
    let p = map.plane(0);
    let mut worst = 0.0_f32;
    for y in 0..h {
        for x in 1..w {
            worst = worst.max((p[y * w + x] - p[y * w + x - 1]).abs());
        }
    }
    for i in w..w * h {
        worst = worst.max((p[i] - p[i - w]).abs());
    }
    assert!(worst < 0.03, "largest step between neighbours {worst}");
}

#[test]
fn textured_region_reads_nearer_than_flat_region_on_the_same_rows() {
    // Left half: a checkerboard; right half: flat at the same mean.
    let (w, h) = (192, 128);
    let img = image_from(w, h, |_, x, y| {
        if x < w / 2 {
            if (x / 8 + y / 8).is_multiple_of(2) {
                0.2
            } else {
                0.8
            }
        } else {
            0.5
        }
    });
    let map = builtin_depth(&img).unwrap();
    for y in [20, 64, 100] {
        assert!(
            at(&map, w / 4, y) + 0.1 < at(&map, 3 * w / 4, y),
            "row {y}: textured {} flat {}",
            at(&map, w / 4, y),
            at(&map, 3 * w / 4, y)
        );
    }
}

#[test]
fn nearly_independent_of_resolution() {
    let small = builtin_depth(&scene(240, 160)).unwrap();
    let large = builtin_depth(&scene(480, 320)).unwrap();
    let large_down = resize_bilinear(&large, 240, 160).unwrap();
    let mean_diff = small
        .data()
        .iter()
        .zip(large_down.data())
        .map(|(a, b)| (a - b).abs())
        .sum::<f32>()
        / small.data().len() as f32;
    assert!(mean_diff < 0.02, "mean abs difference {mean_diff}");
}

#[test]
fn grey_image_equals_its_rgb_replica() {
    let rgb = scene(96, 64);
    let grey = Image::from_planar(96, 64, 1, rgb.plane(1).to_vec()).unwrap();
    let replica = Image::concat_channels(&[&grey, &grey, &grey]).unwrap();
    assert_eq!(
        builtin_depth(&grey).unwrap(),
        builtin_depth(&replica).unwrap()
    );
}

#[test]
fn small_images_and_bad_channels() {
    // Smaller than the grid: used as is, and the contrast cue is flat, so the pure ramp.
    let tiny = builtin_depth(&image_from(7, 5, noise)).unwrap();
    let ramp = builtin_depth(&Image::filled(7, 5, 3, 0.5)).unwrap();
    assert_eq!(tiny, ramp);
    // One pixel: no cue at all, mid-depth.
    let one = builtin_depth(&Image::filled(1, 1, 3, 0.5)).unwrap();
    assert_eq!(one.data(), &[0.5]);
    assert!(builtin_depth(&Image::filled(4, 4, 2, 0.5)).is_err());
    assert!(builtin_depth(&Image::filled(0, 4, 3, 0.5)).is_err());
}

#[test]
fn depth_source_default_is_the_builtin() {
    let img = scene(64, 48);
    let depth = DepthSource::default()
        .prepare()
        .unwrap()
        .depth_for(&img, None)
        .unwrap();
    assert_eq!(depth.map, builtin_depth(&img).unwrap());
    assert!(depth.notes.is_empty());
}

/// Pinned values of the formula on [`scene`] at 144x96 (a 48x32 grid). An independent numpy
/// re-implementation (`tests/reference/builtin_depth_ref.py`, with PIL's float bilinear resize)
/// agrees with the whole map to within 3e-6. Change them only when the formula is changed on
/// purpose.
#[test]
fn pinned_values() {
    let map = builtin_depth(&scene(144, 96)).unwrap();
    let pinned = [
        ((0, 0), PIN_00),
        ((72, 48), PIN_MID),
        ((108, 72), PIN_BOARD),
        ((36, 72), PIN_LEFT_LOW),
        ((143, 95), PIN_CORNER),
    ];
    for ((x, y), want) in pinned {
        let got = at(&map, x, y);
        assert!(
            (got - want).abs() < 1e-4,
            "({x}, {y}): {got} vs pinned {want}"
        );
    }
}

// Top-left: near the top of the ramp, flat surroundings.
const PIN_00: f32 = 0.999_475;
// Centre, on the corner of the checkerboard.
const PIN_MID: f32 = 0.517_833;
// Inside the checkerboard: textured, read nearer than ...
const PIN_BOARD: f32 = 0.165_977;
// ... the smooth gradient on the same row.
const PIN_LEFT_LOW: f32 = 0.405_242;
// Bottom-right corner.
const PIN_CORNER: f32 = 0.098_724;
