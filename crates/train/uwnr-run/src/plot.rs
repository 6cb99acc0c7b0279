//! Pictures of a run, drawn with `uwnr-figures` (plotters and an embedded DejaVu Sans): the
//! loss and validation curves (`curves.png`: titles, axis labels, a legend per panel) and the
//! validation contact sheets (columns headed by the task, one row per pair, labelled with its
//! name).

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::save_rgb;
use uwnr_figures::{Panel, Reference, Series, Sheet, SheetRow, draw_panels, draw_sheet};

use crate::error::{Result, RunError};

/// Width of the curve picture.
const PLOT_W: u32 = 960;
/// Height of each of the two panels.
const PANEL_H: u32 = 320;
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
/// Colour of the validation PSNR curve.
const VAL_COLOUR: [u8; 3] = [213, 94, 0];
/// One validation: step, PSNR.
pub type ValPoint = (usize, f64);

/// A named curve of the loss panel.
#[derive(Clone, Debug, PartialEq)]
pub struct LossSeries {
    /// Legend text.
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

/// Draws a run's curve picture: the top panel shows the loss `series` (log scale) against the
/// step, the bottom panel the validation PSNR with dashed reference lines (e.g. baselines) at
/// `refs`. Series are drawn last to first, so the first lies on top.
pub fn draw_loss_curves(
    path: &Path,
    series: &[LossSeries],
    val: &[ValPoint],
    refs: &[f64],
) -> Result<()> {
    let losses = Panel {
        title: "Training loss (mean per logged window)".into(),
        x_label: "step".into(),
        y_label: "loss (log scale)".into(),
        log_y: true,
        series: series
            .iter()
            .map(|s| Series {
                name: s.name.clone(),
                colour: s.colour,
                points: s.points.iter().map(|&(x, y)| (x as f64, y)).collect(),
                markers: false,
            })
            .collect(),
        references: Vec::new(),
    };
    let validation = Panel {
        title: "Validation".into(),
        x_label: "step".into(),
        y_label: "PSNR (dB)".into(),
        log_y: false,
        series: vec![Series {
            name: "validation PSNR".into(),
            colour: VAL_COLOUR,
            points: val.iter().map(|&(x, y)| (x as f64, y)).collect(),
            markers: true,
        }],
        references: refs
            .iter()
            .map(|&value| Reference {
                name: format!("reference {value:.2} dB"),
                value,
            })
            .collect(),
    };
    let img = draw_panels(&[losses, validation], PLOT_W, PANEL_H).map_err(figure_err)?;
    save_rgb(path, &img)?;
    Ok(())
}

fn figure_err(e: uwnr_figures::FigureError) -> RunError {
    RunError::Figure(e.to_string())
}

/// One row of a contact sheet: its label and its images, one per column.
pub type SheetLine = (String, Vec<Image>);

/// A contact sheet: one row per `(name, images)`, each image scaled to `thumb` pixels high
/// (aspect kept), under the column headers `columns`.
pub fn contact_sheet(
    path: &Path,
    columns: &[&str],
    rows: &[SheetLine],
    thumb: usize,
) -> Result<()> {
    if rows.is_empty() {
        return Err(RunError::Figure(
            "a contact sheet needs at least one row".into(),
        ));
    }
    let sheet = Sheet {
        title: None,
        columns: columns.iter().map(|c| (*c).to_string()).collect(),
        rows: rows
            .iter()
            .map(|(name, images)| SheetRow {
                label: Some(name.clone()),
                images: images.iter().collect(),
            })
            .collect(),
        thumb,
    };
    let img = draw_sheet(&sheet).map_err(figure_err)?;
    save_rgb(path, &img)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
                name: "total".into(),
                colour: TOTAL_COLOUR,
                points: (1..=20).map(|s| (s, 2.0 / s as f64)).collect(),
            },
        ];
        draw_loss_curves(&path, &series, &[(10, 20.0), (20, 22.0)], &[21.0]).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (PLOT_W, 2 * PANEL_H));
        let has = |c: [u8; 3]| img.pixels().any(|p| p.0 == c);
        assert!(has(series_colour(0)) && has(VAL_COLOUR));
    }

    #[test]
    fn contact_sheets_have_a_header_and_a_row_per_pair() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sheet.png");
        let im = Image::filled(16, 8, 3, 0.5);
        let rows = vec![
            ("a".to_string(), vec![im.clone(), im.clone(), im.clone()]),
            ("b".to_string(), vec![im.clone(), im.clone(), im]),
        ];
        let columns = ["clean", "render", "real underwater"];
        contact_sheet(&path, &columns, &rows, 32).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        // Two rows of 32 px plus a header line above them.
        assert!(img.height() > 2 * 32 + 12, "{}", img.height());
        assert!(contact_sheet(&path, &columns, &[], 32).is_err());
    }
}
