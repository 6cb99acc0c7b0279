//! A look at a finished dataset: `preview.png`, a contact sheet of the first clean images each
//! followed by its renders, and `index.html`, a static page of side-by-side thumbnails (clean |
//! underwater) linking to the full images, readable from the folder with no server.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, save_rgb};
use uwnr_core::sheet::contact_sheet;

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
    let mut images: Vec<Vec<Image>> = Vec::new();
    for pairs in rows.values().take(PREVIEW_ROWS) {
        let mut row = vec![load(&pairs[0].clean)?];
        for p in pairs.iter().take(PREVIEW_RENDERS) {
            row.push(load(&p.underwater)?);
        }
        images.push(row);
    }
    let refs: Vec<Vec<&Image>> = images.iter().map(|r| r.iter().collect()).collect();
    save_rgb(
        &out.join(PREVIEW_FILE),
        &contact_sheet(&refs, PREVIEW_THUMB)?,
    )?;

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
    uwnr_core::io::write_atomic(&path, |w| w.write_all(page.as_bytes()))?;
    Ok(())
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
    use super::esc;

    #[test]
    fn escapes_markup() {
        assert_eq!(esc("a<b>&\"c\""), "a&lt;b&gt;&amp;&quot;c&quot;");
    }
}
