//! The one rule for label geometry, the same for COCO, YOLO and masks, at the native size and
//! resized alike:
//!
//! 1. **Malformed input fails.** What cannot be read as the format says (not parseable, an
//!    odd-length polygon, a negative width or height, NaN, a wrong type, an RLE mask or label
//!    mask of another size than its image) fails that image's pairs, with a reason naming the
//!    file, the annotation id or line, and what is wrong (listed in `failed.jsonl`).
//! 2. **Geometry past the image's edge is clipped** to the image, whatever the distance (no
//!    tolerance band), then carried through the pair's [`Fit`] and clipped to the pair.
//! 3. **What is left degenerate is dropped and counted** by [`Drop`] reason: wholly outside the
//!    image, removed by the `--size` crop, a polygon with fewer than 3 points or no area, a box
//!    of zero width or height, an empty mask. A dropped annotation is left out of the pair's
//!    labels (its COCO id is skipped), so nothing a reader such as pycocotools' `annToMask`
//!    cannot read is ever written.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::geometry::{Fit, shoelace};
use crate::plan::Size;

/// Why an annotation was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Drop {
    /// Wholly outside its image.
    OutsideImage,
    /// Inside its image, but removed by the `--size` crop.
    CroppedOut,
    /// A polygon with fewer than 3 points or zero area.
    DegeneratePolygon,
    /// A box of zero width or height.
    EmptyBox,
    /// A mask with no foreground pixel.
    EmptyMask,
}

impl Drop {
    /// The reason's name, as counted in manifests, summaries and `dataset.json`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::OutsideImage => "outside_image",
            Self::CroppedOut => "cropped_out",
            Self::DegeneratePolygon => "degenerate_polygon",
            Self::EmptyBox => "empty_box",
            Self::EmptyMask => "empty_mask",
        }
    }
}

/// Dropped annotations counted by reason (`{"cropped_out": 2}`; reasons with none are absent).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct DropCounts(pub BTreeMap<String, u64>);

impl DropCounts {
    /// Counts one dropped annotation.
    pub fn add(&mut self, reason: Drop) {
        *self.0.entry(reason.name().to_string()).or_default() += 1;
    }

    /// Adds every count of `other`.
    pub fn merge(&mut self, other: &Self) {
        for (k, v) in &other.0 {
            *self.0.entry(k.clone()).or_default() += v;
        }
    }

