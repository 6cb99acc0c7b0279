use super::*;

#[test]
fn cores_partition_on_the_grid() {
    for (len, max_core) in [(3008, 832), (192, 64), (160, 64), (16, 16), (4000, 320)] {
        let b = core_bounds(len, max_core);
        assert_eq!(b[0], 0);
        assert_eq!(*b.last().unwrap(), len);
        for pair in b.windows(2) {
            assert!(pair[1] > pair[0]);
            assert!(pair[1] - pair[0] <= max_core);
            assert_eq!(pair[0] % 16, 0);
        }
    }
}

#[test]
fn ramps_are_complementary_and_positive() {
    let b = core_bounds(640, 160);
    let (half, guard) = (96, 76);
    let mut total = vec![0.0f32; 640];
    for i in 0..b.len() - 1 {
        let (s, e) = tile_extent(b[i], b[i + 1], half, 640);
        for (p, wv) in (s..e).zip(axis_weights(&b, i, s, e, half, guard)) {
            total[p] += wv;
            // Nothing is taken from within the guard of a cut edge.
            if wv > 0.0 {
                assert!(i == 0 || p >= s + guard, "tile {i} px {p}");
                assert!(i == b.len() - 2 || p + guard < e, "tile {i} px {p}");
            }
        }
    }
    for t in total {
        assert!((t - 1.0).abs() < 1e-6, "{t}");
    }
}

#[test]
fn options_are_validated() {
    RenderOptions::default().validate().unwrap();
    for bad in [
        RenderOptions {
            tile: 100,
            ..Default::default()
        },
        RenderOptions {
            overlap: 48,
            ..Default::default()
        },
        RenderOptions {
            tile: 192,
            overlap: 192,
            max_tile_pixels: 0,
            ..Default::default()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
    }
}
