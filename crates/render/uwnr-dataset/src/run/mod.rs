//! A dataset run: render every planned pair that is not yet in the manifest.
//!
//! `jobs` worker threads take clean images from a shared queue; each decodes its image, fits it
//! to the pair size, computes its depth once, draws its references, and renders and writes its K
//! pairs, while the other workers are at other stages of their own images, so decoding, depth,
//! rendering and encoding overlap. Finished pairs go through a bounded channel to the calling
//! thread, the only writer of the manifest. Memory is bounded by `jobs` images in flight plus
//! the light-field cache (one 256x256 u8 map, 192 KiB, per reference used).
//!
//! Crash safety: every file is written to a temporary name and renamed; a pair's manifest line
//! is appended, as one write, only after all its files are in place. A run killed at any moment
//! leaves complete pairs in the manifest, perhaps files of unfinished pairs (rewritten
//! identically on resume) and perhaps one torn last manifest line (dropped on resume).
//!
//! Determinism: a pair depends only on its inputs, its references (a seeded draw per clean
//! image, see [`ReferenceOrder`]) and its seed ([`pair_seed`]), never on which thread or shard
//! made it or when. A complete run rewrites its manifest in pair order, so the same command gives
//! byte-identical folders whatever `jobs` is.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::sync_channel;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::DepthSource;
use uwnr_model::ReferenceStyle;

use crate::labels::{Fit, LABELS_DIR, LabelInputs, Labels, MASKS_DIR};
use crate::target::{StrengthSummary, WaterTarget};

mod resume;
mod worker;
use resume::remove_stale_temps;
use worker::Context;

use crate::error::{DatasetError, Result, io_err};
use crate::manifest::{
    CLEAN_DIR, DEPTH_DIR, FORMAT, Failure, LIGHTFIELD_DIR, ManifestWriter, Record, Settings,
    UNDERWATER_DIR, failed_name, manifest_name, read_manifest, write_failures, write_manifest,
};
use crate::plan::{Shard, Size, discover_images};
use crate::renderer::Renderer;
use uwnr_render::{Camera, DepthPolicy, JobWorker, ReferenceError};

/// What to generate.
#[derive(Clone, Debug)]
pub struct Spec {
    /// Clean images: files, or folders searched recursively.
    pub clean: Vec<PathBuf>,
    /// Real underwater references: files, or folders searched recursively.
    pub references: Vec<PathBuf>,
    /// Renders per clean image (K), each after a different reference.
    pub per_image: usize,
    /// Seed of the reference draw and of the methods' random parameters.
    pub seed: u64,
    /// Pair size.
    pub size: Size,
    /// Write `depth/`.
    pub save_depth: bool,
    /// Write `lightfield/`.
    pub save_lightfield: bool,
    /// Where depth comes from.
    pub depth: DepthSource,
    /// Maps beside the clean images, the scene scale per pair, the trust in the prior.
    pub depth_policy: DepthPolicy,
    /// Labels of the clean images, carried to every pair.
    pub labels: LabelInputs,
    /// The strengths to calibrate a water-anchored model's pairs to ([`crate::target`]);
    /// `None`: the bundled real pairs'. Refused for methods without a water.
    pub target: Option<WaterTarget>,
    /// The camera stage every underwater render goes through, whatever the method
    /// (`uwnr_render::camera`); [`Camera::NONE`] leaves renders as the method made them.
    pub camera: Camera,
}

/// Whether `renderer`'s pairs are calibrated to a target ([`Spec::target`]): a model whose
/// anchor is a water has its strength calibrated; any other method cannot be.
#[must_use]
pub fn calibrates(renderer: &Renderer) -> bool {
    renderer
        .generator_config()
        .is_some_and(|c| c.anchor == uwnr_model::AnchorKind::Water)
}

