//! Background (veiling) light of a real underwater image by quadtree search, as Hou et al. 2020
//! (SUID, "Benchmarking underwater image enhancement and restoration, and beyond", IEEE Access 8)
//! estimate it: split the region into four quadrants, score each by `mean − std` of its values,
//! recurse into the best one until the region holds fewer than 1% of the pixels, then read the
//! light off the final region.
//!
//! A bright, flat region is open water far from the camera, where the image is the background
//! light alone. The score is taken over all three channels' values together, as the public
//! re-implementation `vismiroglou/SUID_data_generation` computes it (`np.mean(region) −
//! np.std(region)`); ties go to the first quadrant in the order top-left, top-right,
//! bottom-left, bottom-right. How the colour is read off the final region is a choice
//! ([`BackgroundPick`]); the paper's text leaves it open.

use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::common::{check_image, check_in};
use crate::error::Result;

/// SUID's stopping size: recurse while the region holds more than 1% of the image's pixels.
pub const SUID_MIN_REGION_FRACTION: f64 = 0.01;
/// Rank, from the brightest, of the pixel [`BackgroundPick::QuarterRank`] takes: the pixel at
/// the 25% mark of the region sorted by decreasing `R + G + B`, as the SUID re-implementation
/// above reads the paper.
const QUARTER_RANK: f64 = 0.25;

/// How the background light is read off the final quadtree region.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackgroundPick {
    /// Mean colour of the region (default): robust to noise and JPEG artefacts.
    #[default]
    Mean,
    /// The brightest pixel of the region (largest `R + G + B`), as dark-channel methods pick it.
    Brightest,
    /// The pixel at the 25% mark of the region sorted by decreasing `R + G + B`.
    QuarterRank,
}

/// Pixel rectangle `[x, x + w) × [y, y + h)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Rect {
    x: usize,
    y: usize,
    w: usize,
    h: usize,
}

/// `mean − std` (population std) of all values of the three channels inside `r`.
fn score(img: &Image, r: Rect) -> f64 {
    let mut sum = 0.0f64;
    let mut sum_sq = 0.0f64;
    for c in 0..3 {
        let p = img.plane(c);
        for row in p.chunks_exact(img.width()).skip(r.y).take(r.h) {
            for &v in &row[r.x..r.x + r.w] {
                let v = f64::from(v);
                sum += v;
                sum_sq += v * v;
            }
        }
    }
    let n = (3 * r.w * r.h) as f64;
    let mean = sum / n;
    let var = (sum_sq / n - mean * mean).max(0.0);
    mean - var.sqrt()
}

/// The quadtree search: the final region.
fn search(img: &Image, min_fraction: f64) -> Rect {
    let total = (img.width() * img.height()) as f64;
    let mut r = Rect {
        x: 0,
        y: 0,
        w: img.width(),
        h: img.height(),
    };
    while (r.w * r.h) as f64 > min_fraction * total && r.w >= 2 && r.h >= 2 {
        let (hw, hh) = (r.w / 2, r.h / 2);
        let quadrants = [
            Rect {
                x: r.x,
                y: r.y,
                w: hw,
                h: hh,
            },
            Rect {
                x: r.x + hw,
                y: r.y,
                w: r.w - hw,
                h: hh,
            },
            Rect {
                x: r.x,
                y: r.y + hh,
                w: hw,
                h: r.h - hh,
            },
            Rect {
                x: r.x + hw,
                y: r.y + hh,
                w: r.w - hw,
                h: r.h - hh,
            },
        ];
        let mut best = quadrants[0];
        let mut best_score = score(img, best);
        for q in &quadrants[1..] {
            let s = score(img, *q);
            if s > best_score {
                best = *q;
                best_score = s;
            }
        }
        r = best;
    }
    r
}

