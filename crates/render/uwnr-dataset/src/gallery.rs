//! A look at a finished dataset: `preview.png`, a contact sheet of the first clean images each
//! followed by its renders, under column headers (`clean`, `underwater 1 (METHOD)`, ...) and
//! with each row labelled with the clean image's name, drawn by `uwnr-figures`; and
//! `index.html`, a static page of side-by-side thumbnails (clean | underwater) linking to the
//! full images, readable from the folder with no server.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, save_rgb};
use uwnr_core::sheet::contact_sheet;
use uwnr_figures::{Sheet, SheetRow, draw_sheet};

use crate::error::{DatasetError, Result, io_err};
use crate::manifest::Record;

/// Name of the contact sheet.
pub const PREVIEW_FILE: &str = "preview.png";
/// Name of the gallery page.
pub const INDEX_FILE: &str = "index.html";
/// Folder of the gallery thumbnails.
pub const GALLERY_DIR: &str = "gallery";
/// Clean images (rows) on the contact sheet.
const PREVIEW_ROWS: usize = 8;
/// Renders per row on the contact sheet.
const PREVIEW_RENDERS: usize = 6;
/// Height of a contact-sheet thumbnail.
const PREVIEW_THUMB: usize = 160;
/// Longest row label on the contact sheet, in characters (longer names are shortened with an
/// ellipsis so that one long file name does not widen the label column for every row).
const PREVIEW_LABEL_CHARS: usize = 24;
/// Pairs shown on the gallery page (the page stays light for datasets of any size).
const GALLERY_PAIRS: usize = 240;
/// Height of a gallery thumbnail.
const GALLERY_THUMB: usize = 128;

