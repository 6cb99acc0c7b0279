//! `uwnr render`: clean photos + real underwater references -> underwater renders, at each clean
//! image's own resolution, with the UWNR network (default), the UWGAN-style GAN baseline (no
//! reference) or a physical / statistical baseline.

use std::collections::HashMap;
use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result, anyhow, bail};
use uwnr_baselines::{Method, RenderInput};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, is_image_path, load_rgb, save_rgb};
use uwnr_model::{Network, ReferenceStyle, RenderOptions};

use crate::cli::{MethodArg, RenderArgs};
use crate::inputs::{Job, expand_images, plan_jobs};
use crate::report::Batch;

/// What renders each job.
enum Renderer {
    Network {
        network: Box<Network>,
        opts: RenderOptions,
        /// Seeds the scene scale drawn per image when `--depth-scale` is a range.
        seed: u64,
    },
    /// The GAN baseline: the water code of job `index` is drawn from `item_seed(seed, index)`.
    Gan {
        generator: Box<uwnr_gan::Generator>,
        device: uwnr_model::Device,
        seed: u64,
    },
    Baseline {
        method: Method,
        seed: u64,
    },
}

/// The per-reference input a renderer needs, computed once per reference.
enum RefInput {
    /// What the network takes of the reference (its light field, and its water).
    Style(ReferenceStyle),
    /// The decoded reference (baselines).
    Image(Image),
}

pub fn run(a: &RenderArgs) -> Result<ExitCode> {
    let cleans = expand_images(&a.clean, "clean")?;
    let refs = if a.reference.is_empty() {
        Vec::new()
    } else {
        expand_images(&a.reference, "reference")?
    };
    super::method::refuse_inapplicable(&[a.method], &a.baseline, !refs.is_empty())?;
    let baseline = super::method::baseline_method(a.method, &a.baseline, !refs.is_empty())?;
    let gan = a.method == MethodArg::Uwgan;
    if baseline.is_none() && !gan && refs.is_empty() {
        bail!("--method uwnr needs --reference (a real underwater image whose style is rendered)");
    }
    // The GAN reads no reference: its water comes from the code drawn from --seed.
    let refs = if gan {
        if !refs.is_empty() {
            eprintln!("note: --method uwgan uses no reference; --reference is ignored");
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

    let renderer = match baseline {
        Some(method) => Renderer::Baseline {
            method,
            seed: a.seed,
        },
        None if gan => {
            let (generator, device, _bytes, _source) = super::load_gan(&a.model, a.precision)?;
            Renderer::Gan {
                generator: Box::new(generator),
                device,
                seed: a.seed,
            }
        }
        None => {
            let backend = super::backend_at(a.model.device, a.precision)?;
            let (network, _info, _source) =
                super::load_network(a.model.weights.as_deref(), &backend)?;
            Renderer::Network {
                network: Box::new(network),
                opts: RenderOptions {
                    max_tile_pixels: a.model.max_whole_pixels,
                    tile: a.model.tile,
                    overlap: a.model.overlap,
                    ..Default::default()
                },
                seed: a.seed,
            }
        }
    };
    let prepared = super::depth_source(&a.depth)?
        .prepare()
        .context("preparing the depth source")?;
    if a.depth.prior_trust.is_some() && a.method != MethodArg::Uwnr {
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
    let mut ref_inputs: HashMap<usize, std::result::Result<RefInput, String>> = HashMap::new();
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
                &job.output,
                &prepared,
                &policy,
                &renderer,
                index,
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

fn reference_input(path: &Path, renderer: &Renderer, limits: &DecodeLimits) -> Result<RefInput> {
    let reference =
        load_rgb(path, limits).with_context(|| format!("reading reference {}", path.display()))?;
    Ok(match renderer {
        Renderer::Network { network, .. } => RefInput::Style(
            network
                .style(&reference)
                .with_context(|| format!("style of {}", path.display()))?,
        ),
        Renderer::Baseline { .. } | Renderer::Gan { .. } => RefInput::Image(reference),
    })
}

#[allow(clippy::too_many_arguments)]
fn render_one(
    clean_path: &Path,
    reference: Option<&RefInput>,
    output: &Path,
    depth: &uwnr_depth::PreparedDepth,
    policy: &uwnr_dataset::DepthPolicy,
    renderer: &Renderer,
    index: usize,
    limits: &DecodeLimits,
    batch: &Batch,
) -> Result<()> {
    let clean = load_rgb(clean_path, limits).context("reading clean image")?;
    let depth = depth.depth_for(&clean, Some(clean_path)).context("depth")?;
    for n in &depth.notes {
        batch.note(&format!("note: {}: {n}", clean_path.display()));
    }
    let out = match (renderer, reference) {
        (Renderer::Network { network, opts, .. }, Some(RefInput::Style(style))) => {
            // The scene scale of a range is drawn per image, as the baselines draw theirs.
            let seed = match renderer {
                Renderer::Network { seed, .. } => uwnr_baselines::item_seed(*seed, index),
                _ => 0,
            };
            let opts = RenderOptions {
                depth: policy.response(&depth, seed),
                ..*opts
            };
            network
                .render(&clean, &depth.map, style, &opts)
                .context("rendering")?
        }
        (Renderer::Baseline { method, seed }, reference) => {
            let reference = match reference {
                Some(RefInput::Image(img)) => Some(img),
                _ => None,
            };
            let input = RenderInput {
                clean: &clean,
                depth: &depth.map,
                reference,
            };
            uwnr_baselines::render(method, &input, uwnr_baselines::item_seed(*seed, index))
                .with_context(|| format!("rendering with {}", method.name()))?
                .image
        }
        (
            Renderer::Gan {
                generator,
                device,
                seed,
            },
            _,
        ) => uwnr_gan::render(
            generator,
            &clean,
            &depth.map,
            uwnr_baselines::item_seed(*seed, index),
            device,
        )
        .context("rendering with uwgan")?,
        (Renderer::Network { .. }, _) => bail!("the network needs a reference"),
    };
    save_rgb(output, &out).with_context(|| format!("writing {}", output.display()))?;
    Ok(())
}
