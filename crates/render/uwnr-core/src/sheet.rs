//! Contact sheets: rows of images scaled to one height, side by side on a white ground. Used for
//! training's validation sheets and a generated dataset's preview.

use crate::error::{CoreError, Result};
use crate::image::Image;
use crate::resize::resize_bilinear;

/// White space between thumbnails and around the sheet, in pixels.
pub const GAP: usize = 4;

/// Lays out `rows` (each a list of RGB images) as one sheet: every image is scaled to `thumb`
/// pixels high with its aspect kept, rows are stacked top to bottom, images left to right, with
/// [`GAP`] pixels of white between them. Rows may hold different numbers of images.
pub fn contact_sheet(rows: &[Vec<&Image>], thumb: usize) -> Result<Image> {
    if rows.is_empty() || rows.iter().all(Vec::is_empty) {
        return Err(CoreError::InvalidArgument(
            "a contact sheet needs at least one image".into(),
        ));
    }
    if thumb == 0 {
        return Err(CoreError::InvalidArgument(
            "contact-sheet thumbnails need a height of at least 1 pixel".into(),
        ));
    }
    let mut scaled: Vec<Vec<Image>> = Vec::with_capacity(rows.len());
    let mut width = 0;
    for row in rows {
        let mut out = Vec::with_capacity(row.len());
        for im in row {
            if im.channels() != 3 {
                return Err(CoreError::InvalidArgument(format!(
                    "contact sheets take RGB images, got {} channels",
                    im.channels()
                )));
            }
            let w = ((im.width() * thumb) as f64 / im.height().max(1) as f64)
                .round()
                .max(1.0) as usize;
            out.push(resize_bilinear(im, w, thumb)?);
        }
        width = width.max(out.iter().map(|i| i.width() + GAP).sum::<usize>() + GAP);
        scaled.push(out);
    }
    let height = rows.len() * (thumb + GAP) + GAP;
    let mut sheet = Image::filled(width, height, 3, 1.0);
    for (r, row) in scaled.iter().enumerate() {
        let mut x0 = GAP;
        let y0 = GAP + r * (thumb + GAP);
        for im in row {
            for c in 0..3 {
                let src = im.plane(c);
                let dst = sheet.plane_mut(c);
                for y in 0..im.height() {
                    let s = &src[y * im.width()..(y + 1) * im.width()];
                    let d = (y0 + y) * width + x0;
                    dst[d..d + im.width()].copy_from_slice(s);
                }
            }
            x0 += im.width() + GAP;
        }
    }
    Ok(sheet)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lays_out_rows_at_thumbnail_height() {
        let a = Image::filled(20, 10, 3, 0.0);
        let b = Image::filled(10, 10, 3, 0.5);
        let sheet = contact_sheet(&[vec![&a, &b], vec![&b]], 8).unwrap();
        // Row 0: 16 + 8 wide plus three gaps; two rows of 8 plus three gaps.
        assert_eq!(sheet.size(), (16 + 8 + 3 * GAP, 2 * 8 + 3 * GAP));
        assert_eq!(sheet.get(0, GAP, GAP), 0.0);
        assert_eq!(sheet.get(1, GAP, GAP + 16 + GAP), 0.5);
        assert_eq!(sheet.get(2, 0, 0), 1.0);
        // Second row, right of its single image: white.
        assert_eq!(sheet.get(0, 2 * GAP + 8, GAP + 8 + GAP + 1), 1.0);
    }

    #[test]
    fn rejects_empty_and_non_rgb() {
        assert!(contact_sheet(&[], 8).is_err());
        let g = Image::filled(4, 4, 1, 0.0);
        assert!(contact_sheet(&[vec![&g]], 8).is_err());
    }
}
