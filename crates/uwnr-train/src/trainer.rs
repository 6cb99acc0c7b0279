//! The training loop (released `train_ddp.py`, rewritten): batches from the loader thread,
//! forward, the weighted loss, backward, an AdamW step at the scheduled learning rate; logs,
//! validation, checkpoints, curves; exact resume; a clean stop on request.
//!
//! Run folder layout:
//! ```text
//! config.json          the TrainConfig of the run
//! data-report.txt      pairs used, files skipped, images upscaled/padded/resized
//! metrics.csv          step, epoch, lr, each loss term, total (mean over log_every_steps)
//! val.csv              step, epoch, PSNR, SSIM on the validation pairs
//! curves.png           loss terms (log) and validation PSNR against the step
//! val/step-NNNNNNN.png contact sheets: clean | render | real underwater
//! checkpoints/last/    model + optimiser + state (resume from here)
//! checkpoints/best/    the generator with the best validation PSNR
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::module::Module;
use burn::optim::{AdamWConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use uwnr_core::io::DecodeLimits;
use uwnr_model::style::{estimate_water, finish_tensor};
use uwnr_model::{Backend, Generator, Network, ReferenceStyle, RenderOptions, Variant};

use crate::augment::{TARGET_CHANNELS, WATER_VALUES};
use crate::checkpoint::{
    BEST, CHECKPOINTS_DIR, LAST, RunState, check_run_folder, find_checkpoint, load_checkpoint,
    save_checkpoint,
};
use crate::config::TrainConfig;
use crate::csvlog::{CsvLog, METRICS_HEADER, VAL_HEADER};
use crate::data::{LoadOptions, TrainData, ValPair, load_data};
use crate::error::{Result, TrainError};
use crate::loader::{Batch, BatchSpec, Loader};
use crate::losses::{Criterion, LossValues, read_terms};
use crate::plot::{contact_sheet, draw_curves};
use crate::vgg::Vgg19Features;
use uwnr_core::lightfield;

/// Name of the config file in the run folder.
pub const CONFIG_FILE: &str = "config.json";
/// Name of the data report in the run folder.
pub const DATA_REPORT_FILE: &str = "data-report.txt";
/// Name of the loss log.
pub const METRICS_FILE: &str = "metrics.csv";
/// Name of the validation log.
pub const VAL_FILE: &str = "val.csv";
/// Name of the curve picture.
pub const CURVES_FILE: &str = "curves.png";
/// Folder of the contact sheets.
pub const VAL_DIR: &str = "val";
/// Height of a contact-sheet thumbnail.
const SHEET_THUMB: usize = 192;

/// Where and how to train (what is not part of the run's config).
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// Training data folders (`underwater/` + `clean/`, optional `depth/`).
    pub data: Vec<PathBuf>,
    /// Validation data folder (same layout), scored at native resolution.
    pub val: Option<PathBuf>,
    /// The run folder.
    pub run_dir: PathBuf,
    /// Continue the run in `run_dir` from its last checkpoint.
    pub resume: bool,
    /// VGG19 weights (safetensors, torchvision keys) for the perceptual term.
    pub vgg19: Option<PathBuf>,
    /// Compute device (without autodiff; training enables it).
    pub device: Device,
    /// Stop (with a checkpoint) after this many steps in this session.
    pub max_steps: Option<usize>,
    /// PSNR reference lines drawn on the validation curve (e.g. baselines).
    pub val_refs: Vec<f64>,
    /// Image decoding limits.
    pub limits: DecodeLimits,
}

impl TrainOptions {
    /// Options with defaults for everything but the data and the run folder.
    #[must_use]
    pub fn new(data: Vec<PathBuf>, run_dir: PathBuf, device: Device) -> Self {
        Self {
            data,
            val: None,
            run_dir,
            resume: false,
            vgg19: None,
            device,
            max_steps: None,
            val_refs: Vec::new(),
            limits: DecodeLimits::default(),
        }
    }
}

