//! The experiment's stages: render, train, score, report.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::tensor::Device;
use serde::{Deserialize, Serialize};
use serde_json::json;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, write_atomic};
use uwnr_core::resize::fit_within;
use uwnr_dataset::{Renderer, RunOptions, Size, Spec};
use uwnr_depth::DepthSource;
use uwnr_enhance::eval::{EvalReport, evaluate_dir};
use uwnr_enhance::train::{EnhanceTrainConfig, EnhanceTrainOptions, train};
use uwnr_enhance::{ShallowUwnet, enhance};
use uwnr_run::pairs::discover_pairs;

use crate::error::{ExperimentError, Result};
use crate::report::{Results, Row, RowKind, Scores, TestSet, write_markdown};

/// Settings of the experiment, recorded in `OUT/experiment.json`.
pub const SETTINGS_FILE: &str = "experiment.json";
/// The table.
pub const RESULTS_MD: &str = "results.md";
/// Everything measured.
pub const RESULTS_JSON: &str = "results.json";
/// Example enhancements: per test image, the input, each network's output and the reference.
pub const EXAMPLES_PNG: &str = "examples.png";
/// Height of the thumbnails of `examples.png`.
pub const EXAMPLE_THUMB: usize = 160;
/// The learning rate is multiplied by the config's `lr_decay` every `ceil(epochs / (this + 1))`
/// epochs, so at most this many times over a run (fewer when the epochs do not divide: 6 epochs
/// decay at epochs 2 and 4). The released recipe decays in steps too, every `step_size` epochs.
pub const LR_DECAYS_PER_RUN: usize = 3;

/// A synthetic training set: the method that renders it.
pub struct TrainingSet {
    /// Short name (`uwnr`, `jerlov`, ...), used for folders and the table.
    pub name: String,
    /// What renders it.
    pub renderer: Renderer,
}

/// What to run.
pub struct DownstreamSpec {
    /// Clean images: files or folders (searched recursively).
    pub clean: Vec<PathBuf>,
    /// Real underwater references: files or folders.
    pub references: Vec<PathBuf>,
    /// Real paired test sets (`underwater/` + `clean/`).
    pub tests: Vec<PathBuf>,
    /// Real paired training sets, trained on as reference rows.
    pub real: Vec<PathBuf>,
    /// Output folder.
    pub out: PathBuf,
    /// Renders per clean image (each after a different reference).
    pub per_image: usize,
    /// Size of the synthetic pairs.
    pub size: Size,
    /// Seed of the reference draw, of the methods' parameters and of training.
    pub seed: u64,
    /// Depth of the clean images.
    pub depth: DepthSource,
    /// Maps beside the clean images, scene scales, trust in the prior.
    pub depth_policy: uwnr_render::DepthPolicy,
    /// Enhancer training (its `epochs` is set per training set from `budget`, its learning-rate
    /// steps from [`LR_DECAYS_PER_RUN`], its seed from `seed`).
    pub train: EnhanceTrainConfig,
    /// Training samples each network sees (the same for every row).
    pub budget: usize,
    /// Test images whose longer side is larger are downscaled to it before scoring.
    pub eval_max_side: Option<usize>,
    /// Example test images per test set in `examples.png`.
    pub examples: usize,
    /// Rendering threads.
    pub jobs: usize,
    /// Device of the enhancer.
    pub device: Device,
    /// VGG19 weights for the enhancer's perceptual term.
    pub vgg19: Option<PathBuf>,
    /// Image decoding limits.
    pub limits: DecodeLimits,
    /// The strengths a water-anchored model's pairs are calibrated to (`uwnr dataset
    /// --target`); the other methods' sets are made without it.
    pub target: Option<uwnr_dataset::WaterTarget>,
    /// The camera stage every method's renders go through (`uwnr dataset --camera`).
    pub camera: uwnr_render::Camera,
}

/// Progress, reported on the calling thread.
pub enum Event<'a> {
    /// A stage starts.
    Stage(&'a str),
    /// Progress of a training set's rendering.
    Dataset(&'a str, uwnr_dataset::Event<'a>),
    /// Progress of a training run.
    Train(&'a str, uwnr_run::Event<'a>),
    /// A row was scored on a test set.
    Scored {
        /// The row.
        row: &'a str,
        /// The test set.
        test: &'a str,
        /// Its scores.
        scores: &'a Scores,
        /// They were read from an earlier session.
        cached: bool,
    },
}

