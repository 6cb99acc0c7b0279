//! Pictures of a run, drawn with the `image` crate alone: the loss and validation curves
//! (`curves.png`) and the validation contact sheets (clean | render | real underwater, one
//! row per pair).
//!
//! Text uses a built-in 3x5 pixel font (digits, capitals A-Z and `. , - + / ( ) : _ %`; lower
//! case is drawn as capitals), scaled up.

use std::path::Path;

use image::{Rgb, RgbImage};
use uwnr_core::Image;
use uwnr_core::io::save_rgb;

use crate::error::{Result, TrainError};

/// Size of the curve picture.
const PLOT_W: u32 = 960;
/// Height of each of the two panels.
const PANEL_H: u32 = 300;
/// Margins around a panel's axes box: left, right, top, bottom.
const MARGIN: (u32, u32, u32, u32) = (80, 20, 30, 30);
/// Pixel size of one font dot.
const FONT_SCALE: u32 = 2;
/// Colours.
const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const BLACK: Rgb<u8> = Rgb([0, 0, 0]);
const GRID: Rgb<u8> = Rgb([225, 225, 225]);
/// Colours given to loss series in order ([`series_colour`]): the Okabe-Ito palette, which
/// stays distinguishable for colour-blind readers.
pub const SERIES_COLOURS: [[u8; 3]; 6] = [
    [230, 159, 0],
    [86, 180, 233],
    [0, 158, 115],
    [204, 121, 167],
    [0, 114, 178],
    [240, 228, 66],
];
/// Colour of a run's total loss.
pub const TOTAL_COLOUR: [u8; 3] = [0, 0, 0];
/// Legend names of UWNR's loss terms (as in `metrics.csv`).
const TERM_NAMES: [&str; 5] = ["L1", "PERCEPTUAL", "DARK CHANNEL", "LIGHT FIELD", "TOTAL"];
/// Colour of the validation PSNR curve.
const VAL_COLOUR: Rgb<u8> = Rgb([213, 94, 0]);
/// Colour of the reference lines on the validation panel.
const REF_COLOUR: Rgb<u8> = Rgb([150, 150, 150]);

/// One logged row of UWNR's training losses: step and the five values.
pub type LossPoint = (usize, [f64; 5]);
/// One validation: step, PSNR.
pub type ValPoint = (usize, f64);

/// A named curve of the loss panel.
#[derive(Clone, Debug, PartialEq)]
pub struct LossSeries {
    /// Legend text (drawn in capitals; letters, digits, space and `. - + / ( ) : _ %`).
    pub name: String,
    /// Line colour, RGB.
    pub colour: [u8; 3],
    /// `(step, value)`; values that are not positive leave a gap on the log axis.
    pub points: Vec<(usize, f64)>,
}

/// The colour of the `index`-th series: [`SERIES_COLOURS`] in turn.
#[must_use]
pub fn series_colour(index: usize) -> [u8; 3] {
    SERIES_COLOURS[index % SERIES_COLOURS.len()]
}

/// Draws UWNR's `curves.png` ([`draw_loss_curves`] with its five loss terms: reconstruction,
/// perceptual, dark channel, light field, total).
pub fn draw_curves(
    path: &Path,
    losses: &[LossPoint],
    val: &[ValPoint],
    refs: &[f64],
) -> Result<()> {
    let series: Vec<LossSeries> = TERM_NAMES
        .iter()
        .enumerate()
        .map(|(term, name)| LossSeries {
            name: (*name).to_string(),
            colour: if term + 1 == TERM_NAMES.len() {
                TOTAL_COLOUR
            } else {
                series_colour(term)
            },
            points: losses.iter().map(|(s, v)| (*s, v[term])).collect(),
        })
        .collect();
    draw_loss_curves(path, &series, val, refs)
}