/// Validation scores of one evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct ValResult {
    /// Steps done when it ran.
    pub step: usize,
    /// Epochs done.
    pub epoch: usize,
    /// Mean PSNR (dB) over the pairs.
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// `(name, psnr, ssim)` per pair.
    pub per_pair: Vec<(String, f64, f64)>,
    /// Seconds it took.
    pub secs: f64,
}

/// What the loop reports as it goes.
#[derive(Debug)]
pub enum Event<'a> {
    /// Something worth telling the user (set-up, warnings).
    Message(&'a str),
    /// Training starts at `step` of `total_steps`.
    Started {
        /// Steps already done.
        step: usize,
        /// Steps of the whole run.
        total_steps: usize,
        /// Steps per epoch.
        steps_per_epoch: usize,
    },
    /// A step finished.
    Step {
        /// Steps done.
        step: usize,
        /// Epoch of the step.
        epoch: usize,
        /// Learning rate used.
        lr: f64,
        /// Its losses.
        loss: &'a LossValues,
    },
    /// A validation finished.
    Validation(&'a ValResult),
    /// A checkpoint was written.
    Checkpoint {
        /// Steps done.
        step: usize,
        /// Its folder.
        path: &'a Path,
    },
}

/// How a session ended.
#[derive(Clone, Debug)]
pub struct TrainSummary {
    /// Steps done in total.
    pub step: usize,
    /// Steps done in this session.
    pub session_steps: usize,
    /// `(step, losses)` of every step of this session.
    pub losses: Vec<(usize, LossValues)>,
    /// The run reached its last epoch.
    pub finished: bool,
    /// The stop flag ended the session.
    pub interrupted: bool,
    /// Best validation PSNR and its step.
    pub best: Option<(f64, usize)>,
    /// The last validation of this session.
    pub last_val: Option<ValResult>,
}

/// Trains (or resumes) the run of `opts.run_dir` with `cfg`. `stop` ends the session cleanly
/// (checkpoint written) at the next step boundary; `observer` receives progress events.
pub fn train(
    cfg: &TrainConfig,
    opts: &TrainOptions,
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<TrainSummary> {
    cfg.validate()?;
    let run = &opts.run_dir;
    check_run_folder(run, opts.resume)?;
    if opts.resume {
        check_saved_config(cfg, run)?;
    }

    let data = load_data(
        &opts.data,
        opts.val.as_deref(),
        &LoadOptions {
            crop: cfg.crop,
            small_images: cfg.small_images,
            depth: cfg.depth.clone(),
            max_pairs_per_dir: cfg.max_pairs_per_dir,
            limits: opts.limits,
        },
    )?;
    let TrainData { pairs, val, report } = data;
    // Shown before anything is checked, so a refused start still lists what was skipped.
    let report = report.to_text();
    observer(Event::Message(report.trim_end()));
    let steps_per_epoch = pairs.len() / cfg.batch_size;
    if steps_per_epoch == 0 {
        return Err(TrainError::NoData(format!(
            "{} training pairs, fewer than one batch of {}",
            pairs.len(),
            cfg.batch_size
        )));
    }
    // The data has loaded: only now is the folder claimed.
    if !opts.resume {
        claim_run_folder(run, &cfg.to_json()?)?;
    }
    write_file(&run.join(DATA_REPORT_FILE), &report)?;
    let total_steps = cfg.epochs * steps_per_epoch;
    let val_lf: Vec<ReferenceStyle> = val
        .iter()
        .map(|v| -> Result<ReferenceStyle> {
            let light_field = lightfield::light_field_for_with(
                &v.underwater,
                v.clean.width(),
                v.clean.height(),
                cfg.model.light_field,
            )?;
            let water = match cfg.model.variant {
                Variant::Paper => None,
                Variant::Anchored => Some(estimate_water(&v.underwater)?),
            };
            Ok(ReferenceStyle { light_field, water })
        })
        .collect::<Result<_>>()?;

    let device = opts.device.clone().autodiff();
    let adamw = AdamWConfig::new()
        .with_beta_1(cfg.betas.0)
        .with_beta_2(cfg.betas.1)
        .with_epsilon(cfg.epsilon)
        .with_weight_decay(cfg.weight_decay);
    let ck_last = run.join(CHECKPOINTS_DIR).join(LAST);
    let ck_best = run.join(CHECKPOINTS_DIR).join(BEST);
    let (mut model, mut optim, mut state) = if opts.resume {
        let dir = find_checkpoint(&ck_last).ok_or_else(|| TrainError::Checkpoint {
            path: ck_last.clone(),
            reason: "no checkpoint to resume from".into(),
        })?;
        let (m, o, s) = load_checkpoint(&dir, &cfg.model, adamw.init(), &device)?;
        s.check_resumable(&dir, steps_per_epoch, pairs.len(), cfg.seed)?;
        observer(Event::Message(&format!(
            "resuming at step {} (epoch {}, batch {})",
            s.step, s.epoch, s.batch_in_epoch
        )));
        (m, o, s)
    } else {
        let m = init_seeded(cfg.seed, &device, || cfg.model.init(&device))?;
        let s = RunState::start(steps_per_epoch, pairs.len(), cfg.seed);
        (m, adamw.init(), s)
    };
    let keep = opts.resume.then_some(state.step);
    let metrics = CsvLog::open(&run.join(METRICS_FILE), METRICS_HEADER, keep)?;
    let val_log = CsvLog::open(&run.join(VAL_FILE), VAL_HEADER, keep)?;

    let vgg = match &opts.vgg19 {
        Some(p) => Some(Vgg19Features::load(p, &device)?),
        None => None,
    };
    if vgg.is_none() && cfg.loss.perceptual > 0.0 {
        observer(Event::Message(
            "warning: no --vgg19 weights: the perceptual term is replaced by its stand-in (see perceptual_fallback)",
        ));
    }
    let criterion = Criterion::new(cfg, vgg);
    observer(Event::Message(&format!(
        "perceptual term: {}",
        criterion.perceptual.describe()
    )));

    let spec = BatchSpec {
        pairs: Arc::new(pairs),
        seed: cfg.seed,
        batch_size: cfg.batch_size,
        crop: cfg.crop,
        augment: cfg.augment,
        light_field: cfg.model.light_field,
        variant: cfg.model.variant,
    };
    let mut loader = Loader::start(
        spec,
        state.epoch,
        state.batch_in_epoch,
        cfg.epochs,
        cfg.prefetch_batches,
    );
    observer(Event::Started {
        step: state.step,
        total_steps,
        steps_per_epoch,
    });

    let ctx = Ctx {
        cfg,
        run,
        val: &val,
        val_lf: &val_lf,
        metrics: &metrics,
        val_log: &val_log,
        refs: &opts.val_refs,
    };
    let mut summary = TrainSummary {
        step: state.step,
        session_steps: 0,
        losses: Vec::new(),
        finished: false,
        interrupted: false,
        best: state.best,
        last_val: None,
    };
    let mut window = LogWindow::default();
    let mut last_ck = Instant::now();
    let session_clock = Instant::now();
    let base_secs = state.train_secs;

    while state.step < total_steps {
        if stop.load(Ordering::Relaxed) {
            summary.interrupted = true;
            break;
        }
        if opts.max_steps.is_some_and(|m| summary.session_steps >= m) {
            break;
        }
        let batch = match loader.next_batch() {
            Some(b) => b?,
            None => {
                return Err(TrainError::Loader(format!(
                    "ran out of batches at step {} of {total_steps}",
                    state.step
                )));
            }
        };
        check_position(&batch, &state)?;
        let t0 = Instant::now();
        let lr = cfg.lr_at(state.step, steps_per_epoch);
        let (next, values) = train_step(model, &mut optim, &criterion, &batch, lr, &device)?;
        model = next;
        if !values.is_finite() {
            return Err(TrainError::NonFiniteLoss {
                step: state.step,
                terms: format!("{values:?}"),
            });
        }
        let epoch_of_step = state.epoch;
        state.step += 1;
        state.batch_in_epoch += 1;
        summary.session_steps += 1;
        summary.step = state.step;
        summary.losses.push((state.step, values));
        window.add(&values, t0.elapsed().as_secs_f64());
        observer(Event::Step {
            step: state.step,
            epoch: epoch_of_step,
            lr,
            loss: &values,
        });
        if state.step.is_multiple_of(cfg.log_every_steps) || state.step == total_steps {
            window.flush(&metrics, state.step, epoch_of_step, lr)?;
        }
        let mut want_ck = (cfg.checkpoint_every_steps > 0
            && state.step.is_multiple_of(cfg.checkpoint_every_steps))
            || (cfg.checkpoint_every_secs > 0
                && last_ck.elapsed().as_secs() >= cfg.checkpoint_every_secs);
        if state.batch_in_epoch == steps_per_epoch {
            state.epoch += 1;
            state.batch_in_epoch = 0;
            want_ck = true;
            let due = cfg.val_every_epochs > 0
                && (state.epoch.is_multiple_of(cfg.val_every_epochs) || state.epoch == cfg.epochs);
            if due && !val.is_empty() {
                let v = ctx.validate(&model, &state, observer)?;
                if state.best.is_none_or(|(b, _)| v.psnr > b) {
                    state.best = Some((v.psnr, state.step));
                    let export = model.valid();
                    save_checkpoint(&ck_best, &export, &cfg.model, None, &state)?;
                }
                summary.best = state.best;
                summary.last_val = Some(v);
            }
        }
        if want_ck {
            state.train_secs = base_secs + session_clock.elapsed().as_secs_f64();
            save_checkpoint(&ck_last, &model, &cfg.model, Some(&optim), &state)?;
            observer(Event::Checkpoint {
                step: state.step,
                path: &ck_last,
            });
            ctx.curves()?;
            last_ck = Instant::now();
        }
    }
    drop(loader);
    summary.finished = state.step >= total_steps;
    // The epoch and learning rate of the last step done.
    let last_epoch = if state.batch_in_epoch == 0 {
        state.epoch.saturating_sub(1)
    } else {
        state.epoch
    };
    let last_lr = cfg.lr_at(state.step.saturating_sub(1), steps_per_epoch);
    window.flush(&metrics, state.step, last_epoch, last_lr)?;
    state.train_secs = base_secs + session_clock.elapsed().as_secs_f64();
    if summary.session_steps > 0 || !opts.resume {
        save_checkpoint(&ck_last, &model, &cfg.model, Some(&optim), &state)?;
        observer(Event::Checkpoint {
            step: state.step,
            path: &ck_last,
        });
    }
    ctx.curves()?;
    summary.best = state.best;
    Ok(summary)
}

/// Everything validation and plotting need.
struct Ctx<'a> {
    cfg: &'a TrainConfig,
    run: &'a Path,
    val: &'a [ValPair],
    val_lf: &'a [ReferenceStyle],
    metrics: &'a CsvLog,
    val_log: &'a CsvLog,
    refs: &'a [f64],
}

impl Ctx<'_> {
    fn validate(
        &self,
        model: &Generator,
        state: &RunState,
        observer: &mut dyn FnMut(Event<'_>),
    ) -> Result<ValResult> {
        let t0 = Instant::now();
        // Validation renders with the inference engine, as `uwnr render` does by default.
        let g = Network::from_generator(&model.valid(), &self.cfg.model, &Backend::Engine)?;
        let opts = RenderOptions::default();
        let mut per_pair = Vec::with_capacity(self.val.len());
        let mut sheet = Vec::new();
        for (v, lf) in self.val.iter().zip(self.val_lf) {
            let out = g.render(&v.clean, &v.depth, lf, &opts)?;
            let p = uwnr_metrics::psnr(&out, &v.underwater, uwnr_metrics::DEFAULT_DATA_RANGE)
                .map_err(|e| metric_err(&v.name, &e))?;
            let s = uwnr_metrics::ssim(&out, &v.underwater, uwnr_metrics::DEFAULT_DATA_RANGE)
                .map_err(|e| metric_err(&v.name, &e))?;
            per_pair.push((v.name.clone(), p, s));
            if sheet.len() < self.cfg.val_sheet_pairs {
                sheet.push((v.name.clone(), v.clean.clone(), out, v.underwater.clone()));
            }
        }
        let n = per_pair.len().max(1) as f64;
        let result = ValResult {
            step: state.step,
            epoch: state.epoch,
            psnr: per_pair.iter().map(|r| r.1).sum::<f64>() / n,
            ssim: per_pair.iter().map(|r| r.2).sum::<f64>() / n,
            per_pair,
            secs: t0.elapsed().as_secs_f64(),
        };
        self.val_log.append(&[
            result.step.to_string(),
            result.epoch.to_string(),
            format!("{:.4}", result.psnr),
            format!("{:.5}", result.ssim),
            format!("{:.1}", result.secs),
        ])?;
        if !sheet.is_empty() {
            let dir = self.run.join(VAL_DIR);
            std::fs::create_dir_all(&dir).map_err(|source| TrainError::Io {
                path: dir.clone(),
                source,
            })?;
            contact_sheet(
                &dir.join(format!("step-{:07}.png", state.step)),
                &sheet,
                SHEET_THUMB,
            )?;
        }
        observer(Event::Validation(&result));
        Ok(result)
    }

    fn curves(&self) -> Result<()> {
        let losses: Vec<(usize, [f64; 5])> = self
            .metrics
            .rows()?
            .into_iter()
            .filter(|r| r.len() >= 8)
            .map(|r| (r[0] as usize, [r[3], r[4], r[5], r[6], r[7]]))
            .collect();
        let val: Vec<(usize, f64)> = self
            .val_log
            .rows()?
            .into_iter()
            .filter(|r| r.len() >= 3)
            .map(|r| (r[0] as usize, r[2]))
            .collect();
        draw_curves(&self.run.join(CURVES_FILE), &losses, &val, self.refs)
    }
}

fn metric_err(name: &str, e: &uwnr_metrics::MetricsError) -> TrainError {
    TrainError::BadImage {
        path: PathBuf::from(name),
        reason: format!("scoring the validation render: {e}"),
    }
}

/// The batch must be the one the state expects (a loader bug would otherwise silently break
/// exact resume).
fn check_position(batch: &Batch, state: &RunState) -> Result<()> {
    if (batch.epoch, batch.index) != (state.epoch, state.batch_in_epoch) {
        return Err(TrainError::Loader(format!(
            "got batch {} of epoch {}, expected batch {} of epoch {}",
            batch.index, batch.epoch, state.batch_in_epoch, state.epoch
        )));
    }
    Ok(())
}

/// Forces the lazy initialisation of every float parameter.
struct Materialise;

impl burn::module::ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &burn::module::Param<Tensor<D>>) {
        let _ = param.val();
    }
}

