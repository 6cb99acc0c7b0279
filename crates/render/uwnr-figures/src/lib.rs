//! Figures of uwnr, drawn with [`plotters`] (bitmap backend) and an embedded open font, DejaVu
//! Sans (`assets/DejaVuSans.ttf`, from Debian's `fonts-dejavu-core`; Bitstream Vera licence with
//! the DejaVu changes in the public domain, see `assets/DejaVuSans-LICENSE.txt`), so text looks
//! the same on every machine and nothing is read from the system's fonts.
//!
//! - [`draw_panels`]: stacked line charts with a title, axis labels, a legend per panel, an
//!   optional log scale and horizontal reference lines (training curves);
//! - [`draw_sheet`]: contact sheets whose columns carry headers and whose rows may carry labels
//!   (validation sheets, the experiment's examples, a dataset's preview).
//!
//! Both return a [`uwnr_core::Image`]; callers encode it once on the way out.

use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;
use plotters::style::FontStyle;
use uwnr_core::Image;
use uwnr_core::io::to_rgb8;
use uwnr_core::resize::resize_bilinear;

/// The embedded font (DejaVu Sans, see the module docs).
const FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The family name the font is registered under.
const FONT: &str = "sans-serif";
/// Text sizes in pixels.
const TITLE_PX: f64 = 20.0;
const LABEL_PX: f64 = 15.0;
const TICK_PX: f64 = 13.0;
/// Space around and between sheet cells, in pixels.
pub const SHEET_GAP: usize = 4;
/// Padding around a sheet's header and label text, in pixels.
const TEXT_PAD: usize = 4;

/// What can go wrong drawing a figure.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// The embedded font could not be read.
    #[error("the embedded font could not be loaded")]
    Font,
    /// Nothing to draw, or a size of zero.
    #[error("{0}")]
    Invalid(String),
    /// plotters failed.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// Image handling in uwnr-core failed.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, FigureError>;

fn draw_err<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> FigureError {
    FigureError::Draw(e.to_string())
}

/// Registers the embedded font once per process.
fn font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    if ok { Ok(()) } else { Err(FigureError::Font) }
}

/// One line of a chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Line colour, RGB.
    pub colour: [u8; 3],
    /// `(x, y)` in drawing order; non-finite values (and, on a log axis, values that are not
    /// positive) leave a gap.
    pub points: Vec<(f64, f64)>,
    /// Mark every point with a dot (sparse series such as validation scores).
    pub markers: bool,
}

/// A horizontal reference line (e.g. a baseline's score), drawn dashed in grey with its name in
/// the legend.
#[derive(Clone, Debug, PartialEq)]
pub struct Reference {
    /// Legend text.
    pub name: String,
    /// Its y value.
    pub value: f64,
}

/// One chart of a figure.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The lines, drawn last to first so the first lies on top.
    pub series: Vec<Series>,
    /// Horizontal reference lines.
    pub references: Vec<Reference>,
}

/// Colour of reference lines.
const REFERENCE_COLOUR: RGBColor = RGBColor(120, 120, 120);

/// Draws `panels` stacked top to bottom, each `width` x `panel_height` pixels. All panels share
/// one x axis, from 0 (or the smallest x, if negative) to the largest x of any series.
pub fn draw_panels(panels: &[Panel], width: u32, panel_height: u32) -> Result<Image> {
    if panels.is_empty() || width == 0 || panel_height == 0 {
        return Err(FigureError::Invalid(
            "a figure needs at least one panel and a size".into(),
        ));
    }
    font()?;
    let height = panel_height * panels.len() as u32;
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let xs = panels
            .iter()
            .flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)));
        let (lo, hi) = padded_range(xs, false);
        let x_range = (lo.min(0.0), hi);
        let areas = root.split_evenly((panels.len(), 1));
        for (area, panel) in areas.iter().zip(panels) {
            draw_panel(area, panel, x_range)?;
        }
        root.present().map_err(draw_err)?;
    }
    rgb8_image(width as usize, height as usize, &buf)
}

