//! Separable 1-D correlations on f64 planes with scipy.ndimage's `mode="reflect"` border
//! (half-sample symmetric: `d c b a | a b c d | d c b a`, the edge pixel repeated), as
//! `scipy.ndimage.correlate1d`, `gaussian_filter`, `uniform_filter` and `sobel` compute them.
//!
//! Axis 0 runs down the rows (y), axis 1 along a row (x), as in numpy's `(H, W)` arrays.

use rayon::prelude::*;

/// Rows per rayon task; below this much work the filters stay on one thread.
const PAR_MIN_PIXELS: usize = 64 * 1024;

/// A row-major f64 plane.
#[derive(Clone, Debug)]
pub(crate) struct PlaneF64 {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f64>,
}

impl PlaneF64 {
    pub fn new(width: usize, height: usize, data: Vec<f64>) -> Self {
        debug_assert_eq!(data.len(), width * height);
        Self {
            width,
            height,
            data,
        }
    }

    /// Elementwise map of two planes of the same size.
    pub fn zip_map(&self, other: &Self, f: impl Fn(f64, f64) -> f64 + Sync) -> Self {
        let data = self
            .data
            .iter()
            .zip(&other.data)
            .map(|(&a, &b)| f(a, b))
            .collect();
        Self::new(self.width, self.height, data)
    }
}

/// Index of sample `i` (which may lie outside `0..n`) under scipy's `reflect` mode.
#[inline]
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let period = 2 * n;
    let mut j = i.rem_euclid(period);
    if j >= n {
        j = period - 1 - j;
    }
    j as usize
}

/// The normalised Gaussian taps of `scipy.ndimage.gaussian_filter1d`:
/// radius `int(truncate * sigma + 0.5)`, weights `exp(-0.5 / sigma^2 * x^2)` over their sum.
pub(crate) fn gaussian_kernel(sigma: f64, truncate: f64) -> Vec<f64> {
    let radius = (truncate * sigma + 0.5) as isize;
    let sigma2 = sigma * sigma;
    let raw: Vec<f64> = (-radius..=radius)
        .map(|x| (-0.5 / sigma2 * (x * x) as f64).exp())
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|w| w / sum).collect()
}

/// `scipy.ndimage.correlate1d(plane, weights, axis=1, mode="reflect")` for an odd number of taps.
pub(crate) fn correlate_axis1(p: &PlaneF64, weights: &[f64]) -> PlaneF64 {
    let (w, h) = (p.width, p.height);
    let r = weights.len() / 2;
    let mut out = vec![0.0; w * h];
    let run_row = |(src, dst): (&[f64], &mut [f64])| {
        let mut padded = Vec::with_capacity(w + 2 * r);
        for i in 0..w + 2 * r {
            padded.push(src[reflect(i as isize - r as isize, w)]);
        }
        // Tap-major accumulation: the same summation order per output as a per-pixel dot
        // product, but each pass runs along the row and vectorises.
        for (k, &wt) in weights.iter().enumerate() {
            for (o, s) in dst.iter_mut().zip(&padded[k..k + w]) {
                *o += wt * s;
            }
        }
    };
    if w * h >= PAR_MIN_PIXELS {
        p.data
            .par_chunks(w)
            .zip(out.par_chunks_mut(w))
            .for_each(run_row);
    } else {
        p.data.chunks(w).zip(out.chunks_mut(w)).for_each(run_row);
    }
    PlaneF64::new(w, h, out)
}

/// `scipy.ndimage.correlate1d(plane, weights, axis=0, mode="reflect")` for an odd number of taps.
pub(crate) fn correlate_axis0(p: &PlaneF64, weights: &[f64]) -> PlaneF64 {
    let (w, h) = (p.width, p.height);
    let r = weights.len() as isize / 2;
    let mut out = vec![0.0; w * h];
    let run_row = |(y, dst): (usize, &mut [f64])| {
        for (k, &wt) in weights.iter().enumerate() {
            let sy = reflect(y as isize + k as isize - r, h);
            let src = &p.data[sy * w..(sy + 1) * w];
            for (o, s) in dst.iter_mut().zip(src) {
                *o += wt * s;
            }
        }
    };
    if w * h >= PAR_MIN_PIXELS {
        out.par_chunks_mut(w).enumerate().for_each(run_row);
    } else {
        out.chunks_mut(w).enumerate().for_each(run_row);
    }
    PlaneF64::new(w, h, out)
}

