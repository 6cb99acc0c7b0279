//! How a clean image becomes a pair, as arithmetic on coordinates: the pair size's scale to cover
//! and centre crop ([`Fit`]), applied to points, boxes, polygons and label rasters. The image
//! itself goes through the same [`Fit`] (`run::fit_geometry`), so labels and pixels cannot drift
//! apart.

use crate::plan::Size;

/// A clean image of `src` size scaled to `scaled` (each axis by its own factor, both within a
/// pixel of the same scale) and cropped at (`x0`, `y0`) to `width x height`.
///
/// Coordinates are continuous pixel coordinates, COCO's convention: the image spans
/// `[0, width] x [0, height]`, pixel `(i, j)` covers `[i, i + 1] x [j, j + 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fit {
    pub src_width: usize,
    pub src_height: usize,
    pub scaled_width: usize,
    pub scaled_height: usize,
    pub x0: usize,
    pub y0: usize,
    pub width: usize,
    pub height: usize,
}

impl Fit {
    /// The fit of an image of `(width, height)` to the pair size `size`: for a fixed size, scaled
    /// (aspect kept) to cover it, then centre-cropped; never stretched.
    #[must_use]
    pub fn new((w, h): (usize, usize), size: Size) -> Self {
        match size {
            Size::Native => Self {
                src_width: w,
                src_height: h,
                scaled_width: w,
                scaled_height: h,
                x0: 0,
                y0: 0,
                width: w,
                height: h,
            },
            Size::Fixed { width, height } => {
                let (wf, hf) = (w as f64, h as f64);
                let scale = (width as f64 / wf).max(height as f64 / hf);
                let sw = ((wf * scale).round() as usize).max(width);
                let sh = ((hf * scale).round() as usize).max(height);
                Self {
                    src_width: w,
                    src_height: h,
                    scaled_width: sw,
                    scaled_height: sh,
                    x0: (sw - width) / 2,
                    y0: (sh - height) / 2,
                    width,
                    height,
                }
            }
        }
    }

    /// The pair is the image itself.
    #[must_use]
    pub fn is_identity(&self) -> bool {
        (self.width, self.height) == (self.src_width, self.src_height)
            && (self.scaled_width, self.scaled_height) == (self.src_width, self.src_height)
    }

    /// Horizontal scale factor.
    #[must_use]
    pub fn sx(&self) -> f64 {
        self.scaled_width as f64 / self.src_width as f64
    }

    /// Vertical scale factor.
    #[must_use]
    pub fn sy(&self) -> f64 {
        self.scaled_height as f64 / self.src_height as f64
    }

    /// Where the point `(x, y)` of the clean image lands in the pair (possibly outside it).
    #[must_use]
    pub fn point(&self, x: f64, y: f64) -> (f64, f64) {
        (
            x * self.sx() - self.x0 as f64,
            y * self.sy() - self.y0 as f64,
        )
    }

    /// Whether `(x, y)`, in pair coordinates, lies inside the pair.
    #[must_use]
    pub fn inside(&self, (x, y): (f64, f64)) -> bool {
        (0.0..=self.width as f64).contains(&x) && (0.0..=self.height as f64).contains(&y)
    }

    /// The box `[x0, y0, x1, y1]` of the clean image in the pair, clipped to it; `None` when
    /// nothing of it is left (the crop removed it). The flag says whether clipping cut it.
    #[must_use]
    pub fn rect(&self, [x0, y0, x1, y1]: [f64; 4]) -> Option<([f64; 4], bool)> {
        let (a, b) = (self.point(x0, y0), self.point(x1, y1));
        let (w, h) = (self.width as f64, self.height as f64);
        let clipped = [a.0.max(0.0), a.1.max(0.0), b.0.min(w), b.1.min(h)];
        let cut = clipped != [a.0, a.1, b.0, b.1];
        (clipped[2] > clipped[0] && clipped[3] > clipped[1]).then_some((clipped, cut))
    }