/// Draws a run's curve picture: the top panel shows the loss `series` (log scale) against the
/// step, with a legend, the bottom panel the validation PSNR with horizontal reference lines
/// (e.g. baselines) at `refs`. Series are drawn last to first, so the first lies on top.
pub fn draw_loss_curves(
    path: &Path,
    series: &[LossSeries],
    val: &[ValPoint],
    refs: &[f64],
) -> Result<()> {
    let mut img = RgbImage::from_pixel(PLOT_W, 2 * PANEL_H, WHITE);
    let max_step = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .chain(val.iter().map(|p| p.0))
        .max()
        .unwrap_or(1)
        .max(1) as f64;
    // Loss panel (log10 of positive values).
    let logs: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .map(|&(step, v)| (step as f64, if v > 0.0 { v.log10() } else { f64::NAN }))
                .collect()
        })
        .collect();
    let finite = logs
        .iter()
        .flat_map(|pts| pts.iter().map(|p| p.1))
        .filter(|v| v.is_finite());
    let (lo, hi) = bounds(finite);
    let panel = Panel::new(0, (0.0, max_step), (lo, hi));
    panel.frame(&mut img, "LOSS LOG10", |v| format!("{:.2}", 10f64.powf(v)));
    let mut legend_x = panel.x0 + panel.w;
    for (s, pts) in series.iter().zip(&logs).rev() {
        let colour = Rgb(s.colour);
        panel.polyline(&mut img, pts, colour);
        legend_x -= text_width(&s.name) + 12;
        draw_text(&mut img, legend_x, panel.y0 - 16, &s.name, colour);
    }
    // Validation panel.
    let (lo, hi) = bounds(val.iter().map(|p| p.1).chain(refs.iter().copied()));
    let panel = Panel::new(PANEL_H, (0.0, max_step), (lo, hi));
    panel.frame(&mut img, "VAL PSNR DB", |v| format!("{v:.1}"));
    for &r in refs {
        panel.polyline(&mut img, &[(0.0, r), (max_step, r)], REF_COLOUR);
    }
    let pts: Vec<(f64, f64)> = val.iter().map(|&(s, p)| (s as f64, p)).collect();
    panel.polyline(&mut img, &pts, VAL_COLOUR);
    for &(x, y) in &pts {
        let (px, py) = panel.to_px(x, y);
        fill_rect(&mut img, px - 2, py - 2, 5, 5, VAL_COLOUR);
    }
    save_png(path, &img)
}

fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// An axes box mapping data coordinates to pixels.
struct Panel {
    x0: i64,
    y0: i64,
    w: i64,
    h: i64,
    xr: (f64, f64),
    yr: (f64, f64),
}

impl Panel {
    fn new(top: u32, xr: (f64, f64), yr: (f64, f64)) -> Self {
        let (l, r, t, b) = MARGIN;
        Self {
            x0: i64::from(l),
            y0: i64::from(top + t),
            w: i64::from(PLOT_W - l - r),
            h: i64::from(PANEL_H - t - b),
            xr,
            yr,
        }
    }

    fn to_px(&self, x: f64, y: f64) -> (i64, i64) {
        let fx = (x - self.xr.0) / (self.xr.1 - self.xr.0);
        let fy = (y - self.yr.0) / (self.yr.1 - self.yr.0);
        (
            self.x0 + (fx * self.w as f64).round() as i64,
            self.y0 + self.h - (fy * self.h as f64).round() as i64,
        )
    }

    /// Box, grid, tick labels (4 on y, 3 on x) and the title.
    fn frame(&self, img: &mut RgbImage, title: &str, ylabel: impl Fn(f64) -> String) {
        const Y_TICKS: i64 = 4;
        for i in 0..=Y_TICKS {
            let y = self.y0 + self.h * i / Y_TICKS;
            line(img, (self.x0, y), (self.x0 + self.w, y), GRID);
            let v = self.yr.1 - (self.yr.1 - self.yr.0) * i as f64 / Y_TICKS as f64;
            let label = ylabel(v);
            let tw = text_width(&label);
            draw_text(img, self.x0 - tw - 6, y - 5, &label, BLACK);
        }
        for i in 0..=2 {
            let x = self.x0 + self.w * i / 2;
            line(img, (x, self.y0), (x, self.y0 + self.h), GRID);
            let step = self.xr.0 + (self.xr.1 - self.xr.0) * f64::from(i as u8) / 2.0;
            let label = format!("{}", step.round() as u64);
            let tw = text_width(&label);
            draw_text(
                img,
                (x - tw / 2).max(0),
                self.y0 + self.h + 6,
                &label,
                BLACK,
            );
        }
        let (l, r, t, b) = (self.x0, self.x0 + self.w, self.y0, self.y0 + self.h);
        line(img, (l, t), (r, t), BLACK);
        line(img, (l, b), (r, b), BLACK);
        line(img, (l, t), (l, b), BLACK);
        line(img, (r, t), (r, b), BLACK);
        draw_text(img, l, t - 16, title, BLACK);
        draw_text(img, self.x0 + self.w * 3 / 4, b + 6, "STEP", BLACK);
    }

