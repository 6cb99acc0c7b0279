//! Properties of the floating-point antialiased bilinear resize.

use uwnr_core::Image;
use uwnr_core::resize::{LazyResize, U8Image, pil_resize_bilinear_u8, resize_bilinear};

fn ramp(width: usize, height: usize) -> Image {
    let data = (0..3)
        .flat_map(|c| {
            (0..height).flat_map(move |y| {
                (0..width).map(move |x| ((x * 7 + y * 3 + c * 50) % 256) as f32 / 255.0)
            })
        })
        .collect();
    Image::from_planar(width, height, 3, data).unwrap()
}

#[test]
fn constant_images_stay_constant() {
    let img = Image::filled(37, 21, 2, 0.375);
    for (w, h) in [(100, 80), (5, 3), (37, 50), (1, 1)] {
        let out = resize_bilinear(&img, w, h).unwrap();
        assert_eq!((out.width(), out.height(), out.channels()), (w, h, 2));
        assert!(out.data().iter().all(|v| (v - 0.375).abs() < 1e-6));
    }
}

#[test]
fn same_size_is_identity_and_zero_size_is_an_error() {
    let img = ramp(13, 9);
    assert_eq!(resize_bilinear(&img, 13, 9).unwrap(), img);
    assert!(resize_bilinear(&img, 0, 9).is_err());
    assert!(resize_bilinear(&Image::filled(0, 4, 3, 0.0), 4, 4).is_err());
}

#[test]
fn halving_uses_the_widened_triangle() {
    // Shrinking by 2 doubles the support: interior weights 1/8, 3/8, 3/8, 1/8; at the borders
    // the taps outside the image are dropped and the rest renormalised (3/7, 3/7, 1/7).
    let row = [0.0_f32, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0];
    let img = Image::from_planar(8, 1, 1, row.to_vec()).unwrap();
    let out = resize_bilinear(&img, 4, 1).unwrap();
    let expected = [1.0 / 7.0, 0.75, 0.25, 6.0 / 7.0];
    for (got, want) in out.data().iter().zip(expected) {
        assert!((got - want).abs() < 1e-6, "{:?}", out.data());
    }
}

#[test]
fn agrees_with_the_pil_port_within_quantisation() {
    let img = ramp(61, 47);
    let u8img = U8Image::from_image(&img);
    for (w, h) in [(256, 256), (20, 33), (122, 23)] {
        let float = U8Image::from_image(&resize_bilinear(&img, w, h).unwrap());
        let pil = pil_resize_bilinear_u8(&u8img, w, h).unwrap();
        let max = float
            .data
            .iter()
            .zip(&pil.data)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap();
        // PIL rounds after each pass: at most one code value apart.
        assert!(max <= 1, "{w}x{h}: max diff {max}");
    }
}

#[test]
fn lazy_resize_gives_the_same_values_over_any_region() {
    let img = ramp(61, 45);
    for (w, h) in [(256, 200), (30, 17), (61, 45), (61, 90)] {
        let full = resize_bilinear(&img, w, h).unwrap();
        let lazy = LazyResize::new(&img, w, h).unwrap();
        assert_eq!((lazy.size(), lazy.channels()), ((w, h), 3));
        // Scattered, repeated and out-of-order indices, as a reflected tile border gives.
        let rows: Vec<usize> = [h / 3, h / 3 + 1, 0, h - 1, h - 2, h / 3 + 1].to_vec();
        let cols: Vec<usize> = [w - 1, 0, 1, w / 2, w / 2 + 1, w / 2].to_vec();
        for c in 0..3 {
            let mut got = Vec::new();
            lazy.sample(c, &rows, &cols, &mut got);
            let want: Vec<f32> = rows
                .iter()
                .flat_map(|&y| cols.iter().map(move |&x| (y, x)))
                .map(|(y, x)| full.plane(c)[y * w + x])
                .collect();
            // Bit for bit: the same taps in the same order.
            assert_eq!(got, want, "{w}x{h} channel {c}");
        }
    }
    assert!(LazyResize::new(&img, 0, 5).is_err());
}