/// Serialises seeding burn's process-wide generator and drawing the initial weights.
static INIT_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Builds a network with the initial weights of `seed`, whatever else runs in the process.
///
/// burn's random initialisers draw from one process-wide generator: seeding it and building the
/// network under a lock gives every run its seed's weights even when several run in one process
/// (as tests do). burn initialises parameters lazily, at first use, so they are all touched
/// before the lock is released. `build` must create the network on `device`.
pub fn init_seeded<M: Module, E>(
    seed: u64,
    device: &Device,
    build: impl FnOnce() -> std::result::Result<M, E>,
) -> std::result::Result<M, E> {
    let _guard = INIT_LOCK
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    device.seed(seed);
    let m = build()?;
    m.visit(&mut Materialise);
    Ok(m)
}

/// One optimisation step: forward, loss, backward, AdamW update at `lr`.
pub fn train_step(
    model: Generator,
    optim: &mut ModuleOptimizer,
    criterion: &Criterion,
    batch: &Batch,
    lr: f64,
    device: &Device,
) -> Result<(Generator, LossValues)> {
    let (b, c) = (batch.size, batch.crop);
    let cin = batch.input.len() / (b * c * c).max(1);
    let x = Tensor::<4>::from_data(TensorData::new(batch.input.clone(), [b, cin, c, c]), device);
    let y = Tensor::<4>::from_data(
        TensorData::new(batch.target.clone(), [b, TARGET_CHANNELS, c, c]),
        device,
    );
    let out = if batch.depth.is_empty() {
        model.forward(x) // [b, 3, c, c]
    } else {
        // The anchored variant: input planes 6..9 are the anchor.
        let anchor = x.clone().slice([0..b, 6..9, 0..c, 0..c]);
        let raw = model.forward(x); // [b, 6, c, c]
        let depth =
            Tensor::<4>::from_data(TensorData::new(batch.depth.clone(), [b, 1, c, c]), device);
        let water = Tensor::<2>::from_data(
            TensorData::new(batch.water.clone(), [b, WATER_VALUES]),
            device,
        );
        let veil = water.clone().slice([0..b, 0..3]).reshape([b, 3, 1, 1]);
        let beta = water.slice([0..b, 3..6]).reshape([b, 3, 1, 1]);
        finish_tensor(raw, anchor, depth, veil, beta) // [b, 3, c, c]
    };
    let loss = criterion.forward(out, y);
    let grads = loss.total.backward();
    let grads = GradientsParams::from_grads(grads, &model);
    let model = optim.step(lr, model, grads);
    let values = read_terms(loss.terms)?;
    Ok((model, values))
}

