//! The model card's figures and colour-statistics table, from the bundled model (or
//! `--weights FILE`):
//! - `docs/model/depth-strip.jpg`: clean photos rendered at constant depths 0, 0.25, ... 1 and
//!   with their real depth map;
//! - `docs/model/contact-sheet.jpg`: in-air photos x references of different waters;
//! - on stdout, a Markdown table of the references' lαβ statistics beside the mean statistics of
//!   their renders.
//!
//! Run from the repository root with `../shared/data` present:
//! `cargo run --release -p uwnr-cli --example model_card_figures [-- --weights FILE]`

use std::path::{Path, PathBuf};

use uwnr_baselines::ColourSpace;
use uwnr_baselines::reinhard::reference_stats;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, save_rgb};
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::DepthSource;
use uwnr_figures::{Sheet, SheetRow, draw_sheet};
use uwnr_model::{Backend, Network, RenderOptions};

const DATA: &str = "../shared/data";
const THUMB: usize = 150;

fn load(path: &Path, long_side: usize) -> Image {
    let img = load_rgb(path, &DecodeLimits::default())
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    let (w, h) = img.size();
    let s = (long_side as f64 / w.max(h) as f64).min(1.0);
    let size = |n: usize| ((n as f64 * s).round() as usize).max(1);
    resize_bilinear(&img, size(w), size(h)).unwrap()
}

fn depth_map(clean: &Image, path: &Path, normalize: bool) -> Image {
    DepthSource::Maps {
        path: path.to_path_buf(),
        invert: false,
        normalize,
        unit: uwnr_depth::DepthUnit::Relative,
    }
    .prepare()
    .unwrap()
    .depth_for(clean, None)
    .unwrap()
    .map
}

