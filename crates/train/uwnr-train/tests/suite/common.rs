//! Helpers shared by the suite's tests.

use uwnr_core::Image;

/// Largest absolute difference between two images of one size.
pub fn max_abs(a: &Image, b: &Image) -> f32 {
    assert_eq!(a.size(), b.size());
    a.data()
        .iter()
        .zip(b.data())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// A smooth plane with structure: `0.5 + 0.45 sin((0.37 x + 0.23 y) scale + c + seed)`.
pub fn wave_plane(w: usize, h: usize, c: usize, scale: f32, seed: f32) -> Vec<f32> {
    (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let v = ((x as f32 * 0.37 + y as f32 * 0.23) * scale + c as f32 + seed).sin();
                0.5 + 0.45 * v
            })
        })
        .collect()
}

/// An image of [`wave_plane`]s, channel `c` with phase `c`.
pub fn wave_image(w: usize, h: usize, channels: usize, scale: f32, seed: f32) -> Image {
    let data = (0..channels)
        .flat_map(|c| wave_plane(w, h, c, scale, seed))
        .collect();
    Image::from_planar(w, h, channels, data).unwrap()
}
