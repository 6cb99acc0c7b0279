//! `uwnr render`: clean photos + real underwater references -> underwater renders, at each clean
//! image's own resolution, with the UWNR network (default), the UWGAN-style GAN baseline (no
//! reference) or a physical / statistical baseline.

use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb, save_rgb};
use uwnr_render::{JobWorker, PreparedReference, ReferenceUse, RenderJob, Renderer};

use crate::cli::RenderArgs;
use crate::inputs::{Job, expand_images, plan_jobs};
use crate::report::Batch;

pub fn run(a: &RenderArgs) -> Result<ExitCode> {
    let cleans = expand_images(&a.clean, "clean")?;
    let refs = if a.reference.is_empty() {
        Vec::new()
    } else {
        expand_images(&a.reference, "reference")?
    };
    super::method::refuse_inapplicable(&[a.method], &a.baseline, !refs.is_empty())?;
    let spec = super::method::method_spec(
        a.method,
        &a.baseline,
        &a.model,
        a.precision,
        !refs.is_empty(),
    )?;
    // A method that reads no reference (the GAN's water comes from the code drawn from --seed).
    let refs = if spec.reference_use() == ReferenceUse::Ignored && a.method.loads_weights() {
        if !refs.is_empty() {
            eprintln!(
                "note: --method {} uses no reference; --reference is ignored",
                a.method
            );
        }
        Vec::new()
    } else {
        refs
    };

    let single_file = cleans.len() == 1 && refs.len() <= 1 && is_image_path(&a.output);
    let jobs: Vec<Job> = if single_file {
        vec![Job {
            clean: 0,
            reference: (!refs.is_empty()).then_some(0),
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

    let renderer = Renderer::load(spec)?;
    let prepared = super::depth_source(&a.depth)?
        .prepare()
        .context("preparing the depth source")?;
    if a.depth.prior_trust.is_some() && a.method != uwnr_render::MethodKind::Uwnr {
        bail!("--prior-trust applies to --method uwnr only");
    }
    let policy = super::depth_policy(
        &a.depth,
        a.baseline.depth_scale,
        uwnr_render::DepthPolicy::render(),
    );
    // Each reference is decoded (and its style computed) once, then reused by every clean image
    // paired with it.
    let render_job = RenderJob::new(Arc::new(renderer), policy, a.seed, refs.len())?;

    let limits = DecodeLimits::default();
    let worker = render_job.worker();
    let mut batch = Batch::new(jobs.len(), "rendering");
    for (index, job) in jobs.iter().enumerate() {
        let clean_path = &cleans[job.clean];
        let reference = job.reference.map(|r| {
            let path = &refs[r];
            render_job
                .reference(&path.to_string_lossy(), || {
                    reference_image(path, &limits).map_err(Into::into)
                })
                .map_err(anyhow::Error::from)
        });
        let result = match reference.transpose() {
            Ok(r) => render_one(
                clean_path,
                r.as_deref(),
                render_job.item_seed(index),
                &job.output,
                &prepared,
                &worker,
                &limits,
                &batch,
            ),
            Err(e) => Err(e),
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

fn reference_image(path: &Path, limits: &DecodeLimits) -> Result<Arc<Image>> {
    load_rgb(path, limits)
        .map(Arc::new)
        .with_context(|| format!("reading reference {}", path.display()))
}

/// Renders one item of the batch: its random parameters (the baselines', the GAN's water code, a
/// range's scene scale) are drawn from `seed`, the item's.
#[allow(clippy::too_many_arguments)]
fn render_one(
    clean_path: &Path,
    reference: Option<&PreparedReference>,
    seed: u64,
    output: &Path,
    depth: &uwnr_depth::PreparedDepth,
    worker: &JobWorker<'_>,
    limits: &DecodeLimits,
    batch: &Batch,
) -> Result<()> {
    let clean = load_rgb(clean_path, limits).context("reading clean image")?;
    let depth = depth.depth_for(&clean, Some(clean_path)).context("depth")?;
    for n in &depth.notes {
        batch.note(&format!("note: {}: {n}", clean_path.display()));
    }
    let out = worker
        .render(
            &clean,
            &depth,
            reference.map(PreparedReference::input),
            seed,
        )?
        .image;
    save_rgb(output, &out).with_context(|| format!("writing {}", output.display()))?;
    Ok(())
}