/// `scipy.ndimage.gaussian_filter(plane, sigma, mode="reflect", truncate=truncate)` (axis 0 first).
pub(crate) fn gaussian_filter(p: &PlaneF64, kernel: &[f64]) -> PlaneF64 {
    correlate_axis1(&correlate_axis0(p, kernel), kernel)
}

/// `scipy.ndimage.uniform_filter(plane, size, mode="reflect")` for odd `size`.
pub(crate) fn uniform_filter(p: &PlaneF64, size: usize) -> PlaneF64 {
    let k = vec![1.0 / size as f64; size];
    correlate_axis1(&correlate_axis0(p, &k), &k)
}

/// Sobel derivative taps and the smoothing taps across, as `scipy.ndimage.sobel`.
const SOBEL_DERIVATIVE: [f64; 3] = [-1.0, 0.0, 1.0];
const SOBEL_SMOOTH: [f64; 3] = [1.0, 2.0, 1.0];

/// Gradient magnitude `hypot(sobel(p, axis=0), sobel(p, axis=1))` with scipy's reflect border.
pub(crate) fn sobel_magnitude(p: &PlaneF64) -> PlaneF64 {
    let d0 = correlate_axis1(&correlate_axis0(p, &SOBEL_DERIVATIVE), &SOBEL_SMOOTH);
    let d1 = correlate_axis0(&correlate_axis1(p, &SOBEL_DERIVATIVE), &SOBEL_SMOOTH);
    d0.zip_map(&d1, f64::hypot)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect_repeats_the_edge_sample() {
        let idx: Vec<usize> = (-3..7).map(|i| reflect(i, 4)).collect();
        assert_eq!(idx, vec![2, 1, 0, 0, 1, 2, 3, 3, 2, 1]);
        // Overhang longer than the signal keeps reflecting.
        assert_eq!(reflect(-5, 2), 0);
        assert_eq!(reflect(9, 2), 1);
    }

    #[test]
    fn gaussian_kernel_matches_scipy_taps() {
        // scipy.ndimage._filters._gaussian_kernel1d(1.5, 0, 5)
        let k = gaussian_kernel(1.5, 3.5);
        assert_eq!(k.len(), 11);
        let want_center = 0.266_011_724_861_794_36;
        let want_edge = 0.001_028_380_084_479_11;
        assert!((k[5] - want_center).abs() < 1e-12, "{}", k[5]);
        assert!((k[0] - want_edge).abs() < 1e-12, "{}", k[0]);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn correlation_uses_reflected_borders() {
        let p = PlaneF64::new(4, 1, vec![1.0, 2.0, 3.0, 4.0]);
        let out = correlate_axis1(&p, &[1.0, 0.0, 0.0]); // picks the left neighbour
        assert_eq!(out.data, vec![1.0, 1.0, 2.0, 3.0]);
        let t = PlaneF64::new(1, 4, vec![1.0, 2.0, 3.0, 4.0]);
        let out = correlate_axis0(&t, &[0.0, 0.0, 1.0]); // picks the next row
        assert_eq!(out.data, vec![2.0, 3.0, 4.0, 4.0]);
    }

    #[test]
    fn sobel_of_a_ramp_is_eight_times_the_slope() {
        // d/dx of x is 1; the [1, 2, 1] smoothing multiplies by 4 and [-1, 0, 1] by 2.
        let w = 6;
        let p = PlaneF64::new(w, 5, (0..30).map(|i| (i % w) as f64).collect());
        let m = sobel_magnitude(&p);
        assert_eq!(m.data[2 * w + 2], 8.0);
        // At the reflected border the step is half as large.
        assert_eq!(m.data[2 * w], 4.0);
    }
}