/// Time spent on a row, summed over sessions (`OUT/state/ROW.json`).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
struct Timing {
    dataset_secs: f64,
    train_secs: f64,
    eval_secs: f64,
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<Option<T>> {
    match std::fs::read_to_string(path) {
        Ok(text) => serde_json::from_str(&text).map(Some).map_err(|e| {
            ExperimentError::Invalid(format!("{}: {e}; delete it to recompute", path.display()))
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(ExperimentError::io(path, e)),
    }
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| ExperimentError::Invalid(format!("serialising {}: {e}", path.display())))?;
    write_text(path, &(text + "\n"))
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| ExperimentError::io(dir, e))?;
    }
    Ok(write_atomic(path, |w| w.write_all(text.as_bytes()))?)
}

fn paths(p: &[PathBuf]) -> Vec<String> {
    p.iter().map(|p| p.display().to_string()).collect()
}

/// Folder-safe, unique short names: the last path component, with `-2`, `-3` for repeats.
fn short_names(dirs: &[PathBuf]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for d in dirs {
        let base = d
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .filter(|n| !n.is_empty() && n != "." && n != "..")
            .unwrap_or_else(|| "set".into());
        let mut name = base.clone();
        let mut k = 2;
        while names.contains(&name) {
            name = format!("{base}-{k}");
            k += 1;
        }
        names.push(name);
    }
    names
}

