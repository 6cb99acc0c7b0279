use super::*;

#[test]
fn holes_take_the_nearest_measurements_and_measured_values_stay() {
    // 4x1: a hole between 1 and 3, a hole at the end.
    let mut v = [1.0, 0.0, 3.0, f32::NAN];
    assert!(fill_holes(&mut v, 4, 1));
    assert_eq!(v[0], 1.0);
    assert_eq!(v[2], 3.0);
    // Each hole takes the mean of its 2x1 cell's measurement.
    assert_eq!(v[1], 1.0);
    assert_eq!(v[3], 3.0);
    // A map with nothing measured cannot be filled.
    let mut none = [0.0f32; 6];
    assert!(!fill_holes(&mut none, 3, 2));
    // A large hole takes a mean of what surrounds it, within the measured range.
    let (w, h) = (16, 16);
    let mut big: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (4..12).contains(&x) && (4..12).contains(&y) {
                0.0
            } else {
                2.0 + x as f32 / 16.0
            }
        })
        .collect();
    assert!(fill_holes(&mut big, w, h));
    assert!(big.iter().all(|&v| (2.0..=3.0).contains(&v)), "{big:?}");
}

#[test]
fn partners_are_found_by_stem_or_by_trailing_number() {
    let maps: Vec<PathBuf> = ["sync_depth_00050.png", "sync_depth_00100.png", "b.png"]
        .iter()
        .map(PathBuf::from)
        .collect();
    let find = |p: &str| partner_map(Path::new(p), &maps).map(|m| m.to_string_lossy().into_owned());
    assert_eq!(
        find("rgb/rgb_00050.jpg").as_deref(),
        Some("sync_depth_00050.png")
    );
    assert_eq!(find("rgb/b.jpg").as_deref(), Some("b.png"));
    assert_eq!(find("rgb/rgb_00007.jpg"), None);
}

#[test]
fn metres_per_code_follow_the_unit() {
    assert_eq!(DepthUnit::Relative.metres_per_code(), None);
    assert_eq!(DepthUnit::Millimetres.metres_per_code(), Some(1e-3));
    assert_eq!(
        DepthUnit::CodesPerMetre(256).metres_per_code(),
        Some(1.0 / 256.0)
    );
    assert_eq!(DepthUnit::Metres.metres_per_code(), Some(1.0));
    assert_eq!(DepthUnit::Millimetres.to_string(), "mm");
}
