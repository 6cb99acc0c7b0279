//! The O(n) dark channel against a brute-force window minimum with edge replication.

use uwnr_core::Image;
use uwnr_core::dark_channel::{UNDERWATER_CHANNELS, UNDERWATER_WINDOW, dark_channel};

/// Deterministic pseudo-random values in [0, 1) (xorshift64*).
fn random_image(width: usize, height: usize, channels: usize, seed: u64) -> Image {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let data = (0..width * height * channels)
        .map(|_| {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            (state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1_u64 << 24) as f32
        })
        .collect();
    Image::from_planar(width, height, channels, data).unwrap()
}

/// The definition: pad by `window / 2` with edge values (`np.pad(..., 'edge')`), then the
/// minimum over the channels and the `window x window` block starting at each pixel.
fn brute_force(img: &Image, channels: &[usize], window: usize) -> Vec<f32> {
    let (w, h) = img.size();
    let before = (window / 2) as i64;
    let clamp = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut m = f32::INFINITY;
            for dy in 0..window as i64 {
                for dx in 0..window as i64 {
                    let yy = clamp(y as i64 - before + dy, h);
                    let xx = clamp(x as i64 - before + dx, w);
                    for &c in channels {
                        m = m.min(img.get(c, yy, xx));
                    }
                }
            }
            out[y * w + x] = m;
        }
    }
    out
}

#[test]
fn matches_brute_force_on_random_images() {
    let cases = [
        (37, 23, 3, UNDERWATER_WINDOW, &UNDERWATER_CHANNELS[..]),
        (16, 16, 3, 15, &[0, 1, 2][..]),
        (9, 31, 3, 4, &[2][..]),
        (5, 3, 4, 7, &[0, 3][..]),
        (64, 1, 3, 15, &UNDERWATER_CHANNELS[..]),
        (1, 40, 3, 2, &[1][..]),
        (20, 20, 3, 1, &[0, 1, 2][..]),
        (20, 11, 3, 41, &UNDERWATER_CHANNELS[..]),
    ];
    for (i, &(w, h, cn, window, channels)) in cases.iter().enumerate() {
        let img = random_image(w, h, cn, i as u64 + 1);
        let got = dark_channel(&img, channels, window).unwrap();
        assert_eq!((got.width(), got.height(), got.channels()), (w, h, 1));
        assert_eq!(
            got.data(),
            &brute_force(&img, channels, window)[..],
            "{w}x{h}, window {window}, channels {channels:?}"
        );
    }
}

#[test]
fn underwater_dark_channel_ignores_red() {
    // Red is 0 everywhere, G and B are high: the underwater dark channel stays high.
    let mut img = random_image(30, 20, 3, 7);
    img.plane_mut(0).fill(0.0);
    for c in 1..3 {
        for v in img.plane_mut(c) {
            *v = 0.5 + *v / 2.0;
        }
    }
    let d = dark_channel(&img, &UNDERWATER_CHANNELS, UNDERWATER_WINDOW).unwrap();
    assert!(d.data().iter().all(|&v| v >= 0.5));
    let all = dark_channel(&img, &[0, 1, 2], UNDERWATER_WINDOW).unwrap();
    assert!(all.data().iter().all(|&v| v == 0.0));
}

#[test]
fn invalid_arguments_are_errors() {
    let img = random_image(4, 4, 3, 3);
    assert!(dark_channel(&img, &[], 3).is_err());
    assert!(dark_channel(&img, &[3], 3).is_err());
    assert!(dark_channel(&img, &[0], 0).is_err());
}