    /// A polygon `[x1, y1, x2, y2, ...]` of the clean image in the pair, clipped to it
    /// (Sutherland-Hodgman against the pair's rectangle); `None` when fewer than 3 points or no
    /// area are left.
    #[must_use]
    pub fn polygon(&self, points: &[f64]) -> Option<Vec<f64>> {
        let mut poly: Vec<(f64, f64)> = points
            .chunks_exact(2)
            .map(|p| self.point(p[0], p[1]))
            .collect();
        let (w, h) = (self.width as f64, self.height as f64);
        // Each edge of the rectangle: keep the side where `inside(p)` holds.
        type Edge = (
            fn((f64, f64), f64) -> bool,
            fn((f64, f64), (f64, f64), f64) -> (f64, f64),
        );
        let edges: [(Edge, f64); 4] = [
            ((|p, _| p.0 >= 0.0, |a, b, _| at_x(a, b, 0.0)), 0.0),
            ((|p, w| p.0 <= w, at_x), w),
            ((|p, _| p.1 >= 0.0, |a, b, _| at_y(a, b, 0.0)), 0.0),
            ((|p, h| p.1 <= h, at_y), h),
        ];
        for ((inside, cross), limit) in edges {
            if poly.is_empty() {
                break;
            }
            let mut out = Vec::with_capacity(poly.len() + 4);
            for (i, &cur) in poly.iter().enumerate() {
                let prev = poly[(i + poly.len() - 1) % poly.len()];
                match (inside(prev, limit), inside(cur, limit)) {
                    (true, true) => out.push(cur),
                    (true, false) => out.push(cross(prev, cur, limit)),
                    (false, true) => {
                        out.push(cross(prev, cur, limit));
                        out.push(cur);
                    }
                    (false, false) => {}
                }
            }
            poly = out;
        }
        poly.dedup();
        if poly.len() > 1 && poly.first() == poly.last() {
            poly.pop();
        }
        (poly.len() >= 3 && shoelace(&poly) > 0.0)
            .then(|| poly.iter().flat_map(|&(x, y)| [x, y]).collect())
    }

    /// For each pixel of the pair, in row-major order, the index of the clean image's pixel that
    /// nearest-neighbour resampling takes it from (pixel centres mapped through the scale, as
    /// PIL's `NEAREST` does).
    #[must_use]
    pub fn nearest_indices(&self) -> Vec<usize> {
        let cols: Vec<usize> = (0..self.width)
            .map(|x| nearest(x + self.x0, self.scaled_width, self.src_width))
            .collect();
        let mut out = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            let row = nearest(y + self.y0, self.scaled_height, self.src_height) * self.src_width;
            out.extend(cols.iter().map(|&c| row + c));
        }
        out
    }

    /// Resamples a label raster of the clean image's size (row-major, `channels` samples per
    /// pixel) to the pair by nearest neighbour: every output value is one of the input's, never
    /// a blend.
    #[must_use]
    pub fn resample<T: Copy>(&self, src: &[T], channels: usize) -> Vec<T> {
        if self.is_identity() {
            return src.to_vec();
        }
        let mut out = Vec::with_capacity(self.width * self.height * channels);
        for i in self.nearest_indices() {
            out.extend_from_slice(&src[i * channels..(i + 1) * channels]);
        }
        out
    }
}

/// The source index of output pixel `o` when `n_in` pixels are resampled to `n_out`.
fn nearest(o: usize, n_out: usize, n_in: usize) -> usize {
    let x = ((o as f64 + 0.5) * n_in as f64 / n_out as f64).floor() as usize;
    x.min(n_in - 1)
}

fn at_x(a: (f64, f64), b: (f64, f64), x: f64) -> (f64, f64) {
    let t = (x - a.0) / (b.0 - a.0);
    (x, a.1 + t * (b.1 - a.1))
}

fn at_y(a: (f64, f64), b: (f64, f64), y: f64) -> (f64, f64) {
    let t = (y - a.1) / (b.1 - a.1);
    (a.0 + t * (b.0 - a.0), y)
}

