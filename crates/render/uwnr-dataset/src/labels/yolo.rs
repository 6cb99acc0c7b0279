//! YOLO label files (`labels/NAME.txt` beside `images/NAME.jpg`): one object per line, either a
//! box `class cx cy w h` or a segment `class x1 y1 ... xn yn` (n >= 3), coordinates normalised
//! by the image's width and height. Objects follow the [`super::rules`]: a line that does not
//! parse (or a negative size) fails the image; geometry past the edge is clipped, and what is
//! left degenerate is dropped and counted. A file whose objects all lie inside the image is
//! copied unchanged at the image's own size (`--size native`); otherwise, and at a fixed size
//! (whose crop changes what "normalised" refers to), every object is carried through the
//! [`Fit`] and normalised again by the pair's size, with 6 decimals.

use std::fmt::Write as _;

use super::geometry::Fit;
use super::rules::{self, DropCounts};

/// One object.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Centre x, centre y, width, height.
    Box([f64; 4]),
    /// `x1, y1, x2, y2, ...`.
    Segment(Vec<f64>),
}

/// One line of a label file.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub class: u32,
    pub shape: Shape,
}

/// Parses and checks a label file's text; errors name the line.
pub fn parse(text: &str) -> Result<Vec<Object>, String> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let at = |what: &str| format!("line {}: {what}", n + 1);
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        let class: u32 = tokens[0].parse().map_err(|_| {
            at(&format!(
                "class {:?} is not a non-negative integer",
                tokens[0]
            ))
        })?;
        let values: Vec<f64> = tokens[1..]
            .iter()
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<_>>()
            .ok_or_else(|| at("a coordinate is not a number"))?;
        let shape = match values.len() {
            4 => {
                let [cx, cy, w, h] = [values[0], values[1], values[2], values[3]];
                if w < 0.0 || h < 0.0 {
                    return Err(at("the box has a negative width or height"));
                }
                Shape::Box([cx, cy, w, h])
            }
            k if k >= 6 && k % 2 == 0 => Shape::Segment(values),
            k if k >= 6 => {
                return Err(at(&format!(
                    "a segment has an odd number of coordinates ({k})"
                )));
            }
            _ => {
                return Err(at(
                    "expected `class cx cy w h` or `class x1 y1 x2 y2 x3 y3 ...` (normalised)",
                ));
            }
        };
        out.push(Object { class, shape });
    }
    Ok(out)
}