/// How to run it.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Render only this shard's pairs.
    pub shard: Option<Shard>,
    /// Worker threads.
    pub jobs: usize,
    /// Limits checked before decoding any image.
    pub limits: DecodeLimits,
    /// Write `preview.png` and `index.html` when an unsharded run completes.
    pub gallery: bool,
}

/// Progress of a run, reported on the calling thread.
#[derive(Debug)]
pub enum Event<'a> {
    /// The plan: pairs this run (shard) owns, how many were already done, how many to make.
    Start {
        planned: usize,
        done: usize,
        todo: usize,
    },
    /// A pair was completed.
    Pair(&'a Record),
    /// An item failed (the run goes on).
    Failed(&'a Failure),
    /// Something worth telling the user.
    Note(&'a str),
}

/// The outcome of a run.
#[derive(Debug, Default)]
pub struct Summary {
    /// Pairs this run (shard) owns.
    pub planned: usize,
    /// Pairs made by this run.
    pub rendered: usize,
    /// Pairs already complete from an earlier run.
    pub skipped: usize,
    /// What failed.
    pub failures: Vec<Failure>,
    /// Wall time in seconds.
    pub secs: f64,
    /// The run was stopped before the end.
    pub interrupted: bool,
    /// Every owned pair is in the manifest.
    pub complete: bool,
    /// PSNR(underwater, clean) over every pair in the manifest (this run's and earlier ones').
    pub strength: Option<StrengthSummary>,
    /// Annotations dropped under the label rules ([`crate::labels::rules`]) over every pair in
    /// the manifest, by reason.
    pub labels_dropped: crate::labels::DropCounts,
}

impl Summary {
    /// The run made every pair it owns, and nothing failed or stopped it: the exit code of the
    /// command follows this, and `verify` reports missing pairs exactly when `complete` is false
    /// and they are not listed as failed.
    #[must_use]
    pub fn ok(&self) -> bool {
        self.complete && self.failures.is_empty() && !self.interrupted
    }
}

enum Msg {
    Pair(Box<Record>),
    Failed(Failure),
}

/// Per-reference styles, each computed once; `Err` for unreadable references.
type RefCache = Vec<OnceLock<std::result::Result<Arc<ReferenceStyle>, ReferenceError>>>;

/// Generates (or finishes) the dataset in `out`.
///
/// Errors are for runs that cannot start (bad inputs, a folder made with other settings, an
/// unwritable folder); items that fail are listed in the summary and in the failure file.
pub fn generate(
    out: &Path,
    spec: &Spec,
    renderer: &Renderer,
    opts: &RunOptions,
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary> {
    let existed = out.exists();
    let result = generate_in(out, spec, renderer, opts, stop, observer);
    // A run that fails before making anything leaves no folder it created (a folder that
    // existed before is left as it was).
    if result.is_err() && !existed && !holds_pairs(out) {
        let _ = std::fs::remove_dir_all(out);
    }
    result
}

/// Whether `out` has a manifest with a line in it (this run made something worth keeping).
fn holds_pairs(out: &Path) -> bool {
    crate::manifest::metadata_files(out).is_ok_and(|(manifests, _)| {
        manifests
            .iter()
            .any(|m| std::fs::metadata(out.join(m)).is_ok_and(|md| md.len() > 0))
    })
}

fn generate_in(
    out: &Path,
    spec: &Spec,
    renderer: &Renderer,
    opts: &RunOptions,
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary> {
    let start = Instant::now();
    if spec.per_image == 0 {
        return Err(DatasetError::Invalid(
            "--per-image must be at least 1".into(),
        ));
    }
    spec.depth_policy
        .validate()
        .map_err(|e| DatasetError::Invalid(e.to_string()))?;
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let exclude = out.canonicalize().map_err(io_err(out))?;
    let cleans = discover_images(&spec.clean, "clean", Some(&exclude))?;
    if cleans.is_empty() {
        return Err(DatasetError::Invalid("no clean images given".into()));
    }
    let uses_refs = renderer.uses_reference() && !spec.references.is_empty();
    let refs = if uses_refs {
        discover_images(&spec.references, "reference", Some(&exclude))?
    } else {
        Vec::new()
    };
    if renderer.needs_reference() && refs.is_empty() {
        return Err(DatasetError::Invalid(format!(
            "--method {} needs --references (real underwater images)",
            renderer.name()
        )));
    }
    if !spec.references.is_empty() && !renderer.uses_reference() {
        observer(Event::Note(&format!(
            "note: --method {} with these settings uses no reference; --references is ignored",
            renderer.name()
        )));
    }
    let mut notes = Vec::new();
    let labels = Labels::prepare(
        &spec.labels,
        &cleans,
        &spec.clean,
        spec.per_image,
        &mut notes,
    )?;
    for n in &notes {
        observer(Event::Note(n));
    }
    let (settings_labels, settings_masks) = labels.settings();
    if !refs.is_empty() && spec.per_image > refs.len() {
        return Err(DatasetError::Invalid(format!(
            "--per-image {} draws that many different references per clean image, but only {} \
             references were given",
            spec.per_image,
            refs.len()
        )));
    }

    let calibration = match (&spec.target, calibrates(renderer)) {
        (Some(t), true) => Some(t.clone()),
        (None, true) => Some(WaterTarget::bundled()?),
        (Some(_), false) => {
            return Err(DatasetError::Invalid(format!(
                "--target calibrates the water of a model with a water anchor (the bundled \
                 model); --method {} with these weights has none",
                renderer.name()
            )));
        }
        (None, false) => None,
    };
    let settings = Settings {
        format: FORMAT.into(),
        method: renderer.name().into(),
        method_params: renderer
            .settings_params()
            .map_err(|e| DatasetError::Invalid(e.to_string()))?,
        depth_source: serde_json::to_value(&spec.depth)
            .map_err(|e| DatasetError::Invalid(format!("cannot record the depth source: {e}")))?,
        depth_policy: serde_json::to_value(spec.depth_policy)
            .map_err(|e| DatasetError::Invalid(format!("cannot record the depth policy: {e}")))?,
        per_image: spec.per_image,
        seed: spec.seed,
        size: spec.size,
        save_depth: spec.save_depth,
        save_lightfield: spec.save_lightfield,
        clean: cleans
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect(),
        references: refs
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect(),
        pairs_planned: cleans.len() * spec.per_image,
        labels: settings_labels,
        masks: settings_masks,
        target: calibration.as_ref().map(WaterTarget::record),
        camera: (!spec.camera.is_none()).then_some(spec.camera),
        strength: None,
        labels_dropped: None,
    };
    let mut label_changes = Vec::new();
    match Settings::read(out) {
        Ok(existing) => {
            let (existing, changed) =
                crate::labels::resume::split_image_fingerprints(&existing, &settings);
            label_changes = changed;
            if let Some((field, there, now)) = existing.first_difference(&settings)? {
                return Err(DatasetError::SettingsMismatch {
                    out: out.to_path_buf(),
                    field,
                    existing: there,
                    requested: now,
                });
            }
        }
        Err(DatasetError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
            settings.write(out)?;
        }
        Err(e) => return Err(e),
    }
    let mut dirs = vec![UNDERWATER_DIR, CLEAN_DIR];
    if spec.save_depth {
        dirs.push(DEPTH_DIR);
    }
    if spec.save_lightfield {
        dirs.push(LIGHTFIELD_DIR);
    }
    if settings.labels.is_some() {
        dirs.push(LABELS_DIR);
    }
    if settings.masks.is_some() {
        dirs.push(MASKS_DIR);
    }
    for d in &dirs {
        let p = out.join(d);
        std::fs::create_dir_all(&p).map_err(io_err(&p))?;
    }

    // What is done already.
    let planned = settings.planned_pairs(opts.shard);
    let by_id: HashMap<&str, &crate::manifest::PlannedPair> =
        planned.iter().map(|p| (p.id.as_str(), p)).collect();
    let manifest_path = out.join(manifest_name(opts.shard));
    let existing = read_manifest(&manifest_path)?;
    existing.refuse_unsafe_paths(&manifest_path)?;
    let wants = resume::PairFiles {
        depth: spec.save_depth,
        lightfield: spec.save_lightfield,
        labels: settings.labels.is_some(),
        mask: settings.masks.is_some(),
    };
    let (mut kept, mut done, dropped) = resume::kept_pairs(out, existing, &by_id, wants);
    // Labels changed since the last run: fine for images none of whose pairs is made (their
    // pairs failed: the fix lets them be made), refused for the others, naming the file.
    if !label_changes.is_empty() {
        if let Some((r, i)) = kept.iter().find_map(|r| {
            let i = by_id.get(r.id.as_str())?.clean_index;
            label_changes.binary_search(&i).is_ok().then_some((r, i))
        }) {
            return Err(DatasetError::Invalid(format!(
                "{}: the labels of {} differ from those pair {} of {} was made with: restore \
                 them, or make the dataset in another output folder",
                labels.files_of(i).join(", "),
                cleans[i].display(),
                r.id,
                out.display()
            )));
        }
        observer(Event::Note(&format!(
            "note: the labels of {} clean image(s) changed since the last run (none of their \
             pairs was made): their pairs are made with the new labels",
            label_changes.len()
        )));
        settings.write(out)?;
    }
    if dropped > 0 {
        observer(Event::Note(&format!(
            "note: {dropped} manifest line(s) were torn, unreadable or pointed at missing files; \
             those pairs are made again"
        )));
        write_manifest(&manifest_path, &mut kept)?;
    }
    remove_stale_temps(out, &dirs, &by_id, opts.shard.is_none())?;

    // The work: every clean image with a pair still to make.
    let mut todo: Vec<(usize, Vec<usize>)> = Vec::new();
    for p in &planned {
        if done.contains(&p.id) {
            continue;
        }
        match todo.last_mut() {
            Some((i, ks)) if *i == p.clean_index => ks.push(p.k),
            _ => todo.push((p.clean_index, vec![p.k])),
        }
    }
    let todo_pairs: usize = todo.iter().map(|(_, ks)| ks.len()).sum();
    observer(Event::Start {
        planned: planned.len(),
        done: done.len(),
        todo: todo_pairs,
    });

    let prepared = spec
        .depth
        .prepare()
        .map_err(|e| DatasetError::Invalid(format!("preparing the depth source: {e}")))?;
    // Measured depth beside the clean images, where the prior would otherwise guess.
    let beside = if spec.depth_policy.beside && spec.depth == DepthSource::Builtin {
        uwnr_depth::beside_maps(&cleans)
            .map_err(|e| DatasetError::Invalid(format!("finding depth maps: {e}")))?
    } else {
        vec![None; cleans.len()]
    };
    let with_maps = beside.iter().filter(|m| m.is_some()).count();
    if with_maps > 0 {
        observer(Event::Note(&format!(
            "{with_maps} of {} clean images have a depth map beside them (depth/ next to rgb/), \
             read as {}",
            cleans.len(),
            spec.depth_policy.unit
        )));
    }
    let names = settings.names();
    let ctx = Context {
        out,
        method: renderer.name(),
        renderer,
        spec,
        cleans: &cleans,
        names: &names,
        refs: &refs,
        ref_cache: (0..refs.len()).map(|_| OnceLock::new()).collect(),
        depth: &prepared,
        beside: &beside,
        labels: &labels,
        calibration: calibration.as_ref(),
        limits: &opts.limits,
        stop,
    };

    let mut summary = Summary {
        planned: planned.len(),
        skipped: done.len(),
        ..Summary::default()
    };
    let mut writer = ManifestWriter::open(&manifest_path)?;
    let mut write_error: Option<DatasetError> = None;
    let next = AtomicUsize::new(0);
    let jobs = opts.jobs.max(1);
    std::thread::scope(|scope| {
        let (tx, rx) = sync_channel::<Msg>(2 * jobs);
        for _ in 0..jobs {
            let tx = tx.clone();
            let (ctx, todo, next) = (&ctx, &todo, &next);
            scope.spawn(move || {
                let worker = JobWorker::new(renderer.worker(), &spec.depth_policy);
                loop {
                    if ctx.stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let t = next.fetch_add(1, Ordering::Relaxed);
                    let Some((i, ks)) = todo.get(t) else { break };
                    if !ctx.make_clean(&worker, *i, ks, &tx) {
                        break;
                    }
                }
            });
        }
        drop(tx);
        for msg in rx {
            match msg {
                Msg::Pair(r) => {
                    if write_error.is_none() {
                        if let Err(e) = writer.append(&r) {
                            // The manifest cannot grow: stop; everything recorded so far holds.
                            ctx.stop.store(true, Ordering::Relaxed);
                            write_error = Some(e);
                            continue;
                        }
                        done.insert(r.id.clone());
                        summary.rendered += 1;
                        observer(Event::Pair(&r));
                        kept.push(*r);
                    }
                }
                Msg::Failed(f) => {
                    observer(Event::Failed(&f));
                    summary.failures.push(f);
                }
            }
        }
    });
    if let Some(e) = write_error {
        return Err(e);
    }
    writer.sync()?;
    summary.interrupted = stop.load(Ordering::Relaxed);
    summary.complete = planned.iter().all(|p| done.contains(&p.id));
    summary.failures.sort_by(|a, b| a.source.cmp(&b.source));
    if !summary.interrupted {
        write_failures(&out.join(failed_name(opts.shard)), &summary.failures)?;
    }
    // What the pairs measured: their strength and the annotations their labels dropped.
    let mut measured = settings.finished(&kept, true);
    summary.strength.clone_from(&measured.strength);
    summary.labels_dropped = measured.labels_dropped.clone().unwrap_or_default();
    if !summary.interrupted {
        // Put the manifest in pair order, so the folder is the same whatever the job count.
        write_manifest(&manifest_path, &mut kept)?;
        if opts.shard.is_none() && (summary.complete || settings.labels.is_some()) {
            // The strength of the finished folder and the annotations its labels dropped, kept
            // beside its settings (not compared on resume).
            if !summary.complete {
                measured.strength = None;
            }
            measured.write(out)?;
        }
        if opts.shard.is_none() {
            crate::labels::write_coco(out, settings.labels.as_ref(), &kept)?;
        }
        if opts.shard.is_none() && opts.gallery && summary.complete {
            crate::gallery::write(out, &kept)?;
        }
    }
    summary.secs = start.elapsed().as_secs_f64();
    Ok(summary)
}

/// The clean image as the pair holds it: fitted to the pair size (cover and centre-crop for a
/// fixed size) and quantised to 8 bits, so what is rendered is exactly what `clean/` stores.
pub fn fit(img: &Image, size: Size) -> uwnr_core::Result<Image> {
    Ok(fit_geometry(img, size)?.quantised())
}

/// [`fit`] without the quantisation (depth maps): the image through its [`Fit`].
pub fn fit_geometry(img: &Image, size: Size) -> uwnr_core::Result<Image> {
    let f = Fit::new(img.size(), size);
    if f.is_identity() {
        return Ok(img.clone());
    }
    let scaled = if (f.scaled_width, f.scaled_height) == img.size() {
        img.clone()
    } else {
        resize_bilinear(img, f.scaled_width, f.scaled_height)?
    };
    scaled.crop(f.x0, f.y0, f.width, f.height)
}

#[cfg(test)]
mod tests;
