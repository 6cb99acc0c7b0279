//! `uwnr render`: clean photos + real underwater references -> underwater renders, at each clean
//! image's own resolution, with the UWNR network (default), the UWGAN-style GAN baseline (no
//! reference) or a physical / statistical baseline.

use std::collections::HashMap;
use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result, anyhow, bail};
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb, save_rgb};
use uwnr_render::{PreparedReference, ReferenceUse, Renderer, Worker};

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
    if spec.reference_use() == ReferenceUse::Required && refs.is_empty() {
        bail!(
            "--method {} needs --reference (a real underwater image whose style is rendered)",
            a.method
        );
    }
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
        uwnr_dataset::DepthPolicy::render(),
    );
    policy.validate()?;

    let limits = DecodeLimits::default();
    // Each reference is decoded (and its light field computed) once, then reused by every
    // clean image paired with it.
    let mut ref_inputs: HashMap<usize, std::result::Result<PreparedReference, String>> =
        HashMap::new();
    let worker = renderer.worker()?;
    let mut batch = Batch::new(jobs.len(), "rendering");
    for (index, job) in jobs.iter().enumerate() {
        let clean_path = &cleans[job.clean];
        let reference = job.reference.map(|r| {
            ref_inputs
                .entry(r)
                .or_insert_with(|| {
                    reference_input(&refs[r], &renderer, &limits).map_err(|e| format!("{e:#}"))
                })
                .as_ref()
                .map_err(|msg| anyhow!("{msg}"))
        });
        let result = match reference.transpose() {
            Ok(r) => render_one(
                clean_path,
                r,
                index,
                &job.output,
                &prepared,
                &policy,
                &worker,
                a.seed,
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

fn reference_input(
    path: &Path,
    renderer: &Renderer,
    limits: &DecodeLimits,
) -> Result<PreparedReference> {
    let reference =
        load_rgb(path, limits).with_context(|| format!("reading reference {}", path.display()))?;
    renderer
        .prepare_reference(reference)
        .with_context(|| format!("style of {}", path.display()))
}

/// Renders job `index` of the batch: its random parameters (the baselines', the GAN's water
/// code, a range's scene scale) are drawn from `item_seed(seed, index)`.
#[allow(clippy::too_many_arguments)]
fn render_one(
    clean_path: &Path,
    reference: Option<&PreparedReference>,
    index: usize,
    output: &Path,
    depth: &uwnr_depth::PreparedDepth,
    policy: &uwnr_dataset::DepthPolicy,
    worker: &Worker<'_>,
    seed: u64,
    limits: &DecodeLimits,
    batch: &Batch,
) -> Result<()> {
    let clean = load_rgb(clean_path, limits).context("reading clean image")?;
    let depth = depth.depth_for(&clean, Some(clean_path)).context("depth")?;
    for n in &depth.notes {
        batch.note(&format!("note: {}: {n}", clean_path.display()));
    }
    let seed = uwnr_baselines::item_seed(seed, index);
    let response = policy.response(&depth, seed);
    let out = worker
        .render(
            &clean,
            &depth.map,
            &response,
            reference.map(PreparedReference::input),
            seed,
        )?
        .image;
    save_rgb(output, &out).with_context(|| format!("writing {}", output.display()))?;
    Ok(())
}
