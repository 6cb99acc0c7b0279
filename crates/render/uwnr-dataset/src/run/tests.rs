use super::*;

#[test]
fn fit_covers_and_centre_crops() {
    // 40x20 with a bright right half; fitting to 20x20 keeps the middle 20 columns.
    let mut img = Image::filled(40, 20, 3, 0.0);
    for c in 0..3 {
        for y in 0..20 {
            for x in 20..40 {
                img.plane_mut(c)[y * 40 + x] = 1.0;
            }
        }
    }
    let out = fit(
        &img,
        Size::Fixed {
            width: 20,
            height: 20,
        },
    )
    .unwrap();
    assert_eq!(out.size(), (20, 20));
    assert_eq!(out.get(0, 10, 0), 0.0);
    assert_eq!(out.get(0, 10, 19), 1.0);
    // Upscaling to cover: 40x20 -> 80x80 needs 160x80, cropped to 80 wide.
    let up = fit(
        &img,
        Size::Fixed {
            width: 80,
            height: 80,
        },
    )
    .unwrap();
    assert_eq!(up.size(), (80, 80));
}

#[test]
fn fit_quantises_to_8_bits() {
    let img = Image::filled(4, 4, 3, 0.1234);
    let out = fit(&img, Size::Native).unwrap();
    let v = out.get(0, 0, 0) * 255.0;
    assert!((v - v.round()).abs() < 1e-4);
}
