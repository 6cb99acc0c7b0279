//! `uwnr dataset`, `uwnr dataset verify`, `uwnr dataset merge` (library: `uwnr_dataset`).

use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_core::io::DecodeLimits;
use uwnr_dataset::{Event, Renderer, RunOptions, Spec};

use crate::cli::{DatasetAction, DatasetArgs, DatasetFormat, DatasetMakeArgs};

/// Problems printed by `verify` before the rest are only counted.
const MAX_LISTED_PROBLEMS: usize = 200;

pub fn run(a: &DatasetArgs) -> Result<ExitCode> {
    match &a.action {
        Some(DatasetAction::Verify { out }) => verify(out),
        Some(DatasetAction::Merge {
            out,
            sources,
            no_gallery,
        }) => {
            let r = uwnr_dataset::merge(out, sources, !no_gallery)
                .with_context(|| format!("merging into {}", out.display()))?;
            eprintln!(
                "merged {} pairs{}{} into {}",
                r.pairs,
                r.shards
                    .map(|n| format!(" from {n} shards"))
                    .unwrap_or_default(),
                if r.copied > 0 {
                    format!(" ({} files copied)", r.copied)
                } else {
                    String::new()
                },
                out.join("manifest.jsonl").display()
            );
            if r.failed > 0 {
                eprintln!(
                    "{} planned pairs failed in the shards (see failed.jsonl)",
                    r.failed
                );
            }
            Ok(ExitCode::SUCCESS)
        }
        Some(DatasetAction::Export {
            out,
            to,
            shard_size,
        }) => export(out, to.as_deref(), *shard_size),
        None => make(&a.make),
    }
}

fn export(out: &Path, to: Option<&Path>, shard_size: u64) -> Result<ExitCode> {
    let bar = super::progress_bar("{spinner} packing {pos}/{len} pairs [{bar:30}] eta {eta}");
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let r = uwnr_dataset::export(out, to, shard_size, &progress)
        .with_context(|| format!("packing {} as WebDataset shards", out.display()))?;
    bar.finish_and_clear();
    eprintln!(
        "packed {} pairs into {} shard(s), {:.1} MB, in {:.1} s: {}",
        r.index.pairs,
        r.index.shards.len(),
        r.bytes as f64 / 1e6,
        r.secs,
        r.dir.join(&r.index.pattern).display()
    );
    Ok(ExitCode::SUCCESS)
}

fn renderer(a: &DatasetMakeArgs) -> Result<Renderer> {
    let have_refs = !a.references.is_empty();
    super::method::refuse_inapplicable(&[a.method], &a.baseline, have_refs)?;
    super::method::renderer(a.method, &a.baseline, &a.model, a.precision, have_refs)
}