/// Mean of the losses since the last `metrics.csv` row.
#[derive(Default)]
struct LogWindow {
    sum: LossValues,
    secs: f64,
    n: usize,
}

impl LogWindow {
    fn add(&mut self, v: &LossValues, secs: f64) {
        self.sum = self.sum.add(v);
        self.secs += secs;
        self.n += 1;
    }

    fn flush(&mut self, log: &CsvLog, step: usize, epoch: usize, lr: f64) -> Result<()> {
        if self.n == 0 {
            return Ok(());
        }
        let k = 1.0 / self.n as f64;
        let m = self.sum.scale(k);
        let mut row = vec![step.to_string(), epoch.to_string(), format!("{lr:.6e}")];
        row.extend(m.as_array().iter().map(|v| format!("{v:.6}")));
        row.push(format!("{:.3}", self.secs * k));
        log.append(&row)?;
        *self = Self::default();
        Ok(())
    }
}

/// On resume, the run's `config.json` must equal `cfg`.
fn check_saved_config(cfg: &TrainConfig, run: &Path) -> Result<()> {
    let cfg_path = run.join(CONFIG_FILE);
    let saved = TrainConfig::from_json_file(&cfg_path)?;
    if &saved != cfg {
        return Err(TrainError::ConfigChanged { path: cfg_path });
    }
    Ok(())
}

/// Creates the run folder and writes its `config.json` (the text of the run's config); called
/// on a fresh start once the data has loaded ([`check_run_folder`] has refused a folder holding
/// a run, so what it replaces is what a failed start left).
pub fn claim_run_folder(run: &Path, config_json: &str) -> Result<()> {
    std::fs::create_dir_all(run).map_err(|source| TrainError::Io {
        path: run.to_path_buf(),
        source,
    })?;
    write_file(&run.join(CONFIG_FILE), config_json)
}

fn write_file(path: &Path, text: &str) -> Result<()> {
    uwnr_core::io::write_atomic(path, |out| out.write_all(text.as_bytes()))?;
    Ok(())
}