/// The label file of a pair and the objects dropped: the original text when nothing needs
/// changing (the image's own size, every object inside it), else every object carried through
/// `fit` under the [`rules`] and written with 6 decimals.
#[must_use]
pub fn fitted(text: &str, objects: &[Object], fit: &Fit) -> (String, DropCounts) {
    let (sw, sh) = (fit.src_width as f64, fit.src_height as f64);
    let (w, h) = (fit.width as f64, fit.height as f64);
    let mut out = String::new();
    let mut dropped = DropCounts::default();
    let mut cut = false;
    for o in objects {
        match &o.shape {
            Shape::Box([cx, cy, bw, bh]) => {
                let px = [
                    (cx - bw / 2.0) * sw,
                    (cy - bh / 2.0) * sh,
                    (cx + bw / 2.0) * sw,
                    (cy + bh / 2.0) * sh,
                ];
                match rules::fit_box(fit, px) {
                    Ok(k) => {
                        cut |= k.cut;
                        let r = k.shape;
                        let _ = writeln!(
                            out,
                            "{} {:.6} {:.6} {:.6} {:.6}",
                            o.class,
                            (r[0] + r[2]) / 2.0 / w,
                            (r[1] + r[3]) / 2.0 / h,
                            (r[2] - r[0]) / w,
                            (r[3] - r[1]) / h
                        );
                    }
                    Err(d) => dropped.add(d),
                }
            }
            Shape::Segment(points) => {
                let px: Vec<f64> = points
                    .chunks_exact(2)
                    .flat_map(|p| [p[0] * sw, p[1] * sh])
                    .collect();
                match rules::fit_polygon(fit, &px) {
                    Ok(k) => {
                        cut |= k.cut;
                        let _ = write!(out, "{}", o.class);
                        for p in k.shape.chunks_exact(2) {
                            let _ = write!(out, " {:.6} {:.6}", p[0] / w, p[1] / h);
                        }
                        out.push('\n');
                    }
                    Err(d) => dropped.add(d),
                }
            }
        }
    }
    if fit.is_identity() && !cut && dropped.is_empty() {
        return (text.to_string(), dropped);
    }
    (out, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Size;

    #[test]
    fn label_files_parse_and_bad_lines_are_named() {
        let o = parse("0 0.5 0.5 0.2 0.4\n\n3 0.1 0.1 0.3 0.1 0.2 0.3\n").unwrap();
        assert_eq!(o.len(), 2);
        assert_eq!(o[0].shape, Shape::Box([0.5, 0.5, 0.2, 0.4]));
        assert_eq!(o[1].class, 3);
        let e = parse("0 0.5 0.5 0.2 0.4\n1 0.5 0.5 -0.2 0.2\n").unwrap_err();
        assert!(e.starts_with("line 2:") && e.contains("negative"), "{e}");
        let e = parse("0 0.1 0.1 0.3 0.1 0.2 0.3 0.4\n").unwrap_err();
        assert!(e.starts_with("line 1:") && e.contains("odd number"), "{e}");
        assert!(parse("x 0.5 0.5 0.1 0.1").unwrap_err().contains("class"));
        assert!(parse("0 0.5 0.5 0.1").unwrap_err().contains("expected"));
        assert!(
            parse("0 0.5 nan 0.1 0.1")
                .unwrap_err()
                .contains("not a number")
        );
    }

    #[test]
    fn native_size_copies_the_file_and_crops_renormalise() {
        let text = "0 0.5 0.5 0.2 0.4\n";
        let objects = parse(text).unwrap();
        let native = Fit::new((400, 200), Size::Native);
        assert_eq!(fitted(text, &objects, &native).0, text);
        // 400x200 to 100x100 keeps the middle 200x200 (scaled by 0.5): a box at the centre,
        // 80x80 px, becomes 40x40 of 100x100.
        let fit = Fit::new(
            (400, 200),
            Size::Fixed {
                width: 100,
                height: 100,
            },
        );
        assert_eq!(
            fitted(text, &objects, &fit).0,
            "0 0.500000 0.500000 0.400000 0.400000\n"
        );
        // A box in the cropped-off strip disappears; one across the edge is clipped.
        let text = "1 0.05 0.5 0.1 0.2\n2 0.25 0.5 0.1 0.2\n";
        let (out, dropped) = fitted(text, &parse(text).unwrap(), &fit);
        assert_eq!(out, "2 0.050000 0.500000 0.100000 0.200000\n");
        assert_eq!(dropped.line(), "cropped_out 1");
        // Segments are clipped and renormalised.
        let text = "4 0.5 0.25 0.6 0.75 0.4 0.75\n";
        let (out, _) = fitted(text, &parse(text).unwrap(), &fit);
        assert_eq!(
            out,
            "4 0.500000 0.250000 0.700000 0.750000 0.300000 0.750000\n"
        );
    }

    #[test]
    fn the_edge_rule_is_the_same_at_native_size() {
        // 100x100 at its own size: a box 0.9 px past the right edge and one 19 px past are
        // clipped alike; a zero-width box, a segment wholly outside and a degenerate segment are
        // dropped and counted; the file is rewritten since it changed.
        let text = "0 0.9545 0.5 0.1 0.2\n1 1.045 0.5 0.28 0.2\n2 0.5 0.5 0 0.2\n\
                    3 1.1 0.1 1.3 0.1 1.2 0.3\n4 0.1 0.1 0.2 0.2 0.3 0.3\n5 0.5 0.5 0.2 0.2\n";
        let native = Fit::new((100, 100), Size::Native);
        let (out, dropped) = fitted(text, &parse(text).unwrap(), &native);
        assert_eq!(
            out,
            "0 0.952250 0.500000 0.095500 0.200000\n1 0.952500 0.500000 0.095000 0.200000\n\
             5 0.500000 0.500000 0.200000 0.200000\n"
        );
        assert_eq!(
            dropped.line(),
            "degenerate_polygon 1, empty_box 1, outside_image 1"
        );
        // The same file at a fixed size drops the same objects for the same reasons.
        let fit = Fit::new(
            (100, 100),
            Size::Fixed {
                width: 50,
                height: 50,
            },
        );
        let (out, again) = fitted(text, &parse(text).unwrap(), &fit);
        assert_eq!(again, dropped);
        assert_eq!(out.lines().count(), 3);
    }
}
