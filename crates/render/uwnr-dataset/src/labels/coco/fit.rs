//! One COCO annotation carried to a pair under the [`rules`]: malformed fields are errors;
//! boxes and polygons are clipped to the image and to the pair; what is left degenerate is
//! dropped with its [`Drop`] reason; areas follow (scaled, or measured again where clipping cut
//! the object). An annotation that needs nothing changed is copied as it is.

use serde_json::{Map, Value, json};

use super::super::geometry::{Fit, polygon_area};
use super::super::rle::{Mask, counts_from_string, counts_to_string};
use super::super::rules::{self, Drop};

/// Rounds a pixel coordinate to 1/1000 pixel, so files stay short and exact to read back.
pub(super) fn r3(v: f64) -> f64 {
    let r = (v * 1000.0).round() / 1000.0;
    if r == 0.0 { 0.0 } else { r }
}

pub(super) fn numbers(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(Value::as_f64).collect()
}

/// The segmentation of an annotation, checked.
enum Segmentation {
    /// None given, or `[]` (a box-only annotation).
    None,
    Polygons(Vec<Vec<f64>>),
    Rle {
        mask: Mask,
        compressed: bool,
    },
}

fn segmentation(a: &Map<String, Value>, (w, h): (usize, usize)) -> Result<Segmentation, String> {
    match a.get("segmentation") {
        None => Ok(Segmentation::None),
        Some(Value::Array(polys)) if polys.is_empty() => Ok(Segmentation::None),
        Some(Value::Array(polys)) => {
            let mut out = Vec::with_capacity(polys.len());
            for (n, p) in polys.iter().enumerate() {
                let pts = numbers(p)
                    .filter(|p| p.iter().all(|x| x.is_finite()))
                    .ok_or_else(|| {
                        format!("segmentation polygon {n} is not a list of finite numbers")
                    })?;
                if pts.len() % 2 != 0 {
                    return Err(format!(
                        "segmentation polygon {n} has an odd number of coordinates ({})",
                        pts.len()
                    ));
                }
                out.push(pts);
            }
            Ok(Segmentation::Polygons(out))
        }
        Some(Value::Object(rle)) => {
            let size = rle
                .get("size")
                .and_then(numbers)
                .filter(|s| s.len() == 2 && s.iter().all(|v| *v >= 0.0 && v.fract() == 0.0))
                .ok_or_else(|| "an RLE segmentation has no [height, width] \"size\"".to_string())?;
            let (rh, rw) = (size[0] as usize, size[1] as usize);
            if (rw, rh) != (w, h) {
                return Err(format!("its RLE mask is {rw}x{rh}, the image is {w}x{h}"));
            }
            let compressed = rle.get("counts").is_some_and(Value::is_string);
            let counts = match rle.get("counts") {
                Some(Value::String(s)) => counts_from_string(s),
                Some(Value::Array(c)) => c.iter().map(Value::as_u64).collect(),
                _ => None,
            }
            .ok_or_else(|| "its RLE \"counts\" do not decode".to_string())?;
            let mask = Mask::from_counts(rh, rw, &counts)
                .ok_or_else(|| format!("its RLE counts do not add up to {rw}x{rh} pixels"))?;
            Ok(Segmentation::Rle { mask, compressed })
        }
        Some(other) => Err(format!("segmentation {other} is neither polygons nor RLE")),
    }
}

/// Grows `b` (`[x0, y0, x1, y1]`) to hold the points of `poly`.
fn extend_box(b: &mut Option<[f64; 4]>, poly: &[f64]) {
    for q in poly.chunks_exact(2) {
        let b = b.get_or_insert([q[0], q[1], q[0], q[1]]);
        *b = [
            b[0].min(q[0]),
            b[1].min(q[1]),
            b[2].max(q[0]),
            b[3].max(q[1]),
        ];
    }
}