fn make(a: &DatasetMakeArgs) -> Result<ExitCode> {
    let Some(out) = a.output.clone() else {
        anyhow::bail!("--output is required");
    };
    let renderer = renderer(a)?;
    let spec = Spec {
        clean: a.clean.clone(),
        references: a.references.clone(),
        per_image: a.per_image,
        seed: a.seed,
        size: a.size,
        save_depth: a.save_depth,
        save_lightfield: a.save_lightfield,
        depth: super::depth_source(&a.depth)?,
        depth_policy: super::depth_policy(
            &a.depth,
            a.baseline.depth_scale,
            uwnr_render::DepthPolicy::default(),
        ),
        labels: uwnr_dataset::LabelInputs {
            coco: a.coco.clone(),
            yolo: a.yolo.clone(),
            masks: a.masks.clone(),
        },
        target: a
            .target
            .as_deref()
            .map(|dir| {
                uwnr_dataset::WaterTarget::load(dir, &uwnr_core::io::DecodeLimits::default())
            })
            .transpose()?,
        camera: a.camera,
    };
    let jobs = a.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(usize::from)
            .unwrap_or(1)
    });
    let opts = RunOptions {
        shard: a.shard,
        jobs,
        limits: DecodeLimits::default(),
        gallery: !a.no_gallery,
    };

    let stop = super::stop_on_ctrl_c(
        "finishing the pairs in progress (Ctrl-C again to abort; resume with the same command)",
    )?;

    let bar =
        super::progress_bar("{spinner} pairs {pos}/{len} [{bar:30}] {per_sec} eta {eta} {msg}");
    let mut observer = |e: Event<'_>| match e {
        Event::Start {
            planned,
            done,
            todo,
        } => {
            bar.suspend(|| {
                eprintln!(
                    "{planned} pairs planned{}: {done} already done, {todo} to render with {jobs} job(s)",
                    a.shard
                        .map(|s| format!(" in shard {}/{}", s.index, s.count))
                        .unwrap_or_default()
                );
            });
            bar.set_length(todo as u64);
            bar.reset_eta();
        }
        Event::Pair(r) => {
            bar.inc(1);
            bar.set_message(r.id.clone());
        }
        Event::Failed(f) => {
            bar.inc(f.ids.len() as u64);
            bar.suspend(|| eprintln!("uwnr: failed: {}: {}", f.source, f.reason));
        }
        Event::Note(n) => bar.suspend(|| eprintln!("{n}")),
    };
    let summary = uwnr_dataset::generate(&out, &spec, &renderer, &opts, &stop, &mut observer)
        .with_context(|| format!("generating the dataset in {}", out.display()))?;
    bar.finish_and_clear();
    eprintln!(
        "dataset: {} rendered, {} skipped (already done), {} failed in {:.1} s ({:.2} pairs/s)",
        summary.rendered,
        summary.skipped,
        summary
            .failures
            .iter()
            .map(|f| f.ids.len().max(1))
            .sum::<usize>(),
        summary.secs,
        summary.rendered as f64 / summary.secs.max(1e-9)
    );
    if let Some(strength) = &summary.strength {
        eprintln!("{}", strength.line());
    }
    if !summary.labels_dropped.is_empty() {
        eprintln!(
            "labels: {} annotation(s) dropped over the dataset's pairs ({}); see labels_info in \
             manifest.jsonl",
            summary.labels_dropped.total(),
            summary.labels_dropped.line()
        );
    }
    if !summary.failures.is_empty() {
        eprintln!("failed items:");
        for f in &summary.failures {
            eprintln!("  {}: {}", f.source, f.reason);
        }
    }
    if summary.interrupted {
        eprintln!("stopped before the end: run the same command again to finish");
        return Ok(ExitCode::from(130));
    }
    if summary.complete && a.shard.is_none() {
        eprintln!("wrote {}", out.join("manifest.jsonl").display());
    }
    if a.format == DatasetFormat::Webdataset {
        if a.shard.is_some() {
            eprintln!(
                "note: a shard is not packed; after `uwnr dataset merge`, run `uwnr dataset export {}`",
                out.display()
            );
        } else if summary.rendered + summary.skipped > 0 {
            export(&out, None, a.shard_size)?;
        }
    }
    if !summary.complete {
        let made = summary.rendered + summary.skipped;
        let next = if summary.failures.is_empty() {
            "run the same command again to finish"
        } else {
            "fix the inputs listed in failed.jsonl, then run the same command again to finish"
        };
        eprintln!(
            "uwnr: incomplete: {made} of {} planned pairs made; {next}",
            summary.planned
        );
    }
    Ok(if summary.ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn verify(out: &std::path::Path) -> Result<ExitCode> {
    let bar = super::progress_bar("{spinner} checking {pos}/{len} pairs [{bar:30}] eta {eta}");
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let report = uwnr_dataset::verify(out, &progress)
        .with_context(|| format!("verifying {}", out.display()))?;
    bar.finish_and_clear();
    for n in &report.notes {
        eprintln!("note: {n}");
    }
    for p in report.problems.iter().take(MAX_LISTED_PROBLEMS) {
        eprintln!("problem: {p}");
    }
    if report.problems.len() > MAX_LISTED_PROBLEMS {
        eprintln!(
            "... and {} more problems",
            report.problems.len() - MAX_LISTED_PROBLEMS
        );
    }
    if report.ok() {
        eprintln!(
            "verify: OK: {} pairs ({} planned, {} not made because their inputs failed)",
            report.pairs, report.planned, report.failed
        );
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "verify: {} problem(s) in {} ({} pairs in the manifest, {} planned)",
            report.problems.len(),
            out.display(),
            report.pairs,
            report.planned
        );
        Ok(ExitCode::FAILURE)
    }
}
