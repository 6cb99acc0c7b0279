//! The normalised Gaussian blur of the render's smooth fields and of detail retention: the
//! kernel `exp(-x^2 / (2 sigma^2))` truncated at [`BLUR_TRUNCATE_SIGMAS`] sigmas (and at the image
//! size), renormalised over the part inside the image (a normalised convolution), separable.
//! The training wing's tensor form is `uwnr-train`'s `burn_style::gaussian_blur`.

use rayon::prelude::*;

/// Where the Gaussian kernels are truncated, in sigmas.
pub const BLUR_TRUNCATE_SIGMAS: f64 = 3.0;

/// Normalised Gaussian kernel `exp(-x^2 / (2 sigma^2))`, `x = -radius..=radius`.
#[must_use]
pub fn gaussian_kernel(sigma: f64, radius: usize) -> Vec<f64> {
    let r = radius as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-((i * i) as f64) / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = k.iter().sum();
    k.into_iter().map(|v| v / total).collect()
}

/// For a signal of length `n`, the kernel mass that falls inside it at each position: the
/// normaliser of a zero-padded convolution.
pub fn inside_mass(kernel: &[f64], n: usize) -> Vec<f64> {
    let r = (kernel.len() / 2) as i64;
    (0..n as i64)
        .map(|i| {
            (-r..=r)
                .filter(|k| (0..n as i64).contains(&(i + k)))
                .map(|k| kernel[(k + r) as usize])
                .sum()
        })
        .collect()
}

/// Radius of the blur of `sigma` along an axis of `n` pixels.
pub fn blur_radius(sigma: f64, n: usize) -> usize {
    ((BLUR_TRUNCATE_SIGMAS * sigma).ceil() as usize).min(n.saturating_sub(1))
}

/// Gaussian blur of one `h x w` plane, in place, with the kernel truncated at
/// [`BLUR_TRUNCATE_SIGMAS`] sigmas (and at the image size) and renormalised over the part
/// inside the image at the borders (normalised convolution): a constant plane stays constant.
/// Rows in parallel. The training wing's tensor blur (`uwnr-train`) is the same operation.
pub fn blur_plane(p: &mut [f32], w: usize, h: usize, sigma: f64) {
    let (rx, ry) = (blur_radius(sigma, w), blur_radius(sigma, h));
    let (kx, ky) = (gaussian_kernel(sigma, rx), gaussian_kernel(sigma, ry));
    let (mx, my) = (inside_mass(&kx, w), inside_mass(&ky, h));
    // Each pass adds one kernel tap to a whole row at a time (the loops vectorise), in the tap
    // order of a pixel-by-pixel sum, so every pixel gets the same sum in the same order.
    let mut tmp = vec![0.0f32; w * h];
    tmp.par_chunks_mut(w).zip(p.par_chunks(w)).for_each_init(
        || vec![0.0f64; w],
        |acc, (out, row)| {
            acc.fill(0.0);
            for (k, &kv) in kx.iter().enumerate() {
                // Output x reads row[x + k - rx]: x in lo..hi stays inside the row.
                let (lo, hi) = (rx.saturating_sub(k), (w + rx).saturating_sub(k).min(w));
                if lo >= hi {
                    continue;
                }
                let src = &row[lo + k - rx..hi + k - rx];
                for (a, &v) in acc[lo..hi].iter_mut().zip(src) {
                    *a += kv * f64::from(v);
                }
            }
            for (o, &a) in out.iter_mut().zip(acc.iter()) {
                *o = a as f32;
            }
        },
    );
    p.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0.0f64; w],
        |acc, (y, out)| {
            acc.fill(0.0);
            for (k, &kv) in ky.iter().enumerate() {
                let Some(sy) = (y + k).checked_sub(ry).filter(|&sy| sy < h) else {
                    continue;
                };
                for (a, &v) in acc.iter_mut().zip(&tmp[sy * w..(sy + 1) * w]) {
                    *a += kv * f64::from(v);
                }
            }
            for ((o, &a), &m) in out.iter_mut().zip(acc.iter()).zip(&mx) {
                *o = (a / (m * my[y])) as f32;
            }
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_blurred_constant_stays_constant() {
        let mut p = vec![0.3f32; 7 * 5];
        blur_plane(&mut p, 7, 5, 4.0);
        assert!(p.iter().all(|v| (v - 0.3).abs() < 1e-6), "{p:?}");
    }

    /// The blur as it was first written, pixel by pixel: the row-at-a-time blur must give the
    /// same bits.
    fn blur_pixelwise(p: &mut [f32], w: usize, h: usize, sigma: f64) {
        let (rx, ry) = (blur_radius(sigma, w), blur_radius(sigma, h));
        let (kx, ky) = (gaussian_kernel(sigma, rx), gaussian_kernel(sigma, ry));
        let (mx, my) = (inside_mass(&kx, w), inside_mass(&ky, h));
        let mut tmp = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0f64;
                for (k, &kv) in kx.iter().enumerate() {
                    let sx = x as i64 + k as i64 - rx as i64;
                    if (0..w as i64).contains(&sx) {
                        s += kv * f64::from(p[y * w + sx as usize]);
                    }
                }
                tmp[y * w + x] = s as f32;
            }
        }
        for y in 0..h {
            for x in 0..w {
                let mut s = 0.0f64;
                for (k, &kv) in ky.iter().enumerate() {
                    let sy = y as i64 + k as i64 - ry as i64;
                    if (0..h as i64).contains(&sy) {
                        s += kv * f64::from(tmp[sy as usize * w + x]);
                    }
                }
                p[y * w + x] = (s / (mx[x] * my[y])) as f32;
            }
        }
    }

    #[test]
    fn the_row_blur_gives_the_pixelwise_sums_bit_for_bit() {
        for (w, h, sigma) in [
            (37, 23, 0.8),
            (64, 48, 3.0),
            (5, 90, 12.0),
            (1, 7, 2.0),
            (9, 1, 1.0),
        ] {
            let plane: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919 % 1000) as f32 / 1000.0).powf(1.3))
                .collect();
            let (mut a, mut b) = (plane.clone(), plane);
            blur_plane(&mut a, w, h, sigma);
            blur_pixelwise(&mut b, w, h, sigma);
            assert!(
                a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{w}x{h} sigma {sigma}"
            );
        }
    }
}