    /// No annotation was dropped.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.0.values().all(|&v| v == 0)
    }

    /// Annotations dropped, all reasons together.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.0.values().sum()
    }

    /// `cropped_out 2, outside_image 1` (empty when none).
    #[must_use]
    pub fn line(&self) -> String {
        self.0
            .iter()
            .filter(|(_, v)| **v > 0)
            .map(|(k, v)| format!("{k} {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A shape carried to the pair: its pair coordinates and whether clipping (at the image's edge
/// or the crop's) changed it.
#[derive(Clone, Debug, PartialEq)]
pub struct Kept<T> {
    pub shape: T,
    pub cut: bool,
}

/// The source image's own rectangle, as a [`Fit`] that changes nothing.
fn image_fit(fit: &Fit) -> Fit {
    Fit::new((fit.src_width, fit.src_height), Size::Native)
}

/// A box `[x0, y0, x1, y1]` of the clean image (pixel coordinates, `x0 <= x1`, `y0 <= y1`)
/// carried to the pair: clipped to the image, fitted, clipped to the pair.
pub fn fit_box(fit: &Fit, b: [f64; 4]) -> Result<Kept<[f64; 4]>, Drop> {
    if b[2] <= b[0] || b[3] <= b[1] {
        return Err(Drop::EmptyBox);
    }
    let Some((inside, cut_at_edge)) = image_fit(fit).rect(b) else {
        return Err(Drop::OutsideImage);
    };
    let Some((r, cut_by_crop)) = fit.rect(inside) else {
        return Err(Drop::CroppedOut);
    };
    Ok(Kept {
        shape: r,
        cut: cut_at_edge || cut_by_crop,
    })
}

/// A polygon `[x1, y1, ..., xn, yn]` of the clean image (an even number of finite values)
/// carried to the pair: clipped to the image, fitted, clipped to the pair.
pub fn fit_polygon(fit: &Fit, points: &[f64]) -> Result<Kept<Vec<f64>>, Drop> {
    let poly: Vec<(f64, f64)> = points.chunks_exact(2).map(|p| (p[0], p[1])).collect();
    if poly.len() < 3 || shoelace(&poly) <= 0.0 {
        return Err(Drop::DegeneratePolygon);
    }
    let image = image_fit(fit);
    let Some(inside) = image.polygon(points) else {
        return Err(Drop::OutsideImage);
    };
    let cut_at_edge = poly.iter().any(|&p| !image.inside(p));
    let Some(shape) = fit.polygon(&inside) else {
        return Err(Drop::CroppedOut);
    };
    let cut_by_crop = inside
        .chunks_exact(2)
        .any(|q| !fit.inside(fit.point(q[0], q[1])));
    Ok(Kept {
        shape,
        cut: cut_at_edge || cut_by_crop,
    })
}

/// Of several parts' reasons, the one an annotation with no part left is dropped for: the crop
/// before the image's edge before degeneracy (the most informative first).
#[must_use]
pub fn worst(reasons: &[Drop]) -> Drop {
    [Drop::CroppedOut, Drop::OutsideImage, Drop::EmptyMask]
        .into_iter()
        .find(|r| reasons.contains(r))
        .unwrap_or(Drop::DegeneratePolygon)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(width: usize, height: usize) -> Size {
        Size::Fixed { width, height }
    }

    #[test]
    fn boxes_past_the_edge_are_clipped_whatever_the_distance() {
        let native = Fit::new((40, 40), Size::Native);
        // 19 px past the right edge: clipped to [30, 30, 40, 35], not refused.
        let k = fit_box(&native, [30.0, 30.0, 59.0, 35.0]).unwrap();
        assert_eq!(k.shape, [30.0, 30.0, 40.0, 35.0]);
        assert!(k.cut);
        // 0.9 px past: clipped the same way.
        let k = fit_box(&native, [0.0, 0.0, 40.9, 10.0]).unwrap();
        assert_eq!(k.shape, [0.0, 0.0, 40.0, 10.0]);
        // Inside: unchanged.
        let k = fit_box(&native, [1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!((k.shape, k.cut), ([1.0, 2.0, 3.0, 4.0], false));
    }

    #[test]
    fn degenerate_and_outside_boxes_are_dropped_by_reason() {
        let native = Fit::new((40, 40), Size::Native);
        assert_eq!(fit_box(&native, [5.0, 5.0, 5.0, 9.0]), Err(Drop::EmptyBox));
        assert_eq!(
            fit_box(&native, [50.0, 50.0, 60.0, 60.0]),
            Err(Drop::OutsideImage)
        );
        // Touching the edge from outside leaves no area: outside.
        assert_eq!(
            fit_box(&native, [40.0, 0.0, 45.0, 10.0]),
            Err(Drop::OutsideImage)
        );
        // 400x200 to 100x100 crops 100 source px on each side.
        let fit = Fit::new((400, 200), fixed(100, 100));
        assert_eq!(fit_box(&fit, [0.0, 0.0, 90.0, 50.0]), Err(Drop::CroppedOut));
        // Past the image and across the crop: clipped twice, scaled by 0.5.
        let k = fit_box(&fit, [60.0, -30.0, 140.0, 40.0]).unwrap();
        assert_eq!(k.shape, [0.0, 0.0, 20.0, 20.0]);
    }

    #[test]
    fn polygons_follow_the_same_rule() {
        let native = Fit::new((100, 100), Size::Native);
        assert_eq!(
            fit_polygon(&native, &[1.0, 1.0, 5.0, 5.0]),
            Err(Drop::DegeneratePolygon)
        );
        // Three collinear points: no area.
        assert_eq!(
            fit_polygon(&native, &[0.0, 0.0, 5.0, 5.0, 10.0, 10.0]),
            Err(Drop::DegeneratePolygon)
        );
        assert_eq!(
            fit_polygon(&native, &[110.0, 0.0, 130.0, 0.0, 120.0, 20.0]),
            Err(Drop::OutsideImage)
        );
        // Half past the right edge: the inside half, 20x40.
        let k = fit_polygon(&native, &[80.0, 10.0, 120.0, 10.0, 120.0, 50.0, 80.0, 50.0]).unwrap();
        assert!(k.cut);
        assert!((super::super::geometry::polygon_area(&k.shape) - 800.0).abs() < 1e-9);
        let fit = Fit::new((400, 200), fixed(100, 100));
        assert_eq!(
            fit_polygon(&fit, &[0.0, 0.0, 90.0, 0.0, 90.0, 50.0]),
            Err(Drop::CroppedOut)
        );
        let k = fit_polygon(&fit, &[120.0, 20.0, 200.0, 20.0, 200.0, 100.0]).unwrap();
        assert_eq!(k.shape, [10.0, 10.0, 50.0, 10.0, 50.0, 50.0]);
        assert!(!k.cut);
    }

    #[test]
    fn counts_add_up_by_reason() {
        let mut c = DropCounts::default();
        assert!(c.is_empty());
        c.add(Drop::CroppedOut);
        c.add(Drop::CroppedOut);
        c.add(Drop::EmptyBox);
        let mut all = DropCounts::default();
        all.merge(&c);
        all.merge(&c);
        assert_eq!(all.total(), 6);
        assert_eq!(all.line(), "cropped_out 4, empty_box 2");
        assert_eq!(
            serde_json::to_value(&c).unwrap(),
            serde_json::json!({"cropped_out": 2, "empty_box": 1})
        );
        assert_eq!(
            worst(&[Drop::DegeneratePolygon, Drop::OutsideImage]),
            Drop::OutsideImage
        );
    }
}