    fn polyline(&self, img: &mut RgbImage, pts: &[(f64, f64)], colour: Rgb<u8>) {
        let mut prev: Option<(i64, i64)> = None;
        for &(x, y) in pts {
            if !y.is_finite() {
                prev = None;
                continue;
            }
            let p = self.to_px(x, y);
            if let Some(q) = prev {
                line(img, q, p, colour);
            }
            prev = Some(p);
        }
    }
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && x < i64::from(img.width()) && y < i64::from(img.height()) {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn fill_rect(img: &mut RgbImage, x: i64, y: i64, w: i64, h: i64, c: Rgb<u8>) {
    for yy in y..y + h {
        for xx in x..x + w {
            put(img, xx, yy, c);
        }
    }
}

/// Bresenham's line.
fn line(img: &mut RgbImage, a: (i64, i64), b: (i64, i64), c: Rgb<u8>) {
    let (mut x, mut y) = a;
    let (dx, dy) = ((b.0 - x).abs(), -(b.1 - y).abs());
    let (sx, sy) = (if x < b.0 { 1 } else { -1 }, if y < b.1 { 1 } else { -1 });
    let mut err = dx + dy;
    loop {
        put(img, x, y, c);
        if (x, y) == b {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

/// 3x5 glyphs, one row per entry, bit 2 = left column.
fn glyph(ch: char) -> [u8; 5] {
    match ch.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        '+' => [0, 2, 7, 2, 0],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [7, 4, 4, 4, 7],
        'D' => [6, 5, 5, 5, 6],
        'F' => [7, 4, 6, 4, 4],
        'H' => [5, 5, 7, 5, 5],
        'U' => [5, 5, 5, 5, 7],
        'K' => [5, 5, 6, 5, 5],
        'E' => [7, 4, 6, 4, 7],
        'G' => [7, 4, 5, 5, 7],
        'I' => [7, 2, 2, 2, 7],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [7, 5, 5, 5, 7],
        'P' => [7, 5, 7, 4, 4],
        'R' => [6, 5, 6, 5, 5],
        'S' => [7, 4, 7, 1, 7],
        'T' => [7, 2, 2, 2, 2],
        'V' => [5, 5, 5, 5, 2],
        'J' => [1, 1, 1, 5, 7],
        'Q' => [2, 5, 5, 6, 3],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        ',' => [0, 0, 0, 2, 4],
        '/' => [1, 1, 2, 4, 4],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        ':' => [0, 2, 0, 2, 0],
        '_' => [0, 0, 0, 0, 7],
        '%' => [5, 1, 2, 4, 5],
        _ => [0; 5],
    }
}

fn text_width(s: &str) -> i64 {
    (s.chars().count() as i64) * 4 * i64::from(FONT_SCALE)
}

fn draw_text(img: &mut RgbImage, x: i64, y: i64, s: &str, c: Rgb<u8>) {
    let k = i64::from(FONT_SCALE);
    for (i, ch) in s.chars().enumerate() {
        let g = glyph(ch);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    fill_rect(
                        img,
                        x + (i as i64 * 4 + col) * k,
                        y + row as i64 * k,
                        k,
                        k,
                        c,
                    );
                }
            }
        }
    }
}

fn save_png(path: &Path, img: &RgbImage) -> Result<()> {
    let (w, h) = img.dimensions();
    let data: Vec<f32> = img.as_raw().iter().map(|&v| f32::from(v) / 255.0).collect();
    let im = Image::from_interleaved(w as usize, h as usize, 3, &data)?;
    save_rgb(path, &im)?;
    Ok(())
}

/// A contact sheet: one row per `(clean, render, underwater)` triple, each image scaled to
/// `thumb` pixels high (aspect kept), separated by a white gap ([`uwnr_core::sheet`]).
pub fn contact_sheet(path: &Path, rows: &[(Image, Image, Image)], thumb: usize) -> Result<()> {
    if rows.is_empty() {
        return Err(TrainError::InvalidConfig {
            field: "val_sheet_pairs",
            reason: "a contact sheet needs at least one pair".into(),
        });
    }
    let rows: Vec<Vec<&Image>> = rows.iter().map(|(a, b, c)| vec![a, b, c]).collect();
    let sheet = uwnr_core::sheet::contact_sheet(&rows, thumb)?;
    save_rgb(path, &sheet)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_capital_and_digit_has_a_glyph() {
        for ch in ('A'..='Z').chain('0'..='9').chain(".,-+/():_%".chars()) {
            assert_ne!(glyph(ch), [0; 5], "{ch:?} has no glyph");
        }
        assert_eq!(glyph('m'), glyph('M'));
    }

    #[test]
    fn named_series_are_drawn_in_their_colours() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("curves.png");
        let series = vec![
            LossSeries {
                name: "MSE".into(),
                colour: series_colour(0),
                points: (1..=20).map(|s| (s, 1.0 / s as f64)).collect(),
            },
            LossSeries {
                name: "TOTAL".into(),
                colour: TOTAL_COLOUR,
                points: (1..=20).map(|s| (s, 2.0 / s as f64)).collect(),
            },
        ];
        draw_loss_curves(&path, &series, &[(10, 20.0), (20, 22.0)], &[21.0]).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (PLOT_W, 2 * PANEL_H));
        let has = |c: [u8; 3]| img.pixels().any(|p| p.0 == c);
        assert!(has(series_colour(0)) && has(VAL_COLOUR.0) && has(REF_COLOUR.0));
    }
}