/// One annotation of an image of size `(w, h)` through `fit`: `Err` when it is malformed (the
/// reason), `Ok(Err(drop))` when nothing readable is left of it in the pair.
pub(super) fn fit_annotation(
    a: &Map<String, Value>,
    (w, h): (usize, usize),
    fit: &Fit,
) -> Result<Result<Map<String, Value>, Drop>, String> {
    let bbox = match a.get("bbox") {
        Some(v) => {
            let b = numbers(v).filter(|b| b.len() == 4 && b.iter().all(|x| x.is_finite()));
            let Some(b) = b else {
                return Err(format!("bbox {v} is not [x, y, width, height]"));
            };
            if b[2] < 0.0 || b[3] < 0.0 {
                return Err(format!("bbox {v} has a negative width or height"));
            }
            Some(b)
        }
        None => None,
    };
    let seg = segmentation(a, (w, h))?;
    let keypoints = match a.get("keypoints") {
        Some(kp) => Some(
            numbers(kp)
                .filter(|k| k.len() % 3 == 0 && k.iter().all(|x| x.is_finite()))
                .ok_or_else(|| "keypoints are not x, y, v triplets".to_string())?,
        ),
        None => None,
    };

    let mut changed = !fit.is_identity();
    let mut cut = false;
    let mut fitted_box = None;
    if let Some(b) = &bbox {
        match rules::fit_box(fit, [b[0], b[1], b[0] + b[2], b[1] + b[3]]) {
            Ok(k) => {
                cut |= k.cut;
                fitted_box = Some(k.shape);
            }
            Err(d) => return Ok(Err(d)),
        }
    }
    let mut seg_box: Option<[f64; 4]> = None;
    let mut seg_area: Option<f64> = None;
    let mut new_seg: Option<Value> = None;
    let mut remeasure = false;
    match seg {
        Segmentation::None => {}
        Segmentation::Polygons(polys) => {
            let mut kept = Vec::with_capacity(polys.len());
            let mut reasons = Vec::new();
            let mut area = 0.0;
            for p in &polys {
                match rules::fit_polygon(fit, p) {
                    Ok(k) => {
                        cut |= k.cut;
                        area += polygon_area(&k.shape);
                        extend_box(&mut seg_box, &k.shape);
                        kept.push(Value::from(k.shape.into_iter().map(r3).collect::<Vec<_>>()));
                    }
                    Err(d) => reasons.push(d),
                }
            }
            if kept.is_empty() {
                return Ok(Err(rules::worst(&reasons)));
            }
            // A part dropped: the rest is rewritten, and its area measured again.
            if !reasons.is_empty() {
                changed = true;
                remeasure = true;
            }
            seg_area = Some(area);
            new_seg = Some(Value::Array(kept));
        }
        Segmentation::Rle { mask, compressed } => {
            if mask.area() == 0 {
                return Ok(Err(Drop::EmptyMask));
            }
            if !fit.is_identity() {
                let fitted = mask.fitted(fit);
                let area = fitted.area();
                if area == 0 {
                    return Ok(Err(Drop::CroppedOut));
                }
                cut |= (area as f64) + 0.5 < mask.area() as f64 * fit.sx() * fit.sy() * 0.999;
                let c = fitted.counts();
                let counts = if compressed {
                    Value::from(counts_to_string(&c))
                } else {
                    Value::from(c)
                };
                let b = fitted.bbox();
                seg_box = Some([b[0], b[1], b[0] + b[2], b[1] + b[3]]);
                seg_area = Some(area as f64);
                remeasure = true;
                new_seg = Some(json!({ "size": [fit.height, fit.width], "counts": counts }));
            }
        }
    }
    changed |= cut;
    if !changed {
        return Ok(Ok(a.clone()));
    }

    let mut out = a.clone();
    if let Some(s) = new_seg {
        out.insert("segmentation".into(), s);
    }
    if let Some(mut r) = fitted_box {
        // A box cut by the clipping is tightened to what is left of the object's outline.
        if let (true, Some(s)) = (cut, seg_box) {
            r = [
                r[0].max(s[0]),
                r[1].max(s[1]),
                r[2].min(s[2]),
                r[3].min(s[3]),
            ];
            if r[2] <= r[0] || r[3] <= r[1] {
                return Ok(Err(if fit.is_identity() {
                    Drop::OutsideImage
                } else {
                    Drop::CroppedOut
                }));
            }
        }
        out.insert(
            "bbox".into(),
            Value::from(vec![r3(r[0]), r3(r[1]), r3(r[2] - r[0]), r3(r[3] - r[1])]),
        );
        fitted_box = Some(r);
    }
    if let Some(area) = a.get("area").and_then(Value::as_f64) {
        let new = match (seg_area, fitted_box) {
            (Some(s), _) if cut || remeasure => s,
            // Box-only: what is left of the box.
            (None, Some(r)) if cut => (r[2] - r[0]) * (r[3] - r[1]),
            _ => area * fit.sx() * fit.sy(),
        };
        out.insert("area".into(), Value::from(r3(new)));
    }
    if let Some(k) = keypoints {
        let mut moved = Vec::with_capacity(k.len());
        let mut visible = 0u64;
        for t in k.chunks_exact(3) {
            let p = fit.point(t[0], t[1]);
            let in_image = (0.0..=w as f64).contains(&t[0]) && (0.0..=h as f64).contains(&t[1]);
            if t[2] > 0.0 && in_image && fit.inside(p) {
                moved.extend([r3(p.0), r3(p.1), t[2]]);
                visible += 1;
            } else {
                moved.extend([0.0, 0.0, 0.0]);
            }
        }
        out.insert("keypoints".into(), Value::from(moved));
        if out.contains_key("num_keypoints") {
            out.insert("num_keypoints".into(), json!(visible));
        }
    }
    Ok(Ok(out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Size;

    fn ann(v: Value) -> Map<String, Value> {
        v.as_object().unwrap().clone()
    }

    fn fixed(width: usize, height: usize) -> Fit {
        Fit::new((400, 200), Size::Fixed { width, height })
    }

    #[test]
    fn a_cut_box_only_annotation_gets_the_clipped_box_area() {
        // 400x200 to 100x100: scale 0.5, 50 px cropped each side. [60, 0, 80, 40] keeps source
        // columns 100..140, i.e. [0, 0, 20, 20] of the pair: 400 px^2, not 0.
        let a = ann(json!({"id": 1, "bbox": [60, 0, 80, 40], "area": 3200, "segmentation": []}));
        let out = fit_annotation(&a, (400, 200), &fixed(100, 100))
            .unwrap()
            .unwrap();
        assert_eq!(out["bbox"], json!([0.0, 0.0, 20.0, 20.0]));
        assert_eq!(out["area"], json!(400.0));
        assert_eq!(out["segmentation"], json!([]));
    }

    #[test]
    fn degenerate_and_outside_annotations_are_dropped_at_every_size() {
        let native = Fit::new((400, 200), Size::Native);
        let cases = [
            (
                json!({"segmentation": [[1, 1, 5, 5]]}),
                Drop::DegeneratePolygon,
            ),
            (
                json!({"segmentation": [[410, 0, 430, 0, 420, 20]]}),
                Drop::OutsideImage,
            ),
            (json!({"bbox": [10, 10, 0, 5]}), Drop::EmptyBox),
            (json!({"bbox": [500, 10, 10, 5]}), Drop::OutsideImage),
            (
                json!({"segmentation": {"size": [200, 400], "counts": [80000]}}),
                Drop::EmptyMask,
            ),
        ];
        for (a, reason) in cases {
            for fit in [native, fixed(100, 100)] {
                let got = fit_annotation(&ann(a.clone()), (400, 200), &fit).unwrap();
                assert_eq!(got.err(), Some(reason), "{a}");
            }
        }
        // Past the edge at the native size: clipped, area measured again.
        let a = ann(json!({"bbox": [390, 190, 30, 30], "area": 900}));
        let out = fit_annotation(&a, (400, 200), &native).unwrap().unwrap();
        assert_eq!(out["bbox"], json!([390.0, 190.0, 10.0, 10.0]));
        assert_eq!(out["area"], json!(100.0));
        // Inside at the native size: copied unchanged.
        let a = ann(json!({"bbox": [1, 2, 3, 4], "area": 12}));
        assert_eq!(fit_annotation(&a, (400, 200), &native).unwrap().unwrap(), a);
    }

    #[test]
    fn malformed_annotations_fail_with_what_is_wrong() {
        let fit = Fit::new((400, 200), Size::Native);
        let e = fit_annotation(&ann(json!({"segmentation": [[1, 2, 3]]})), (400, 200), &fit);
        assert!(e.unwrap_err().contains("odd number of coordinates (3)"));
        let e = fit_annotation(&ann(json!({"bbox": [1, 2, -3, 4]})), (400, 200), &fit);
        assert!(e.unwrap_err().contains("negative width or height"));
        let e = fit_annotation(&ann(json!({"bbox": [1, 2, "3", 4]})), (400, 200), &fit);
        assert!(e.unwrap_err().contains("is not [x, y, width, height]"));
    }
}
