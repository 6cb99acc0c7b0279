//! YOLO label files (`labels/NAME.txt` beside `images/NAME.jpg`): one object per line, either a
//! box `class cx cy w h` or a segment `class x1 y1 ... xn yn` (n >= 3), coordinates normalised
//! by the image's width and height. At the image's own size (`--size native`) the file is copied
//! unchanged; a fixed size's crop changes what "normalised" refers to, so boxes and segments are
//! carried through the [`Fit`], clipped, and normalised again by the pair's size (objects the
//! crop removes are dropped).

use std::fmt::Write as _;

use super::geometry::Fit;

/// How far outside `[0, 1]` a normalised coordinate may lie and be clipped rather than refused.
const TOLERANCE: f64 = 1e-3;

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
        let range = -TOLERANCE..=1.0 + TOLERANCE;
        let shape = match values.len() {
            4 => {
                let [cx, cy, w, h] = [values[0], values[1], values[2], values[3]];
                if w < 0.0 || h < 0.0 {
                    return Err(at("the box has a negative size"));
                }
                let corners = [cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0];
                if !corners.iter().all(|c| range.contains(c)) {
                    return Err(at(&format!(
                        "the box {} lies outside the image (coordinates are normalised to 0..1)",
                        tokens[1..].join(" ")
                    )));
                }
                Shape::Box([cx, cy, w, h])
            }
            k if k >= 6 && k % 2 == 0 => {
                if !values.iter().all(|c| range.contains(c)) {
                    return Err(at(
                        "a segment point lies outside the image (coordinates are normalised to 0..1)",
                    ));
                }
                Shape::Segment(values)
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

/// The label file of a pair: the original text at the image's own size, else every object
/// carried through `fit` and written with 6 decimals.
#[must_use]
pub fn fitted(text: &str, objects: &[Object], fit: &Fit) -> String {
    if fit.is_identity() {
        return text.to_string();
    }
    let (sw, sh) = (fit.src_width as f64, fit.src_height as f64);
    let (w, h) = (fit.width as f64, fit.height as f64);
    let mut out = String::new();
    for o in objects {
        match &o.shape {
            Shape::Box([cx, cy, bw, bh]) => {
                let px = [
                    (cx - bw / 2.0) * sw,
                    (cy - bh / 2.0) * sh,
                    (cx + bw / 2.0) * sw,
                    (cy + bh / 2.0) * sh,
                ];
                if let Some((r, _)) = fit.rect(px) {
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
            }
            Shape::Segment(points) => {
                let px: Vec<f64> = points
                    .chunks_exact(2)
                    .flat_map(|p| [p[0] * sw, p[1] * sh])
                    .collect();
                if let Some(c) = fit.polygon(&px) {
                    let _ = write!(out, "{}", o.class);
                    for p in c.chunks_exact(2) {
                        let _ = write!(out, " {:.6} {:.6}", p[0] / w, p[1] / h);
                    }
                    out.push('\n');
                }
            }
        }
    }
    out
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
        let e = parse("0 0.5 0.5 0.2 0.4\n1 0.95 0.5 0.2 0.2\n").unwrap_err();
        assert!(e.starts_with("line 2:") && e.contains("outside"), "{e}");
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
        assert_eq!(fitted(text, &objects, &native), text);
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
            fitted(text, &objects, &fit),
            "0 0.500000 0.500000 0.400000 0.400000\n"
        );
        // A box in the cropped-off strip disappears; one across the edge is clipped.
        let text = "1 0.05 0.5 0.1 0.2\n2 0.25 0.5 0.1 0.2\n";
        let out = fitted(text, &parse(text).unwrap(), &fit);
        assert_eq!(out, "2 0.050000 0.500000 0.100000 0.200000\n");
        // Segments are clipped and renormalised.
        let text = "4 0.5 0.25 0.6 0.75 0.4 0.75\n";
        let out = fitted(text, &parse(text).unwrap(), &fit);
        assert_eq!(
            out,
            "4 0.500000 0.250000 0.700000 0.750000 0.300000 0.750000\n"
        );
    }
}
