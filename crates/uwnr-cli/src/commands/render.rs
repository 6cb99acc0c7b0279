//! `uwnr render`: clean photos + real underwater references -> underwater renders, at each clean
//! image's own resolution.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, Result, anyhow, bail};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb, save_rgb};
use uwnr_core::lightfield::light_field;
use uwnr_core::resize::resize_bilinear;
use uwnr_model::RenderOptions;

use crate::cli::RenderArgs;
use crate::inputs::{Job, expand_images, plan_jobs};
use crate::report::Batch;

pub fn run(a: &RenderArgs) -> Result<ExitCode> {
    let cleans = expand_images(&a.clean, "clean")?;
    let refs = expand_images(&a.reference, "reference")?;

    let single_file = cleans.len() == 1 && refs.len() == 1 && is_image_path(&a.output);
    let jobs: Vec<Job> = if single_file {
        vec![Job {
            clean: 0,
            reference: 0,
            output: a.output.clone(),
        }]
    } else {
        if is_image_path(&a.output) && !a.output.is_dir() {
            bail!(
                "--output {} names an image file, but {} clean image(s) and {} reference(s) were given: \
                 pass a directory",
                a.output.display(),
                cleans.len(),
                refs.len()
            );
        }
        std::fs::create_dir_all(&a.output)
            .with_context(|| format!("creating output directory {}", a.output.display()))?;
        plan_jobs(
            &cleans,
            &refs,
            a.pairing,
            a.seed,
            &a.output,
            a.format.extension(),
        )
    };

    let device = super::device(a.model.device)?;
    let (generator, _config, _info, _source) = super::load_model(a.model.weights.as_deref(), &device)?;
    let prepared = super::depth_source(&a.depth)
        .prepare()
        .context("preparing the depth source")?;
    let opts = RenderOptions {
        max_tile_pixels: a.model.max_whole_pixels,
        tile: a.model.tile,
        overlap: a.model.overlap,
    };

    let limits = DecodeLimits::default();
    // Each reference's light field is computed once (at the 256x256 scale the network was trained
    // with) and resized to every clean image that uses it.
    let mut fields: HashMap<usize, std::result::Result<Image, String>> = HashMap::new();
    let mut batch = Batch::new(jobs.len(), "rendering");
    for job in &jobs {
        let clean_path = &cleans[job.clean];
        let ref_path = &refs[job.reference];
        let field = fields
            .entry(job.reference)
            .or_insert_with(|| reference_field(ref_path, &limits).map_err(|e| format!("{e:#}")));
        let result = match field {
            Ok(field) => render_one(
                clean_path,
                field,
                &job.output,
                &prepared,
                &generator,
                &opts,
                &device,
                &limits,
                &batch,
            ),
            Err(msg) => Err(anyhow!("{msg}")),
        };
        match result {
            Ok(()) => batch.ok(),
            Err(e) => batch.fail(clean_path.clone(), &e),
        }
    }
    let all_ok = batch.finish("render");
    if single_file && all_ok {
        eprintln!("wrote {}", a.output.display());
    }
    Ok(if all_ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn reference_field(path: &Path, limits: &DecodeLimits) -> Result<Image> {
    let reference =
        load_rgb(path, limits).with_context(|| format!("reading reference {}", path.display()))?;
    light_field(&reference).with_context(|| format!("light field of {}", path.display()))
}

#[allow(clippy::too_many_arguments)]
fn render_one(
    clean_path: &PathBuf,
    field: &Image,
    output: &Path,
    depth: &uwnr_depth::PreparedDepth,
    generator: &uwnr_model::Generator,
    opts: &RenderOptions,
    device: &uwnr_model::Device,
    limits: &DecodeLimits,
    batch: &Batch,
) -> Result<()> {
    let clean = load_rgb(clean_path, limits).context("reading clean image")?;
    let depth = depth.depth_for(&clean, Some(clean_path)).context("depth")?;
    for n in &depth.notes {
        batch.note(&format!("note: {}: {n}", clean_path.display()));
    }
    let lf = resize_bilinear(field, clean.width(), clean.height())?;
    let out = uwnr_model::render(generator, &clean, &depth.map, &lf, opts, device).context("rendering")?;
    save_rgb(output, &out).with_context(|| format!("writing {}", output.display()))?;
    Ok(())
}