/// Writes `preview.png`, `gallery/*.jpg` and `index.html` for the pairs in `records`.
pub fn write(out: &Path, records: &[Record]) -> Result<()> {
    if records.is_empty() {
        return Ok(());
    }
    let mut sorted: Vec<&Record> = records.iter().collect();
    sorted.sort_by_key(|r| r.index);
    let limits = DecodeLimits::default();
    let load = |rel: &str| load_rgb(&out.join(rel), &limits).map_err(DatasetError::from);

    // Contact sheet: rows grouped by clean source, in pair order.
    let mut rows: BTreeMap<u64, Vec<&Record>> = BTreeMap::new();
    let mut first_index: BTreeMap<String, u64> = BTreeMap::new();
    for r in &sorted {
        let key = *first_index.entry(r.clean_source.clone()).or_insert(r.index);
        rows.entry(key).or_default().push(r);
    }
    let shown_rows: Vec<&[&Record]> = rows
        .values()
        .take(PREVIEW_ROWS)
        .map(|pairs| &pairs[..pairs.len().min(PREVIEW_RENDERS)])
        .collect();
    let mut images: Vec<(String, Vec<Image>)> = Vec::with_capacity(shown_rows.len());
    for pairs in &shown_rows {
        let mut row = vec![load(&pairs[0].clean)?];
        for p in *pairs {
            row.push(load(&p.underwater)?);
        }
        images.push((row_label(&pairs[0].id), row));
    }
    let sheet = Sheet {
        title: None,
        columns: preview_columns(&shown_rows),
        rows: images
            .iter()
            .map(|(label, row)| SheetRow {
                label: Some(label.clone()),
                images: row.iter().collect(),
            })
            .collect(),
        thumb: PREVIEW_THUMB,
    };
    save_rgb(&out.join(PREVIEW_FILE), &draw_sheet(&sheet)?)?;

    // Gallery thumbnails and page.
    let dir = out.join(GALLERY_DIR);
    std::fs::create_dir_all(&dir).map_err(io_err(&dir))?;
    let shown = &sorted[..sorted.len().min(GALLERY_PAIRS)];
    let mut cards = String::new();
    for r in shown {
        let clean = load(&r.clean)?;
        let under = load(&r.underwater)?;
        let thumb = contact_sheet(&[vec![&clean, &under]], GALLERY_THUMB)?;
        let name = format!("{GALLERY_DIR}/{}.jpg", r.id);
        save_rgb(&out.join(&name), &thumb)?;
        let reference = r
            .reference_source
            .as_deref()
            .map(|s| {
                Path::new(s)
                    .file_name()
                    .map_or(s.to_string(), |n| n.to_string_lossy().into_owned())
            })
            .unwrap_or_else(|| "no reference".into());
        let _ = writeln!(
            cards,
            "<figure><a href=\"{u}\"><img src=\"{t}\" alt=\"{id}\" loading=\"lazy\"></a>\
             <figcaption><b>{id}</b> {w}x{h}<br>reference: {rf}<br>\
             <a href=\"{c}\">clean</a> · <a href=\"{u}\">underwater</a></figcaption></figure>",
            u = esc(&r.underwater),
            t = esc(&name),
            id = esc(&r.id),
            w = r.width,
            h = r.height,
            rf = esc(&reference),
            c = esc(&r.clean),
        );
    }
    let method = sorted[0].method.as_str();
    let page = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>uwnr dataset: {n} pairs</title>\n<style>\
         body{{font:14px system-ui,sans-serif;margin:1.5em;background:#f4f6f8}}\
         main{{display:flex;flex-wrap:wrap;gap:12px}}\
         figure{{margin:0;background:#fff;padding:6px;border-radius:4px;box-shadow:0 1px 2px #0002}}\
         figcaption{{font-size:12px;color:#333;margin-top:4px}}img{{display:block}}\
         </style></head><body>\n<h1>uwnr dataset</h1>\n<p>{n} pairs, method <b>{m}</b>; \
         each card shows the clean image and its underwater render. \
         Showing {s} of {n}; see <code>manifest.jsonl</code> for all, \
         <a href=\"{p}\">{p}</a> for an overview.</p>\n<main>\n{cards}</main>\n</body></html>\n",
        n = sorted.len(),
        m = esc(method),
        s = shown.len(),
        p = PREVIEW_FILE,
    );
    let path = out.join(INDEX_FILE);
    uwnr_core::io::write_atomic_bytes(&path, page.as_bytes())?;
    Ok(())
}

/// The contact sheet's column headers: `clean`, then one per render column, `underwater N
/// (METHOD)`, or just `underwater` when each clean image has one render (without the method
/// when the column mixes methods, as a merged folder may).
fn preview_columns(rows: &[&[&Record]]) -> Vec<String> {
    let renders = rows.iter().map(|r| r.len()).max().unwrap_or(0);
    let mut columns = vec!["clean".to_string()];
    for j in 0..renders {
        let mut methods = rows
            .iter()
            .filter_map(|r| r.get(j))
            .map(|r| r.method.as_str());
        let first = methods.next();
        let method = first.filter(|m| methods.all(|x| x == *m));
        let name = if renders == 1 {
            "underwater".to_string()
        } else {
            format!("underwater {}", j + 1)
        };
        columns.push(match method {
            Some(m) => format!("{name} ({m})"),
            None => name,
        });
    }
    columns
}

/// The row label of a clean image: its name in the dataset (the pair id `NAME_k` without `_k`),
/// shortened to [`PREVIEW_LABEL_CHARS`] characters.
fn row_label(pair_id: &str) -> String {
    let name = pair_id.rsplit_once('_').map_or(pair_id, |(name, _)| name);
    if name.chars().count() <= PREVIEW_LABEL_CHARS {
        name.to_string()
    } else {
        let head: String = name.chars().take(PREVIEW_LABEL_CHARS - 1).collect();
        format!("{head}\u{2026}")
    }
}

/// Escapes text for HTML.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use uwnr_figures::SHEET_GAP;

    fn record(name: &str, k: usize, index: u64, method: &str) -> Record {
        let id = format!("{name}_{k}");
        Record {
            id: id.clone(),
            index,
            clean_source: format!("in/{name}.png"),
            reference_source: None,
            method: method.into(),
            params: uwnr_render::MethodRecord::Earlier(serde_json::Value::Null),
            seed: 0,
            width: 24,
            height: 16,
            underwater: format!("underwater/{id}.png"),
            clean: format!("clean/{id}.png"),
            depth: None,
            lightfield: None,
            labels: None,
            mask: None,
            strength_db: None,
            labels_info: None,
        }
    }

    #[test]
    fn escapes_markup() {
        assert_eq!(esc("a<b>&\"c\""), "a&lt;b&gt;&amp;&quot;c&quot;");
    }

    #[test]
    fn columns_name_the_method_and_rows_the_image() {
        let (a0, a1, b0) = (
            record("a", 0, 0, "jerlov"),
            record("a", 1, 1, "jerlov"),
            record("b", 0, 2, "reinhard"),
        );
        let rows: [&[&Record]; 2] = [&[&a0, &a1], &[&b0]];
        assert_eq!(
            preview_columns(&rows),
            ["clean", "underwater 1", "underwater 2 (jerlov)"]
        );
        let one: [&[&Record]; 1] = [&[&b0]];
        assert_eq!(preview_columns(&one), ["clean", "underwater (reinhard)"]);
        assert_eq!(row_label("img_07_3"), "img_07");
        let long = row_label(&format!("{}_0", "x".repeat(40)));
        assert_eq!(long.chars().count(), PREVIEW_LABEL_CHARS);
        assert!(long.ends_with('\u{2026}'));
    }

    #[test]
    fn preview_has_a_header_band_and_a_label_column() {
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path();
        for dir in ["clean", "underwater"] {
            std::fs::create_dir_all(out.join(dir)).unwrap();
        }
        let records = vec![
            record("a", 0, 0, "jerlov"),
            record("a", 1, 1, "jerlov"),
            record("b", 0, 2, "jerlov"),
            record("b", 1, 3, "jerlov"),
        ];
        // 24x16 images: thumbnails 240 wide at the sheet's 160 px height.
        for r in &records {
            save_rgb(&out.join(&r.clean), &Image::filled(24, 16, 3, 0.8)).unwrap();
            save_rgb(&out.join(&r.underwater), &Image::filled(24, 16, 3, 0.3)).unwrap();
        }
        write(out, &records).unwrap();
        let preview = load_rgb(&out.join(PREVIEW_FILE), &DecodeLimits::default()).unwrap();
        let (w, h) = preview.size();
        // Without headers: the gap above, then two rows of a thumbnail and a gap.
        let bare_h = SHEET_GAP + 2 * (PREVIEW_THUMB + SHEET_GAP);
        let header = h - bare_h;
        assert!((12..40).contains(&header), "header band of {header} px");
        // Three 240 px columns and a label column, with nothing wider than needed.
        let bare_w = SHEET_GAP + 3 * (240 + SHEET_GAP);
        let label = w - bare_w;
        assert!((8..80).contains(&label), "label column of {label} px");
        // The header band holds text (dark pixels) over the columns.
        let dark = (0..header)
            .flat_map(|y| (label..w).map(move |x| (y, x)))
            .filter(|&(y, x)| (0..3).all(|c| preview.get(c, y, x) < 0.3))
            .count();
        assert!(dark > 20, "{dark} dark pixels in the header band");
        assert!(out.join(INDEX_FILE).is_file());
    }
}
