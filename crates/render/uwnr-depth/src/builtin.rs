//! Built-in depth prior: a ground-plane ramp plus a local-contrast cue, smoothed at a fixed
//! fraction of the image size. Needs no weights, takes milliseconds, and is deterministic.
//!
//! ```text
//! grid   = the image shrunk (antialiased bilinear) so its long side is GRID_LONG_SIDE cells
//! L      = ITU-R 601 luma of the clean image
//! sigma  = sqrt(max(0, E[L^2] - E[L]^2))   per grid cell (E = the antialiased shrink)
//! c      = (max sigma - sigma) / max(max sigma - min sigma, MIN_CONTRAST_SPREAD)
//!                                                         contrast cue: 1 = flattest cell
//! r      = 1 - (row + 0.5) / rows                         ramp: 1 at the top, ~0 at the bottom
//! g      = RAMP_WEIGHT * r + CONTRAST_WEIGHT * c
//! g      = Gaussian blur of g, sigma = SMOOTH_SIGMA_FRACTION * long side of the grid (in cells)
//! depth  = min-max normalise(bilinear resize of g to the image size)      in [0, 1], far = 1
//! ```
//!
//! Why these two cues:
//! - **Ground-plane ramp.** In ordinary photos taken upright (indoor and outdoor) the floor or
//!   ground fills the bottom of the frame close to the camera and recedes towards the horizon,
//!   so distance grows towards the top ("gravity" / ground-plane prior of single-image depth
//!   work, e.g. Hoiem, Efros & Hebert 2005, "Automatic photo pop-up"). It is by far the strongest
//!   cheap cue on the RGB-D images we checked (`tests/suite/rgbd_eval.rs`).
//! - **Local contrast.** Near surfaces show resolved texture and sharp object boundaries;
//!   distant regions, walls and sky are flatter (aerial perspective lowers contrast with
//!   distance, the cue behind haze priors such as He et al. 2009's dark channel). The cue only
//!   modulates the ramp ([`CONTRAST_WEIGHT`] is a quarter) so that a textured object reads a
//!   little nearer than the flat wall behind it. Colour cues (Zhu et al. 2015's colour
//!   attenuation prior `depth ~ 0.96 V - 0.78 S`, saturation alone, the dark channel) were
//!   tried too: on clear in-air photos they read bright near objects (white furniture, lit
//!   walls) as far and lowered the rank correlation with true depth, so they are not used.
//!
//! Measured on the 12 RGB-D images of `../shared/data/rgbd` (NYU-v2 3, Redwood 5, KITTI 3,
//! SUN RGB-D 1; valid pixels only), mean correlation with true depth:
//!
//! | map | Spearman | Pearson | Spearman, 9 indoor |
//! |---|---|---|---|
//! | plain ramp `1 - (y + 0.5) / h` | 0.625 | 0.589 | 0.511 |
//! | this prior | 0.625 | 0.579 | 0.516 |
//!
//! The contrast cue does not improve the rank correlation on average (it helps on the real
//! indoor NYU / SUN RGB-D photos, costs a little on KITTI's road scenes and the synthetic
//! Redwood room); it is kept because it makes the map depend on the content in the direction
//! that matters for rendering (a textured foreground object gets less water than the flat
//! background behind it) without hurting the ranking. Twelve images are too few to tune
//! weights on, so the weights are round numbers, not fitted values.
//!
//! Everything is computed on a coarse grid (about 48 cells on the long side) and blurred there,
//! so the map has no texture at any image size and costs a few milliseconds; the same photo at
//! two resolutions gives nearly the same map. The final min-max normalisation makes the map a
//! *relative* depth spanning [0, 1], like the normalised maps of a monocular depth network.
//! Images no larger than the grid are used as they are: their cells are single pixels, the
//! contrast cue is then constant and the map is the pure ramp.

use uwnr_core::Image;
use uwnr_core::resize::{fit_within_dims, resize_bilinear};

use crate::error::Result;
use crate::util::{MIN_RANGE, min_max, normalise_min_max, rgb_planes};

/// Cells on the long side of the working grid: the cues are resolved at about 1/48 of the
/// image size, coarse enough to carry no texture, fine enough to follow large objects.
pub const GRID_LONG_SIDE: usize = 48;
/// Weight of the ground-plane ramp (top of the frame = far).
pub const RAMP_WEIGHT: f32 = 0.75;
/// Weight of the local-contrast cue (flat, low-contrast cells = far).
pub const CONTRAST_WEIGHT: f32 = 0.25;
/// Standard deviation of the Gaussian that smooths the grid, as a fraction of the grid's long
/// side (1.5 cells of a 48-cell grid, about 3% of the image's long side).
pub const SMOOTH_SIGMA_FRACTION: f32 = 1.5 / GRID_LONG_SIDE as f32;
/// Smallest spread (max - min) of the local luma standard deviation that counts fully as
/// texture contrast, 5/255: smaller differences (JPEG noise, grain) shift the cue
/// proportionally less, and a flat image gets no contrast cue at all.
pub const MIN_CONTRAST_SPREAD: f32 = 5.0 / 255.0;
/// The Gaussian is truncated at this many standard deviations.
const GAUSS_TRUNCATE: f32 = 3.0;
/// ITU-R BT.601 luma weights (R, G, B), as `uwnr_core::io` uses for grey conversion.
const LUMA_601: [f32; 3] = [0.299, 0.587, 0.114];
/// Value of the map when every cue is flat (a 1-pixel-tall uniform image): mid-depth.
const FLAT_DEPTH: f32 = 0.5;

