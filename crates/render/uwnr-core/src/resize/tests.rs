use super::*;

#[test]
fn fit_within_dims_shrinks_the_longer_side_and_keeps_the_aspect() {
    assert_eq!(fit_within_dims((1000, 500), 256), (256, 128));
    assert_eq!(fit_within_dims((1000, 500), 512), (512, 256));
    assert_eq!(fit_within_dims((300, 1200), 100), (25, 100));
    // 640 * 100 / 900 = 71.1 and 900 -> 100; 3 * 100 / 200 = 1.5 rounds to 2.
    assert_eq!(fit_within_dims((640, 900), 100), (71, 100));
    assert_eq!(fit_within_dims((200, 3), 100), (100, 2));
    // A side that would round to 0 keeps one pixel.
    assert_eq!(fit_within_dims((1000, 1), 10), (10, 1));
    // Sizes that fit are kept, never enlarged.
    assert_eq!(fit_within_dims((100, 50), 512), (100, 50));
    assert_eq!(fit_within_dims((512, 512), 512), (512, 512));
    assert_eq!(fit_within_dims((0, 0), 8), (0, 0));
    assert_eq!(fit_within_dims((4, 2), 0), (1, 1));
}

#[test]
fn fit_within_resizes_bilinearly_and_only_shrinks() {
    let data: Vec<f32> = (0..3 * 40 * 20).map(|v| (v % 7) as f32 / 7.0).collect();
    let img = Image::from_planar(40, 20, 3, data).unwrap();
    let small = fit_within(&img, 10).unwrap();
    assert_eq!(small, resize_bilinear(&img, 10, 5).unwrap());
    assert_eq!(fit_within(&img, 40).unwrap(), img);
    assert_eq!(fit_within(&img, 100).unwrap(), img);
}