fn grey_to_rgb(d: &Image) -> Image {
    let p = d.plane(0).to_vec();
    let (w, h) = d.size();
    Image::from_planar(w, h, 3, [p.clone(), p.clone(), p].concat()).unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let net = match args.iter().position(|a| a == "--weights") {
        Some(i) => {
            Network::load(Path::new(&args[i + 1]), &Backend::Engine)
                .unwrap()
                .0
        }
        None => uwnr_model::bundled_network()
            .expect("a build with the bundled model")
            .unwrap(),
    };
    let data = PathBuf::from(DATA);
    let samples = PathBuf::from("assets/samples");
    let opts = RenderOptions::default();
    std::fs::create_dir_all("docs/model").unwrap();

    // Depth strip.
    let depths = [0.0f32, 0.25, 0.5, 0.75, 1.0];
    let strip_cases = [
        (
            samples.join("clean-room.jpg"),
            samples.join("clean-room-depth.png"),
            false,
            samples.join("ref-green.png"),
        ),
        (
            data.join("rgbd/nyu/rgb/rgb_00050.jpg"),
            data.join("rgbd/nyu/depth/sync_depth_00050.png"),
            true,
            samples.join("ref-blue.jpg"),
        ),
    ];
    let mut strip_images: Vec<Vec<Image>> = Vec::new();
    let mut labels = Vec::new();
    for (clean_path, depth_path, normalize, ref_path) in &strip_cases {
        let clean = load(clean_path, 320);
        let style = net.style(&load(ref_path, 512)).unwrap();
        let (w, h) = clean.size();
        let mut row = vec![clean.clone()];
        for &d in &depths {
            row.push(
                net.render(&clean, &Image::filled(w, h, 1, d), &style, &opts)
                    .unwrap(),
            );
        }
        let real = depth_map(&clean, depth_path, *normalize);
        row.push(net.render(&clean, &real, &style, &opts).unwrap());
        row.push(grey_to_rgb(&real));
        strip_images.push(row);
        labels.push(format!(
            "{} / {}",
            clean_path.file_name().unwrap().to_string_lossy(),
            ref_path.file_name().unwrap().to_string_lossy()
        ));
    }
    let mut columns = vec!["clean".to_string()];
    columns.extend(depths.iter().map(|d| format!("depth {d}")));
    columns.extend(["real depth".to_string(), "depth map".to_string()]);
    let sheet = Sheet {
        title: Some(
            "Bundled model: one scene at constant depths and with its real depth map".into(),
        ),
        columns,
        rows: strip_images
            .iter()
            .zip(&labels)
            .map(|(r, l)| SheetRow {
                label: Some(l.clone()),
                images: r.iter().collect(),
            })
            .collect(),
        thumb: THUMB,
    };
    save_rgb(
        Path::new("docs/model/depth-strip.jpg"),
        &draw_sheet(&sheet).unwrap(),
    )
    .unwrap();

    // Contact sheet: in-air photos x waters.
    let refs = [
        ("blue", data.join("references/u45/blue/16.png")),
        ("green", data.join("references/u45/green/1.png")),
        ("hazy", data.join("references/u45/haze/31.png")),
        (
            "dark",
            data.join("paired/euvp-dark/underwater/264296_n02319095_1106.JPEG"),
        ),
        (
            "blue-green",
            data.join("references/ruie-uccs/blue-green/bg_00.jpg"),
        ),
    ];
    let cleans = [
        data.join("inair/sun-hays80/abbey_sun_asztnlqhlrvirneh.jpg"),
        data.join("inair/urban100/img_004.jpg"),
        data.join("inair/cbsd68/101085.jpg"),
        data.join("rgbd/nyu/rgb/rgb_00000.jpg"),
    ];
    let references: Vec<Image> = refs.iter().map(|(_, p)| load(p, 512)).collect();
    let styles: Vec<_> = references.iter().map(|r| net.style(r).unwrap()).collect();
    let mut rows_images: Vec<(String, Vec<Image>)> = vec![(
        "reference".into(),
        std::iter::once(Image::filled(8, 8, 3, 1.0))
            .chain(references.iter().cloned())
            .collect(),
    )];
    let mut render_stats = vec![[[0.0f64; 3]; 2]; refs.len()];
    for clean_path in &cleans {
        let clean = load(clean_path, 320);
        let depth = uwnr_depth::builtin_depth(&clean).unwrap();
        let mut row = vec![clean.clone()];
        for (k, style) in styles.iter().enumerate() {
            let out = net.render(&clean, &depth, style, &opts).unwrap();
            let st = reference_stats(&out, ColourSpace::LAlphaBeta).unwrap();
            let n = cleans.len() as f64;
            let [mean, std] = &mut render_stats[k];
            for (acc, v) in mean.iter_mut().zip(st.mean) {
                *acc += v / n;
            }
            for (acc, v) in std.iter_mut().zip(st.std) {
                *acc += v / n;
            }
            row.push(out);
        }
        rows_images.push((
            clean_path
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned(),
            row,
        ));
    }
    let mut columns = vec!["clean".to_string()];
    columns.extend(refs.iter().map(|(n, _)| n.to_string()));
    let sheet = Sheet {
        title: Some("Bundled model: in-air photos rendered with references of different waters (built-in depth)".into()),
        columns,
        rows: rows_images
            .iter()
            .map(|(l, r)| SheetRow {
                label: Some(l.clone()),
                images: r.iter().collect(),
            })
            .collect(),
        thumb: THUMB,
    };
    save_rgb(
        Path::new("docs/model/contact-sheet.jpg"),
        &draw_sheet(&sheet).unwrap(),
    )
    .unwrap();

    println!(
        "| reference | reference l, α, β mean | renders' mean | reference l, α, β std | renders' std |"
    );
    println!("|---|---|---|---|---|");
    for (k, (name, _)) in refs.iter().enumerate() {
        let r = reference_stats(&references[k], ColourSpace::LAlphaBeta).unwrap();
        let f = |v: [f64; 3]| format!("{:.3}, {:.3}, {:.3}", v[0], v[1], v[2]);
        println!(
            "| {name} | {} | {} | {} | {} |",
            f(r.mean),
            f(render_stats[k][0]),
            f(r.std),
            f(render_stats[k][1])
        );
    }
}