/// The built-in relative depth of a clean image (1 or 3 channels): a 1-channel map of the same
/// size in [0, 1], larger = farther. See the module documentation for the formula.
pub fn builtin_depth(clean: &Image) -> Result<Image> {
    let [r, g, b] = rgb_planes(clean)?;
    let (width, height) = clean.size();

    // Luma (centred on its mean, so a flat image has exactly zero variance and f32 rounding
    // in E[L^2] - E[L]^2 stays small) and its square, shrunk together: the shrink's weights are
    // the local averages E[.].
    let n = width * height;
    let mut moments = vec![0.0_f32; 2 * n];
    let (luma, luma_sq) = moments.split_at_mut(n);
    for i in 0..n {
        luma[i] = LUMA_601[0] * r[i] + LUMA_601[1] * g[i] + LUMA_601[2] * b[i];
    }
    let mean = (luma.iter().map(|&l| f64::from(l)).sum::<f64>() / n as f64) as f32;
    for (l, l2) in luma.iter_mut().zip(luma_sq.iter_mut()) {
        *l -= mean;
        *l2 = *l * *l;
    }
    let moments = Image::from_planar(width, height, 2, moments)?;
    let (gw, gh) = grid_size(width, height);
    let moments = resize_bilinear(&moments, gw, gh)?;

    // Contrast cue: 1 where the local standard deviation is smallest, scaled by the spread of
    // the standard deviations (at least MIN_CONTRAST_SPREAD, so noise is not amplified).
    let sigma: Vec<f32> = moments
        .plane(0)
        .iter()
        .zip(moments.plane(1))
        .map(|(&m, &m2)| (m2 - m * m).max(0.0).sqrt())
        .collect();
    let (lo, hi) = min_max(&sigma).unwrap_or((0.0, 0.0));
    let spread = (hi - lo).max(MIN_CONTRAST_SPREAD);
    let contrast: Vec<f32> = sigma.iter().map(|&s| (hi - s) / spread).collect();

    let mut grid = vec![0.0_f32; gw * gh];
    for (y, row) in grid.chunks_exact_mut(gw).enumerate() {
        let ramp = 1.0 - (y as f32 + 0.5) / gh as f32;
        for (x, v) in row.iter_mut().enumerate() {
            *v = RAMP_WEIGHT * ramp + CONTRAST_WEIGHT * contrast[y * gw + x];
        }
    }
    let sigma_cells = SMOOTH_SIGMA_FRACTION * gw.max(gh) as f32;
    let grid = gaussian_blur(&grid, gw, gh, sigma_cells);

    let grid = Image::from_planar(gw, gh, 1, grid)?;
    let mut depth = resize_bilinear(&grid, width, height)?;
    let values = depth.plane_mut(0);
    if normalise_min_max(values).is_none() {
        values.fill(FLAT_DEPTH);
    }
    Ok(depth)
}

/// Size of the working grid: the image scaled so its long side is [`GRID_LONG_SIDE`], never
/// enlarged, at least one cell per side.
fn grid_size(width: usize, height: usize) -> (usize, usize) {
    fit_within_dims((width, height), GRID_LONG_SIDE)
}

/// Separable Gaussian blur of a `width x height` plane with clamp-to-edge borders.
fn gaussian_blur(plane: &[f32], width: usize, height: usize, sigma: f32) -> Vec<f32> {
    if sigma < MIN_RANGE {
        return plane.to_vec();
    }
    let radius = (GAUSS_TRUNCATE * sigma).ceil() as isize;
    let mut kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-((i * i) as f32) / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f32 = kernel.iter().sum();
    for k in &mut kernel {
        *k /= total;
    }
    let clamp = |i: isize, len: usize| i.clamp(0, len as isize - 1) as usize;

    let mut tmp = vec![0.0_f32; plane.len()];
    for y in 0..height {
        let row = &plane[y * width..(y + 1) * width];
        for x in 0..width {
            tmp[y * width + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, &w)| w * row[clamp(x as isize + k as isize - radius, width)])
                .sum();
        }
    }
    let mut out = vec![0.0_f32; plane.len()];
    for y in 0..height {
        for x in 0..width {
            out[y * width + x] = kernel
                .iter()
                .enumerate()
                .map(|(k, &w)| w * tmp[clamp(y as isize + k as isize - radius, height) * width + x])
                .sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_keeps_aspect_and_never_enlarges() {
        assert_eq!(grid_size(640, 480), (48, 36));
        assert_eq!(grid_size(480, 640), (36, 48));
        assert_eq!(grid_size(4000, 10), (48, 1));
        assert_eq!(grid_size(30, 20), (30, 20));
    }

    #[test]
    fn blur_preserves_a_constant_and_the_mean_of_a_spike() {
        let flat = gaussian_blur(&[0.25; 20], 5, 4, 1.5);
        assert!(flat.iter().all(|v| (v - 0.25).abs() < 1e-6));
        // A centred spike far from the borders keeps its mass.
        let mut spike = vec![0.0; 21 * 21];
        spike[10 * 21 + 10] = 1.0;
        let out = gaussian_blur(&spike, 21, 21, 1.5);
        assert!((out.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!(out[10 * 21 + 10] < 0.1);
    }
}