/// The area of a polygon (absolute value of the shoelace sum).
#[must_use]
pub fn shoelace(poly: &[(f64, f64)]) -> f64 {
    let n = poly.len();
    let twice: f64 = (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum();
    twice.abs() / 2.0
}

/// The area of a flat polygon `[x1, y1, x2, y2, ...]`.
#[must_use]
pub fn polygon_area(points: &[f64]) -> f64 {
    let poly: Vec<(f64, f64)> = points.chunks_exact(2).map(|p| (p[0], p[1])).collect();
    shoelace(&poly)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(width: usize, height: usize) -> Size {
        Size::Fixed { width, height }
    }

    #[test]
    fn fit_scales_to_cover_and_centres_the_crop() {
        // 400x200 to 100x100: scale 0.5 gives 200x100, cropped 50 px on each side.
        let f = Fit::new((400, 200), fixed(100, 100));
        assert_eq!(
            (f.scaled_width, f.scaled_height, f.x0, f.y0),
            (200, 100, 50, 0)
        );
        assert_eq!(f.point(100.0, 0.0), (0.0, 0.0));
        assert_eq!(f.point(300.0, 200.0), (100.0, 100.0));
        assert!(Fit::new((64, 48), Size::Native).is_identity());
        assert!(!f.is_identity());
    }

    #[test]
    fn boxes_are_scaled_and_clipped_and_vanish_when_cropped_out() {
        let f = Fit::new((400, 200), fixed(100, 100));
        // Inside: scaled by 0.5 and shifted by the crop.
        assert_eq!(
            f.rect([120.0, 20.0, 200.0, 100.0]),
            Some(([10.0, 10.0, 50.0, 50.0], false))
        );
        // Across the left edge: clipped and flagged.
        assert_eq!(
            f.rect([60.0, 0.0, 140.0, 40.0]),
            Some(([0.0, 0.0, 20.0, 20.0], true))
        );
        // In the cropped-off strip: gone.
        assert_eq!(f.rect([0.0, 0.0, 90.0, 50.0]), None);
    }

    #[test]
    fn polygons_are_clipped_to_the_pair() {
        let f = Fit::new((100, 100), fixed(100, 100));
        assert!(f.is_identity());
        // A square half outside the right edge keeps its inside half.
        let p = f
            .polygon(&[80.0, 10.0, 120.0, 10.0, 120.0, 50.0, 80.0, 50.0])
            .unwrap();
        assert!((polygon_area(&p) - 20.0 * 40.0).abs() < 1e-9, "{p:?}");
        assert!(p.chunks(2).all(|q| q[0] <= 100.0));
        // Entirely outside: gone.
        assert_eq!(f.polygon(&[110.0, 0.0, 130.0, 0.0, 120.0, 20.0]), None);
        // Degenerate (two points): gone.
        assert_eq!(f.polygon(&[1.0, 1.0, 5.0, 5.0]), None);
        // A triangle that contains the whole image is clipped to the image.
        let big = f
            .polygon(&[-1000.0, -1000.0, 1000.0, -1000.0, 0.0, 1000.0])
            .unwrap();
        assert!(polygon_area(&big) <= 100.0 * 100.0 + 1e-6);
    }

    #[test]
    fn nearest_resampling_only_copies_values() {
        // 4x2 with distinct values, doubled to 8x4: each value becomes a 2x2 block.
        let src: Vec<u8> = (0..8).collect();
        let f = Fit::new((4, 2), fixed(8, 4));
        let out = f.resample(&src, 1);
        assert_eq!(out.len(), 32);
        assert_eq!(&out[..8], &[0, 0, 1, 1, 2, 2, 3, 3]);
        assert_eq!(&out[8..16], &[0, 0, 1, 1, 2, 2, 3, 3]);
        assert_eq!(&out[16..24], &[4, 4, 5, 5, 6, 6, 7, 7]);
        // Halving with a crop takes values from the kept region only.
        let src: Vec<u16> = (0..64).collect();
        let f = Fit::new((16, 4), fixed(4, 4));
        let out = f.resample(&src, 1);
        assert!(out.iter().all(|v| src.contains(v)));
        assert_eq!(out.len(), 16);
        // Channels travel together.
        let rgb: Vec<u8> = (0..24).collect();
        let f = Fit::new((4, 2), fixed(8, 4));
        let out = f.resample(&rgb, 3);
        assert_eq!(&out[..6], &[0, 1, 2, 0, 1, 2]);
    }
}