fn rgb8_image(width: usize, height: usize, buf: &[u8]) -> Result<Image> {
    let data: Vec<f32> = buf.iter().map(|&v| f32::from(v) / 255.0).collect();
    Ok(Image::from_interleaved(width, height, 3, &data)?)
}

/// The finite range of `values`, padded by 5% (a flat range is widened to be visible).
fn padded_range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && (!log || *v > 0.0)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return if log { (0.1, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        return (lo / 1.1, hi * 1.1);
    }
    if hi - lo < 1e-9 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

fn draw_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    p: &Panel,
    (x0, x1): (f64, f64),
) -> Result<()> {
    let ys = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|q| q.1))
        .chain(p.references.iter().map(|r| r.value));
    let (y0, y1) = padded_range(ys, p.log_y);
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, (FONT, TITLE_PX))
        .margin(8)
        .x_label_area_size(38)
        .y_label_area_size(64);
    if p.log_y {
        let chart = builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(draw_err)?;
        fill_chart(chart, p, |v| *v > 0.0, |v| format!("{v:.3}"))
    } else {
        let chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(draw_err)?;
        fill_chart(chart, p, |_| true, |v| format!("{v:.2}"))
    }
}

fn fill_chart<'a, Y>(
    mut chart: ChartContext<
        'a,
        BitMapBackend<'a>,
        Cartesian2d<plotters::coord::types::RangedCoordf64, Y>,
    >,
    p: &Panel,
    valid: impl Fn(&f64) -> bool,
    y_format: impl Fn(&f64) -> String,
) -> Result<()>
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    std::ops::Range<f64>: AsRangedCoord,
{
    let x_format = |v: &f64| format!("{}", v.round() as i64);
    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&x_format)
        .y_label_formatter(&y_format)
        .label_style((FONT, TICK_PX))
        .axis_desc_style((FONT, LABEL_PX))
        .light_line_style(RGBColor(236, 236, 236))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()
        .map_err(draw_err)?;
    let (xr0, xr1) = {
        let r = chart.x_range();
        (r.start, r.end)
    };
    for r in &p.references {
        if !valid(&r.value) {
            continue;
        }
        let style = ShapeStyle::from(&REFERENCE_COLOUR).stroke_width(1);
        chart
            .draw_series(DashedLineSeries::new(
                [(xr0, r.value), (xr1, r.value)],
                6,
                4,
                style,
            ))
            .map_err(draw_err)?
            .label(r.name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
    }
    for s in p.series.iter().rev() {
        let colour = RGBColor(s.colour[0], s.colour[1], s.colour[2]);
        let style = ShapeStyle::from(&colour).stroke_width(2);
        // Split at gaps (non-finite or invalid values).
        let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for &(x, y) in &s.points {
            if x.is_finite() && y.is_finite() && valid(&y) {
                if let Some(run) = runs.last_mut() {
                    run.push((x, y));
                }
            } else if runs.last().is_some_and(|r| !r.is_empty()) {
                runs.push(Vec::new());
            }
        }
        let mut labelled = false;
        for run in runs.iter().filter(|r| !r.is_empty()) {
            let drawn = chart
                .draw_series(LineSeries::new(run.iter().copied(), style))
                .map_err(draw_err)?;
            if !labelled {
                drawn
                    .label(s.name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
                labelled = true;
            }
            if s.markers {
                chart
                    .draw_series(run.iter().map(|&q| Circle::new(q, 3, colour.filled())))
                    .map_err(draw_err)?;
            }
        }
    }
    if !p.series.is_empty() || !p.references.is_empty() {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, TICK_PX))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(190, 190, 190))
            .draw()
            .map_err(draw_err)?;
    }
    Ok(())
}

/// One row of a contact sheet.
#[derive(Clone, Debug)]
pub struct SheetRow<'a> {
    /// Text left of the row (e.g. the image's name); `None` for none.
    pub label: Option<String>,
    /// The images, left to right under the column headers.
    pub images: Vec<&'a Image>,
}

/// A contact sheet: a title, column headers, and rows of images scaled to one height.
#[derive(Clone, Debug, Default)]
pub struct Sheet<'a> {
    /// Text above everything; `None` for none.
    pub title: Option<String>,
    /// One header per column (a row may hold fewer images than there are headers).
    pub columns: Vec<String>,
    /// The rows, top to bottom.
    pub rows: Vec<SheetRow<'a>>,
    /// Height of every thumbnail in pixels (aspect kept).
    pub thumb: usize,
}