/// The settings recorded in `experiment.json`: a re-run must match them.
fn settings(spec: &DownstreamSpec, sets: &[TrainingSet]) -> Result<serde_json::Value> {
    let methods = sets
        .iter()
        .map(|s| {
            let params = s
                .renderer
                .settings_params()
                .map_err(|e| ExperimentError::Invalid(format!("{}: {e}", s.name)))?;
            Ok(json!({ "name": s.name, "params": params }))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut settings = json!({
        "clean": paths(&spec.clean),
        "references": paths(&spec.references),
        "tests": paths(&spec.tests),
        "real": paths(&spec.real),
        "methods": methods,
        "per_image": spec.per_image,
        "size": spec.size.to_string(),
        "seed": spec.seed,
        "depth": spec.depth,
        "train": spec.train,
        "budget": spec.budget,
        "eval_max_side": spec.eval_max_side,
        "vgg19": spec.vgg19.as_ref().map(|p| p.display().to_string()),
    });
    // Only when set, so that folders made before the field existed still resume.
    if let Some(t) = &spec.target {
        settings["target"] =
            json!({ "kind": t.kind, "source": t.source, "entries": t.entries.len() });
    }
    Ok(settings)
}

/// Checks the output folder's recorded settings against this run's (or records them).
fn check_settings(out: &Path, settings: &serde_json::Value) -> Result<()> {
    let path = out.join(SETTINGS_FILE);
    match read_json::<serde_json::Value>(&path)? {
        None => write_json(&path, settings),
        Some(old) if &old == settings => Ok(()),
        Some(old) => {
            let field = settings
                .as_object()
                .and_then(|now| {
                    now.iter()
                        .find(|(k, v)| old.get(k.as_str()) != Some(v))
                        .map(|(k, _)| k.clone())
                })
                .unwrap_or_else(|| "a field".into());
            Err(ExperimentError::SettingsDiffer {
                out: out.to_path_buf(),
                field,
            })
        }
    }
}

/// The training config of one row: `budget` samples, i.e. `budget / batch` steps (the last epoch
/// partial), the learning rate decayed in steps of epochs (see [`LR_DECAYS_PER_RUN`]).
fn row_config(spec: &DownstreamSpec, pairs: usize) -> EnhanceTrainConfig {
    let mut cfg = spec.train.clone();
    let batch = cfg.batch_size.max(1);
    let steps = spec.budget.div_ceil(batch).max(1);
    let steps_per_epoch = (pairs / batch).max(1);
    cfg.epochs = steps.div_ceil(steps_per_epoch);
    cfg.total_steps = Some(steps);
    cfg.lr_step_epochs = cfg.epochs.div_ceil(LR_DECAYS_PER_RUN + 1).max(1);
    cfg.run.seed = spec.seed;
    cfg
}

fn enhance_err(name: &str) -> impl Fn(uwnr_enhance::EnhanceError) -> ExperimentError + '_ {
    move |source| ExperimentError::Enhance {
        name: name.to_string(),
        source,
    }
}

fn pair_count(dir: &Path) -> Result<usize> {
    discover_pairs(dir, None)
        .map(|p| p.pairs.len())
        .map_err(|e| ExperimentError::Invalid(format!("{}: {e}", dir.display())))
}

/// Trains (or finishes training) the enhancer of one row; returns its weights and steps.
fn train_row(
    spec: &DownstreamSpec,
    name: &str,
    data: &Path,
    pairs: usize,
    stop: &AtomicBool,
    timing: &mut Timing,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<(PathBuf, usize)> {
    let cfg = row_config(spec, pairs);
    let mut opts = EnhanceTrainOptions::new(
        vec![data.to_path_buf()],
        spec.out.join("runs").join(name),
        spec.device.clone(),
    );
    // A row killed before its first checkpoint left a folder that holds no run: it starts again.
    opts.resume = uwnr_run::folder::holds_run(&opts.run_dir);
    opts.vgg19.clone_from(&spec.vgg19);
    opts.limits = spec.limits;
    let summary = train(&cfg, &opts, stop, &mut |e| observer(Event::Train(name, e)))
        .map_err(enhance_err(name))?;
    // The trainer's own count: the time behind the checkpoint, over every session that added to
    // it (a session stopped between checkpoints loses its last steps, and their time with them).
    timing.train_secs = summary.train_secs;
    if summary.interrupted || !summary.finished {
        return Err(ExperimentError::Stopped);
    }
    Ok((summary.last_weights, summary.step))
}

/// Scores `net` (or the input, for `None`) on every test set, each score cached in
/// `OUT/eval/ROW/TEST.json`.
#[allow(clippy::too_many_arguments)]
fn score_row(
    spec: &DownstreamSpec,
    name: &str,
    net: Option<&ShallowUwnet>,
    tests: &[TestSet],
    stop: &AtomicBool,
    timing: &mut Timing,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Vec<Scores>> {
    let mut all = Vec::with_capacity(tests.len());
    for (t, dir) in tests.iter().zip(&spec.tests) {
        if stop.load(Ordering::SeqCst) {
            return Err(ExperimentError::Stopped);
        }
        let cache = spec
            .out
            .join("eval")
            .join(name)
            .join(format!("{}.json", t.name));
        let (scores, cached) = match read_json::<Scores>(&cache)? {
            Some(s) => (s, true),
            None => {
                let start = Instant::now();
                let report: EvalReport = evaluate_dir(
                    net,
                    dir,
                    &spec.device,
                    None,
                    spec.eval_max_side,
                    &spec.limits,
                )
                .map_err(enhance_err(name))?;
                timing.eval_secs += start.elapsed().as_secs_f64();
                let s = Scores {
                    images: report.per_image.len(),
                    psnr: report.psnr,
                    ssim: report.ssim,
                    uiqm: report.uiqm,
                    uciqe: report.uciqe,
                };
                write_json(&cache, &s)?;
                (s, false)
            }
        };
        observer(Event::Scored {
            row: name,
            test: &t.name,
            scores: &scores,
            cached,
        });
        all.push(scores);
    }
    Ok(all)
}

/// `image` downscaled so its longer side is at most `max_side` (aspect kept).
fn fit_side(image: Image, max_side: Option<usize>) -> Result<Image> {
    match max_side {
        Some(m) if image.width().max(image.height()) > m => Ok(fit_within(&image, m)?),
        _ => Ok(image),
    }
}

/// `examples.png`: for the first test images of each set, the input, every trained network's
/// output and the clean reference, left to right in table order, under column headers naming
/// the training set of each network; each row is labelled with its test set and image.
fn examples_sheet(
    spec: &DownstreamSpec,
    nets: &[(String, ShallowUwnet)],
    path: &Path,
) -> Result<()> {
    let mut rows: Vec<(String, Vec<Image>)> = Vec::new();
    for (dir, set) in spec.tests.iter().zip(short_names(&spec.tests)) {
        let pairs = discover_pairs(dir, Some(spec.examples))
            .map_err(|e| ExperimentError::Invalid(format!("{}: {e}", dir.display())))?;
        for p in &pairs.pairs {
            let input = fit_side(load_rgb(&p.underwater, &spec.limits)?, spec.eval_max_side)?;
            let clean = fit_side(load_rgb(&p.clean, &spec.limits)?, spec.eval_max_side)?;
            let mut row = vec![input.clone()];
            for (name, net) in nets {
                row.push(enhance(net, &input, &spec.device).map_err(enhance_err(name))?);
            }
            row.push(clean);
            rows.push((format!("{set}: {}", p.name), row));
        }
    }
    if rows.is_empty() {
        return Ok(());
    }
    let columns: Vec<String> = std::iter::once("input (underwater)".to_string())
        .chain(nets.iter().map(|(name, _)| format!("trained on {name}")))
        .chain(std::iter::once("clean reference".to_string()))
        .collect();
    let sheet = uwnr_figures::Sheet {
        title: Some("Shallow-UWnet outputs on the test images".into()),
        columns,
        rows: rows
            .iter()
            .map(|(label, images)| uwnr_figures::SheetRow {
                label: Some(label.clone()),
                images: images.iter().collect(),
            })
            .collect(),
        thumb: EXAMPLE_THUMB,
    };
    let img = uwnr_figures::draw_sheet(&sheet).map_err(|source| ExperimentError::Figure {
        what: EXAMPLES_PNG,
        source,
    })?;
    Ok(uwnr_core::io::save_rgb(path, &img)?)
}

fn validate(spec: &DownstreamSpec, sets: &[TrainingSet]) -> Result<()> {
    if spec.tests.is_empty() {
        return Err(ExperimentError::Invalid(
            "no test sets: give at least one --test folder of real pairs".into(),
        ));
    }
    if sets.is_empty() && spec.real.is_empty() {
        return Err(ExperimentError::Invalid(
            "nothing to train: give at least one method or --real folder".into(),
        ));
    }
    if !sets.is_empty() && spec.clean.is_empty() {
        return Err(ExperimentError::Invalid(
            "the methods need clean images: give --clean".into(),
        ));
    }
    if spec.budget == 0 {
        return Err(ExperimentError::Invalid(
            "the training budget must be at least one sample".into(),
        ));
    }
    let mut names: Vec<&str> = sets.iter().map(|s| s.name.as_str()).collect();
    names.sort_unstable();
    if names.windows(2).any(|w| w[0] == w[1]) {
        return Err(ExperimentError::Invalid("a method is listed twice".into()));
    }
    let mut cfg = spec.train.clone();
    cfg.epochs = cfg.epochs.max(1);
    cfg.validate().map_err(enhance_err("training config"))
}

/// Runs (or finishes) the experiment and writes `results.json`, `results.md` and
/// `examples.png` into `spec.out`. `stop` ends it at the next safe point with
/// [`ExperimentError::Stopped`]; running it again continues.
pub fn run_downstream(
    spec: &DownstreamSpec,
    sets: &[TrainingSet],
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Results> {
    validate(spec, sets)?;
    std::fs::create_dir_all(&spec.out).map_err(|e| ExperimentError::io(&spec.out, e))?;
    let settings = settings(spec, sets)?;
    check_settings(&spec.out, &settings)?;

    let test_names = short_names(&spec.tests);
    let tests = test_names
        .iter()
        .zip(&spec.tests)
        .map(|(name, dir)| {
            Ok(TestSet {
                name: name.clone(),
                path: dir.display().to_string(),
                pairs: pair_count(dir)?,
            })
        })
        .collect::<Result<Vec<_>>>()?;

    let timing_path = |name: &str| spec.out.join("state").join(format!("{name}.json"));
    let mut rows = Vec::new();
    let mut nets: Vec<(String, ShallowUwnet)> = Vec::new();

    observer(Event::Stage("scoring the unenhanced test images"));
    let mut timing: Timing = read_json(&timing_path("none"))?.unwrap_or_default();
    let scores = score_row(spec, "none", None, &tests, stop, &mut timing, observer);
    write_json(&timing_path("none"), &timing)?;
    rows.push(Row {
        name: "none".into(),
        kind: RowKind::NoEnhancement,
        train_pairs: None,
        failed_pairs: None,
        train_steps: None,
        dataset_secs: 0.0,
        train_secs: 0.0,
        eval_secs: timing.eval_secs,
        scores: scores?,
    });

    let dataset_spec = Spec {
        clean: spec.clean.clone(),
        references: spec.references.clone(),
        per_image: spec.per_image,
        seed: spec.seed,
        size: spec.size,
        save_depth: false,
        save_lightfield: false,
        depth: spec.depth.clone(),
        depth_policy: spec.depth_policy,
        labels: uwnr_dataset::LabelInputs::default(),
        target: None,
        camera: spec.camera,
    };
    let real_names: Vec<String> = short_names(&spec.real)
        .into_iter()
        .map(|n| format!("real:{n}"))
        .collect();
    let jobs: Vec<(String, Option<&Renderer>, PathBuf)> = sets
        .iter()
        .map(|s| {
            (
                s.name.clone(),
                Some(&s.renderer),
                spec.out.join("data").join(&s.name),
            )
        })
        .chain(
            real_names
                .iter()
                .zip(&spec.real)
                .map(|(n, d)| (n.clone(), None, d.clone())),
        )
        .collect();

    for (name, renderer, data) in &jobs {
        let folder = name.replace(':', "-");
        let mut timing: Timing = read_json(&timing_path(&folder))?.unwrap_or_default();
        let mut failed_pairs = None;
        if let Some(renderer) = renderer {
            observer(Event::Stage(&format!("rendering the {name} training set")));
            let start = Instant::now();
            let set_spec = Spec {
                target: if uwnr_dataset::calibrates(renderer) {
                    spec.target.clone()
                } else {
                    None
                },
                ..dataset_spec.clone()
            };
            let summary = uwnr_dataset::generate(
                data,
                &set_spec,
                renderer,
                &RunOptions {
                    shard: None,
                    jobs: spec.jobs,
                    limits: spec.limits,
                    gallery: true,
                },
                stop,
                &mut |e| observer(Event::Dataset(name, e)),
            );
            // Time counts only when this session rendered something: checking a finished set
            // again is not rendering (and would make a resumed table differ from the first).
            if !summary.as_ref().is_ok_and(|s| s.rendered == 0) {
                timing.dataset_secs += start.elapsed().as_secs_f64();
                write_json(&timing_path(&folder), &timing)?;
            }
            let summary = summary.map_err(|source| ExperimentError::Dataset {
                name: name.clone(),
                source,
            })?;
            if summary.interrupted {
                return Err(ExperimentError::Stopped);
            }
            let made = pair_count(data)?;
            failed_pairs = Some(summary.planned.saturating_sub(made));
        }
        let pairs = pair_count(data)?;
        observer(Event::Stage(&format!(
            "training Shallow-UWnet on {name} ({pairs} pairs)"
        )));
        let trained = train_row(spec, &folder, data, pairs, stop, &mut timing, observer);
        write_json(&timing_path(&folder), &timing)?;
        let (weights, steps) = trained?;
        let (net, _) =
            uwnr_enhance::weights::load(&weights, &spec.device).map_err(enhance_err(name))?;
        observer(Event::Stage(&format!("scoring {name}")));
        let scores = score_row(
            spec,
            &folder,
            Some(&net),
            &tests,
            stop,
            &mut timing,
            observer,
        );
        write_json(&timing_path(&folder), &timing)?;
        rows.push(Row {
            name: name.clone(),
            kind: if renderer.is_some() {
                RowKind::Synthetic
            } else {
                RowKind::Real
            },
            train_pairs: Some(pairs),
            failed_pairs,
            train_steps: Some(steps),
            dataset_secs: timing.dataset_secs,
            train_secs: timing.train_secs,
            eval_secs: timing.eval_secs,
            scores: scores?,
        });
        nets.push((name.clone(), net));
    }

    let results = Results {
        settings,
        enhancer_params: spec.train.model.param_count(),
        tests,
        rows,
    };
    observer(Event::Stage("writing the results"));
    if spec.examples > 0 {
        examples_sheet(spec, &nets, &spec.out.join(EXAMPLES_PNG))?;
    }
    write_json(&spec.out.join(RESULTS_JSON), &results)?;
    let preamble = format!(
        "Shallow-UWnet ({} parameters) trained on each training set for {} samples (seed {}), \
         scored on real paired test sets: PSNR and SSIM against the clean reference, UIQM and \
         UCIQE of the output alone (higher is better for all four; bold = best in its column). \
         Example enhancements: `{EXAMPLES_PNG}` (input, one column per trained network in table \
         order, reference).",
        results.enhancer_params, spec.budget, spec.seed
    );
    let md = write_markdown(&results, "Downstream experiment", &preamble);
    write_text(&spec.out.join(RESULTS_MD), &md)?;
    Ok(results)
}

#[cfg(test)]
mod tests;
