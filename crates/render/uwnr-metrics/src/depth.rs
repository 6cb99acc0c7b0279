//! How distance acts within one render: the *depth effect*, the contrast a render keeps in the
//! far part of a scene relative to its near part, against the same with a constant depth map.
//!
//! Per block of [`DEPTH_BLOCK`] x [`DEPTH_BLOCK`] pixels: the render's BT.601 luminance standard
//! deviation over the clean photo's (the contrast the render keeps there). Blocks are ranked by
//! their mean depth; *far* is the farthest quarter, *near* the nearest. With the median kept
//! contrast of each group, the far/near ratio measures how much hazier the far part is:
//!
//! ```text
//! effect = (far / near with the real map) / (far / near with a constant map)
//! ```
//!
//! 1 means distance does nothing within the image; water gives less than 1 (farther is
//! hazier). The constant-map render cancels what a method does to the image as a whole and what
//! the photo's own far and near parts look like. Blocks whose clean contrast is below
//! [`FLAT_BLOCK_STD`] are skipped (their ratio is noise).

use uwnr_core::Image;

use crate::error::{MetricsError, Result};
use crate::psnr::LUMA_BT601;

/// Side of the blocks, pixels.
pub const DEPTH_BLOCK: usize = 16;
/// Clean luminance standard deviation below which a block is flat and skipped (2 codes of 255).
pub const FLAT_BLOCK_STD: f64 = 2.0 / 255.0;

/// Luminance of every pixel.
fn luma(img: &Image) -> Vec<f64> {
    let n = img.width() * img.height();
    (0..n)
        .map(|i| {
            (0..3)
                .map(|c| LUMA_BT601[c] * f64::from(img.plane(c)[i]))
                .sum()
        })
        .collect()
}

/// Mean and standard deviation of `v` over the block at `(bx, by)`.
fn block_stats(v: &[f64], w: usize, bx: usize, by: usize) -> (f64, f64) {
    let (mut s, mut s2) = (0.0, 0.0);
    for y in by * DEPTH_BLOCK..(by + 1) * DEPTH_BLOCK {
        for x in bx * DEPTH_BLOCK..(bx + 1) * DEPTH_BLOCK {
            let a = v[y * w + x];
            s += a;
            s2 += a * a;
        }
    }
    let n = (DEPTH_BLOCK * DEPTH_BLOCK) as f64;
    let m = s / n;
    (m, (s2 / n - m * m).max(0.0).sqrt())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// The far/near ratio of the contrast `render` keeps of `clean` (module doc), blocks ranked by
/// `depth` (1 plane, larger = farther). `None` when fewer than 4 blocks in each quarter have
/// contrast to measure.
pub fn far_near_contrast(clean: &Image, render: &Image, depth: &Image) -> Result<Option<f64>> {
    let (w, h) = clean.size();
    for (im, channels) in [(clean, 3), (render, 3), (depth, 1)] {
        if im.size() != (w, h) || im.channels() != channels {
            return Err(MetricsError::ShapeMismatch {
                pred: (im.width(), im.height(), im.channels()),
                target: (w, h, channels),
            });
        }
    }
    let (lc, lr) = (luma(clean), luma(render));
    let d: Vec<f64> = depth.plane(0).iter().map(|&v| f64::from(v)).collect();
    let mut blocks: Vec<(f64, Option<f64>)> = Vec::new();
    for by in 0..h / DEPTH_BLOCK {
        for bx in 0..w / DEPTH_BLOCK {
            let (_, sc) = block_stats(&lc, w, bx, by);
            let (_, sr) = block_stats(&lr, w, bx, by);
            let (md, _) = block_stats(&d, w, bx, by);
            blocks.push((md, (sc >= FLAT_BLOCK_STD).then(|| sr / sc)));
        }
    }
    blocks.sort_by(|a, b| a.0.total_cmp(&b.0));
    let quarter = blocks.len() / 4;
    let kept = |part: &[(f64, Option<f64>)]| -> Option<f64> {
        let v: Vec<f64> = part.iter().filter_map(|b| b.1).collect();
        (v.len() >= 4).then(|| median(v))
    };
    let near = kept(&blocks[..quarter]);
    let far = kept(&blocks[blocks.len() - quarter..]);
    Ok(match (far, near) {
        (Some(f), Some(n)) if n > 0.0 => Some(f / n),
        _ => None,
    })
}

/// The depth effect (module doc) of a method that rendered `clean` as `real` with its real
/// depth map `depth` and as `constant` with a constant map. `None` when it cannot be measured.
pub fn depth_effect(
    clean: &Image,
    real: &Image,
    constant: &Image,
    depth: &Image,
) -> Result<Option<f64>> {
    let with_real = far_near_contrast(clean, real, depth)?;
    let with_constant = far_near_contrast(clean, constant, depth)?;
    Ok(match (with_real, with_constant) {
        (Some(r), Some(c)) if c > 0.0 => Some(r / c),
        _ => None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64x64 checkerboard clean image, depth rising down the image, and a render that keeps
    /// `keep(depth)` of the contrast.
    fn case(keep: impl Fn(f32) -> f32) -> (Image, Image, Image) {
        let (w, h) = (64, 64);
        let depth: Vec<f32> = (0..w * h)
            .map(|i| (i / w) as f32 / (h - 1) as f32)
            .collect();
        let clean: Vec<f32> = (0..w * h)
            .map(|i| if (i / w + i % w) % 2 == 0 { 0.8 } else { 0.2 })
            .collect();
        let render: Vec<f32> = clean
            .iter()
            .zip(&depth)
            .map(|(&c, &d)| 0.5 + (c - 0.5) * keep(d))
            .collect();
        let rgb = |p: &[f32]| Image::from_planar(w, h, 3, [p, p, p].concat()).unwrap();
        (
            rgb(&clean),
            rgb(&render),
            Image::from_planar(w, h, 1, depth).unwrap(),
        )
    }

    #[test]
    fn uniform_contrast_has_no_effect_and_haze_with_distance_has_one() {
        let (clean, flat, depth) = case(|_| 0.5);
        let r = far_near_contrast(&clean, &flat, &depth).unwrap().unwrap();
        assert!((r - 1.0).abs() < 1e-9, "{r}");
        let (_, hazy, _) = case(|d| 1.0 - 0.8 * d);
        let e = depth_effect(&clean, &hazy, &flat, &depth).unwrap().unwrap();
        // Far quarter keeps ~1 - 0.8 * 0.875, near ~1 - 0.8 * 0.125.
        assert!(e < 0.4 && e > 0.2, "{e}");
    }
}