/// Lays out and draws `sheet`: each column as wide as its widest thumbnail, headers centred over
/// their columns, row labels in a column of their own, [`SHEET_GAP`] pixels between cells.
pub fn draw_sheet(sheet: &Sheet<'_>) -> Result<Image> {
    if sheet.rows.iter().all(|r| r.images.is_empty()) {
        return Err(FigureError::Invalid(
            "a contact sheet needs at least one image".into(),
        ));
    }
    if sheet.thumb == 0 {
        return Err(FigureError::Invalid(
            "contact-sheet thumbnails need a height of at least 1 pixel".into(),
        ));
    }
    font()?;
    let mut thumbs: Vec<Vec<Image>> = Vec::with_capacity(sheet.rows.len());
    let columns = sheet
        .rows
        .iter()
        .map(|r| r.images.len())
        .max()
        .unwrap_or(0)
        .max(sheet.columns.len());
    let mut col_w = vec![0usize; columns];
    for row in &sheet.rows {
        let mut out = Vec::with_capacity(row.images.len());
        for (c, im) in row.images.iter().enumerate() {
            if im.channels() != 3 {
                return Err(FigureError::Invalid(format!(
                    "contact sheets take RGB images, got {} channels",
                    im.channels()
                )));
            }
            let w = ((im.width() * sheet.thumb) as f64 / im.height().max(1) as f64)
                .round()
                .max(1.0) as usize;
            let t = resize_bilinear(im, w, sheet.thumb)?;
            col_w[c] = col_w[c].max(t.width());
            out.push(t);
        }
        thumbs.push(out);
    }
    // Text sizes, measured with the font.
    let label_font = (FONT, LABEL_PX).into_font();
    let title_font = (FONT, TITLE_PX).into_font();
    let measure = |text: &str, f: &FontDesc<'_>| -> Result<(usize, usize)> {
        let (w, h) = f
            .box_size(text)
            .map_err(|e| FigureError::Draw(format!("{e:?}")))?;
        Ok((w as usize, h as usize))
    };
    for (c, name) in sheet.columns.iter().enumerate() {
        col_w[c] = col_w[c].max(measure(name, &label_font)?.0 + 2 * TEXT_PAD);
    }
    let line_h = measure("Hg", &label_font)?.1 + 2 * TEXT_PAD;
    let title_h = match &sheet.title {
        Some(t) => measure(t, &title_font)?.1 + 2 * TEXT_PAD,
        None => 0,
    };
    let header_h = if sheet.columns.is_empty() { 0 } else { line_h };
    let mut label_w = 0;
    for r in &sheet.rows {
        if let Some(l) = &r.label {
            label_w = label_w.max(measure(l, &label_font)?.0 + 2 * TEXT_PAD);
        }
    }
    let left = SHEET_GAP + label_w;
    let width = left + col_w.iter().map(|w| w + SHEET_GAP).sum::<usize>();
    let top = title_h + header_h + SHEET_GAP;
    let height = top + sheet.rows.len() * (sheet.thumb + SHEET_GAP);
    let mut buf = vec![255u8; width * height * 3];
    let col_x: Vec<usize> = col_w
        .iter()
        .scan(left, |x, w| {
            let at = *x;
            *x += w + SHEET_GAP;
            Some(at)
        })
        .collect();
    for (r, row) in thumbs.iter().enumerate() {
        let y0 = top + r * (sheet.thumb + SHEET_GAP);
        for (c, t) in row.iter().enumerate() {
            // Centred in its column.
            let x0 = col_x[c] + (col_w[c] - t.width()) / 2;
            let px = to_rgb8(t);
            for y in 0..t.height() {
                let src = &px[y * t.width() * 3..(y + 1) * t.width() * 3];
                let d = ((y0 + y) * width + x0) * 3;
                buf[d..d + src.len()].copy_from_slice(src);
            }
        }
    }
    {
        let root =
            BitMapBackend::with_buffer(&mut buf, (width as u32, height as u32)).into_drawing_area();
        let text = |s: &str, f: &FontDesc<'_>, x: usize, y: usize| {
            root.draw(&Text::new(
                s.to_string(),
                (x as i32, y as i32),
                f.color(&BLACK),
            ))
            .map_err(draw_err)
        };
        if let Some(t) = &sheet.title {
            let w = measure(t, &title_font)?.0;
            text(t, &title_font, width.saturating_sub(w) / 2, TEXT_PAD)?;
        }
        for (c, name) in sheet.columns.iter().enumerate() {
            let w = measure(name, &label_font)?.0;
            let x = col_x[c] + col_w[c].saturating_sub(w) / 2;
            text(name, &label_font, x, title_h + TEXT_PAD)?;
        }
        for (r, row) in sheet.rows.iter().enumerate() {
            if let Some(l) = &row.label {
                let y = top + r * (sheet.thumb + SHEET_GAP) + sheet.thumb / 2;
                let y = y.saturating_sub(line_h / 2) + TEXT_PAD;
                text(l, &label_font, SHEET_GAP + TEXT_PAD, y)?;
            }
        }
        root.present().map_err(draw_err)?;
    }
    rgb8_image(width, height, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dark_pixels(img: &Image, x0: usize, x1: usize, y0: usize, y1: usize) -> usize {
        let mut n = 0;
        for y in y0..y1 {
            for x in x0..x1 {
                if (0..3).all(|c| img.get(c, y, x) < 0.3) {
                    n += 1;
                }
            }
        }
        n
    }

    #[test]
    fn panels_have_their_size_and_colours() {
        let panel = Panel {
            title: "Training loss".into(),
            x_label: "step".into(),
            y_label: "loss".into(),
            log_y: true,
            series: vec![Series {
                name: "L1".into(),
                colour: [230, 159, 0],
                points: (1..=20).map(|s| (s as f64, 1.0 / s as f64)).collect(),
                markers: false,
            }],
            references: vec![],
        };
        let val = Panel {
            title: "Validation".into(),
            x_label: "step".into(),
            y_label: "PSNR (dB)".into(),
            log_y: false,
            series: vec![Series {
                name: "PSNR".into(),
                colour: [213, 94, 0],
                points: vec![(10.0, 20.0), (20.0, 22.0)],
                markers: true,
            }],
            references: vec![Reference {
                name: "mean shift".into(),
                value: 21.0,
            }],
        };
        let img = draw_panels(&[panel, val], 640, 240).unwrap();
        assert_eq!(img.size(), (640, 480));
        let has = |rgb: [u8; 3]| {
            let px = to_rgb8(&img);
            px.chunks_exact(3).any(|p| p == rgb)
        };
        assert!(has([230, 159, 0]) && has([213, 94, 0]) && has([120, 120, 120]));
        // Text was drawn: the title band of the first panel is not blank.
        assert!(dark_pixels(&img, 200, 440, 0, 30) > 20);
    }

    #[test]
    fn sheet_headers_sit_over_their_columns() {
        let a = Image::filled(40, 20, 3, 0.5);
        let b = Image::filled(20, 20, 3, 0.9);
        let sheet = Sheet {
            title: None,
            columns: vec!["input".into(), "network A".into()],
            rows: vec![
                SheetRow {
                    label: Some("img-1".into()),
                    images: vec![&a, &b],
                },
                SheetRow {
                    label: None,
                    images: vec![&b],
                },
            ],
            thumb: 40,
        };
        let img = draw_sheet(&sheet).unwrap();
        let (w, h) = img.size();
        // Two rows of 40 px thumbnails under one header line.
        assert!(h > 2 * 40 + 3 * SHEET_GAP && h < 2 * 40 + 60, "{h}");
        // The first column holds an 80x40 thumbnail; the label column comes first.
        assert!(w >= 80 + 40 + 3 * SHEET_GAP, "{w}");
        // The header band has text, the gap between rows has none.
        let band = dark_pixels(&img, 0, w, 0, 20);
        assert!(band > 10, "{band}");
        assert!(draw_sheet(&Sheet::default()).is_err());
    }
}