/// Background light (RGB in [0, 1]) of the underwater image `img` by SUID's quadtree search.
///
/// `min_fraction` is the stopping size as a fraction of the pixels, in (0, 1]
/// ([`SUID_MIN_REGION_FRACTION`] in the paper).
pub fn quadtree_background(
    img: &Image,
    min_fraction: f64,
    pick: BackgroundPick,
) -> Result<[f64; 3]> {
    check_image(img, "reference", 3)?;
    check_in(
        "min_region_fraction",
        min_fraction,
        f64::MIN_POSITIVE,
        1.0,
        "must be in (0, 1]",
    )?;
    let r = search(img, min_fraction);
    let px = |x: usize, y: usize| -> [f64; 3] { [0, 1, 2].map(|c| f64::from(img.get(c, y, x))) };
    let pixels = (r.y..r.y + r.h).flat_map(|y| (r.x..r.x + r.w).map(move |x| (x, y)));
    let light = match pick {
        BackgroundPick::Mean => {
            let mut sum = [0.0f64; 3];
            for (x, y) in pixels {
                let p = px(x, y);
                for c in 0..3 {
                    sum[c] += p[c];
                }
            }
            let n = (r.w * r.h) as f64;
            sum.map(|s| s / n)
        }
        BackgroundPick::Brightest => {
            let mut best = px(r.x, r.y);
            for (x, y) in pixels {
                let p = px(x, y);
                if p.iter().sum::<f64>() > best.iter().sum::<f64>() {
                    best = p;
                }
            }
            best
        }
        BackgroundPick::QuarterRank => {
            let mut all: Vec<[f64; 3]> = pixels.map(|(x, y)| px(x, y)).collect();
            // Stable sort by decreasing brightness keeps the result independent of the platform.
            all.sort_by(|a, b| b.iter().sum::<f64>().total_cmp(&a.iter().sum::<f64>()));
            let k = ((all.len() as f64 * QUARTER_RANK) as usize).min(all.len() - 1);
            all[k]
        }
    };
    Ok(light)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 20x20 image: dark texture except a flat bright bottom-right quadrant.
    fn scene() -> Image {
        let (w, h) = (20, 20);
        let mut data = vec![0.0f32; 3 * w * h];
        for c in 0..3 {
            for y in 0..h {
                for x in 0..w {
                    let v = if x >= 10 && y >= 10 {
                        [0.2, 0.6, 0.8][c]
                    } else {
                        (((x * 7 + y * 13 + c * 5) % 10) as f32) / 20.0
                    };
                    data[(c * h + y) * w + x] = v;
                }
            }
        }
        Image::from_planar(w, h, 3, data).unwrap()
    }

    #[test]
    fn search_descends_into_the_flat_bright_corner() {
        let img = scene();
        // 1% of 400 px is 4 px: sides 20 -> 10 -> 5 -> 2, inside the flat quadrant.
        let r = search(&img, 0.01);
        assert_eq!(
            r,
            Rect {
                x: 10,
                y: 10,
                w: 2,
                h: 2
            }
        );
        let b = quadtree_background(&img, 0.01, BackgroundPick::Mean).unwrap();
        for (got, want) in b.iter().zip([0.2, 0.6, 0.8]) {
            assert!((got - want).abs() < 1e-6, "{b:?}");
        }
    }

    #[test]
    fn picks_differ_as_documented() {
        // One region of four pixels with brightness 0.1, 0.2, 0.3, 0.4 (grey).
        let v = [0.1f32, 0.2, 0.3, 0.4];
        let data: Vec<f32> = (0..3).flat_map(|_| v).collect();
        let img = Image::from_planar(2, 2, 3, data).unwrap();
        // min_fraction 1: no split at all.
        let mean = quadtree_background(&img, 1.0, BackgroundPick::Mean).unwrap();
        assert!((mean[0] - 0.25).abs() < 1e-6);
        let top = quadtree_background(&img, 1.0, BackgroundPick::Brightest).unwrap();
        assert!((top[0] - 0.4).abs() < 1e-6);
        let q = quadtree_background(&img, 1.0, BackgroundPick::QuarterRank).unwrap();
        assert!((q[0] - 0.3).abs() < 1e-6, "{q:?}");
        assert!(quadtree_background(&img, 0.0, BackgroundPick::Mean).is_err());
    }
}
