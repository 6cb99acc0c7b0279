//! One training loop for every network, in the manner of burn's `TrainStep` / `ValidStep` and
//! its learner: a [`Task`] says how to build its network, take a step on a batch, validate and
//! export weights; the loop owns everything else. Batches come from the task's
//! [`BatchSource`] on a prefetching thread; each step's losses are logged (mean per window) to
//! `metrics.csv`; validation runs at epoch ends, is logged to `val.csv` with a contact sheet, and
//! the best validation PSNR is kept in `checkpoints/best`; `checkpoints/last` is written at epoch
//! ends, every `checkpoint_every_steps` steps and `checkpoint_every_secs` seconds, and once when
//! the session ends (never twice for the same step); a stop request (Ctrl-C) ends the session at
//! the next step boundary with a checkpoint; a resumed run continues exactly where it stopped.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::ModuleOptimizer;
use burn::tensor::{Device, Tensor};

use crate::checkpoint::{
    BEST, CHECKPOINTS_DIR, LAST, RunState, find_checkpoint, load_checkpoint, save_checkpoint,
};
use crate::csvlog::{CsvLog, VAL_HEADER, metrics_header};
use crate::error::RunError;
use crate::folder::{
    CURVES_FILE, DATA_REPORT_FILE, METRICS_FILE, VAL_DIR, VAL_FILE, claim_run_folder, write_text,
};
use crate::loader::{BatchSource, Loader};
use crate::plot::{LossSeries, TOTAL_COLOUR, contact_sheet, draw_loss_curves, series_colour};

/// Height of a contact-sheet thumbnail.
const SHEET_THUMB: usize = 192;

mod task;

pub use task::{
    Event, Prepared, Schedule, Scores, Session, Summary, Task, TrainOptions, ValResult,
};

/// Trains (or resumes) the run of `session.run_dir`. The caller has checked the run folder
/// ([`crate::folder::check_run_folder`], and the saved config on resume) and loaded the data
/// (`prepared`, `source`); the folder is claimed here, now that the data has loaded. `stop` ends
/// the session cleanly (checkpoint written) at the next step boundary; `observer` receives
/// progress events.
#[allow(clippy::too_many_lines)]
pub fn train<T: Task>(
    task: &T,
    source: Arc<T::Source>,
    prepared: &Prepared,
    schedule: &Schedule,
    session: &Session,
    stop: &AtomicBool,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<Summary, T::Error> {
    let run = &session.run_dir;
    // Shown before anything is checked, so a refused start still lists what was skipped.
    observer(Event::Message(prepared.report.trim_end()));
    let steps_per_epoch = source.batches_per_epoch();
    if steps_per_epoch == 0 {
        return Err(RunError::NoData(format!(
            "{} training pairs, fewer than one batch of {}",
            prepared.pairs, schedule.batch_size
        ))
        .into());
    }
    // The data has loaded: only now is the folder claimed.
    if !session.resume {
        claim_run_folder(run, &prepared.config_json)?;
    }
    write_text(&run.join(DATA_REPORT_FILE), &prepared.report)?;
    let whole = schedule.epochs * steps_per_epoch;
    let total_steps = schedule.total_steps.map_or(whole, |t| t.min(whole));

    let ck_last = run.join(CHECKPOINTS_DIR).join(LAST);
    let ck_best = run.join(CHECKPOINTS_DIR).join(BEST);
    let (mut model, mut optim, mut state) = if session.resume {
        let dir = find_checkpoint(&ck_last).ok_or_else(|| RunError::Checkpoint {
            path: ck_last.clone(),
            reason: "no checkpoint to resume from".into(),
        })?;
        let (m, o, s) = load_checkpoint(&dir, task.build()?, task.optimizer())?;
        s.check_resumable(&dir, steps_per_epoch, prepared.pairs, schedule.run.seed)?;
        observer(Event::Message(&format!(
            "resuming at step {} (epoch {}, batch {})",
            s.step, s.epoch, s.batch_in_epoch
        )));
        (m, o, s)
    } else {
        let m = init_seeded(schedule.run.seed, task.device(), || task.build())?;
        let state = RunState::start(steps_per_epoch, prepared.pairs, schedule.run.seed);
        (m, task.optimizer(), state)
    };
    let terms = task.loss_terms();
    let names: Vec<&str> = terms.iter().map(|(c, _)| c.as_str()).collect();
    let keep = session.resume.then_some(state.step);
    let metrics = CsvLog::open(&run.join(METRICS_FILE), &metrics_header(&names), keep)?;
    let val_log = CsvLog::open(&run.join(VAL_FILE), VAL_HEADER, keep)?;
    let mut loader = Loader::start(
        source,
        state.epoch,
        state.batch_in_epoch,
        schedule.epochs,
        schedule.run.prefetch_batches,
    );
    observer(Event::Started {
        step: state.step,
        total_steps,
        steps_per_epoch,
    });

    let logs = Logs {
        run,
        terms: &terms,
        metrics: &metrics,
        val_log: &val_log,
        refs: &session.val_refs,
    };
    let mut summary = Summary {
        step: state.step,
        session_steps: 0,
        losses: Vec::new(),
        finished: false,
        interrupted: false,
        best: state.best,
        last_val: None,
        last_dir: ck_last.clone(),
        best_dir: None,
        train_secs: state.train_secs,
    };
    let mut window = LogWindow::default();
    let mut last_ck = Instant::now();
    let session_clock = Instant::now();
    let base_secs = state.train_secs;
    // Step of the last `last` checkpoint written in this session.
    let mut saved_at: Option<usize> = None;
    let save_last = |model: &T::Model, optim: &ModuleOptimizer, state: &RunState| {
        save_checkpoint(&ck_last, model, Some(optim), state, |tmp: &Path| {
            task.export(&model.valid(), tmp, state)
        })
    };

    while state.step < total_steps {
        if stop.load(Ordering::Relaxed) {
            summary.interrupted = true;
            break;
        }
        if session
            .max_steps
            .is_some_and(|m| summary.session_steps >= m)
        {
            break;
        }
        let next = match loader.next_batch() {
            Some(b) => b?,
            None => {
                return Err(RunError::Loader(format!(
                    "ran out of batches at step {} of {total_steps}",
                    state.step
                ))
                .into());
            }
        };
        if (next.epoch, next.index) != (state.epoch, state.batch_in_epoch) {
            // A loader bug would otherwise silently break exact resume.
            return Err(RunError::Loader(format!(
                "got batch {} of epoch {}, expected batch {} of epoch {}",
                next.index, next.epoch, state.batch_in_epoch, state.epoch
            ))
            .into());
        }
        let t0 = Instant::now();
        let lr = task.lr(state.step, state.epoch);
        let (updated, values) = task.step(model, &mut optim, next.batch, state.step, lr)?;
        model = updated;
        if values.iter().any(|v| !v.is_finite()) {
            let terms = terms
                .iter()
                .zip(&values)
                .map(|((c, _), v)| format!("{c} {v}"))
                .collect::<Vec<_>>()
                .join(", ");
            return Err(RunError::NonFiniteLoss {
                step: state.step,
                terms,
            }
            .into());
        }
        let epoch_of_step = state.epoch;
        state.step += 1;
        state.batch_in_epoch += 1;
        summary.session_steps += 1;
        summary.step = state.step;
        window.add(&values, t0.elapsed().as_secs_f64());
        observer(Event::Step {
            step: state.step,
            epoch: epoch_of_step,
            lr,
            losses: &values,
        });
        summary.losses.push((state.step, values));
        if state
            .step
            .is_multiple_of(schedule.run.log_every_steps.max(1))
            || state.step == total_steps
        {
            window.flush(&metrics, state.step, epoch_of_step, lr)?;
        }
        let mut want_ck = (schedule.run.checkpoint_every_steps > 0
            && state
                .step
                .is_multiple_of(schedule.run.checkpoint_every_steps))
            || (schedule.run.checkpoint_every_secs > 0
                && last_ck.elapsed().as_secs() >= schedule.run.checkpoint_every_secs);
        if state.batch_in_epoch == steps_per_epoch {
            state.epoch += 1;
            state.batch_in_epoch = 0;
            want_ck = true;
            let due = schedule.run.val_every_epochs > 0
                && (state.epoch.is_multiple_of(schedule.run.val_every_epochs)
                    || state.epoch == schedule.epochs);
            if due && task.has_validation() {
                let v = validate(task, &model, &state, schedule, &logs, observer)?;
                if state.best.is_none_or(|(b, _)| v.psnr > b) {
                    state.best = Some((v.psnr, state.step));
                    let export = model.valid();
                    save_checkpoint(&ck_best, &export, None, &state, |tmp: &Path| {
                        task.export(&export, tmp, &state)
                    })?;
                }
                summary.best = state.best;
                summary.last_val = Some(v);
            }
        }
        if want_ck {
            state.train_secs = base_secs + session_clock.elapsed().as_secs_f64();
            save_last(&model, &optim, &state)?;
            saved_at = Some(state.step);
            observer(Event::Checkpoint {
                step: state.step,
                path: &ck_last,
            });
            logs.curves()?;
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
    let last_lr = task.lr(state.step.saturating_sub(1), last_epoch);
    window.flush(&metrics, state.step, last_epoch, last_lr)?;
    if (summary.session_steps > 0 || !session.resume) && saved_at != Some(state.step) {
        state.train_secs = base_secs + session_clock.elapsed().as_secs_f64();
        save_last(&model, &optim, &state)?;
        observer(Event::Checkpoint {
            step: state.step,
            path: &ck_last,
        });
    }
    logs.curves()?;
    summary.best = state.best;
    summary.train_secs = state.train_secs;
    summary.best_dir = find_checkpoint(&ck_best);
    Ok(summary)
}

/// Runs the task's validation, logs it, draws its contact sheet and reports it.
fn validate<T: Task>(
    task: &T,
    model: &T::Model,
    state: &RunState,
    schedule: &Schedule,
    logs: &Logs<'_>,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<ValResult, T::Error> {
    let t0 = Instant::now();
    let scores = task.validate(&model.valid(), schedule.run.val_sheet_pairs)?;
    let result = ValResult {
        step: state.step,
        epoch: state.epoch,
        psnr: scores.psnr,
        ssim: scores.ssim,
        per_pair: scores.per_pair,
        secs: t0.elapsed().as_secs_f64(),
    };
    logs.val_log.append(&[
        result.step.to_string(),
        result.epoch.to_string(),
        format!("{:.4}", result.psnr),
        format!("{:.5}", result.ssim),
        format!("{:.1}", result.secs),
    ])?;
    if !scores.sheet.is_empty() {
        let dir = logs.run.join(VAL_DIR);
        std::fs::create_dir_all(&dir).map_err(RunError::io(&dir))?;
        let columns = task.sheet_columns();
        let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
        contact_sheet(
            &dir.join(format!("step-{:07}.png", state.step)),
            &columns,
            &scores.sheet,
            SHEET_THUMB,
        )?;
    }
    observer(Event::Validation(&result));
    Ok(result)
}

/// The run's logs and what drawing its curves needs.
struct Logs<'a> {
    run: &'a Path,
    terms: &'a [(String, String)],
    metrics: &'a CsvLog,
    val_log: &'a CsvLog,
    refs: &'a [f64],
}

impl Logs<'_> {
    /// Redraws `curves.png` from the logs.
    fn curves(&self) -> Result<(), RunError> {
        let n = self.terms.len();
        let rows: Vec<Vec<f64>> = self
            .metrics
            .rows()?
            .into_iter()
            .filter(|r| r.len() >= 3 + n)
            .collect();
        let series: Vec<LossSeries> = self
            .terms
            .iter()
            .enumerate()
            .map(|(i, (_, legend))| LossSeries {
                name: legend.clone(),
                colour: if i + 1 == n {
                    TOTAL_COLOUR
                } else {
                    series_colour(i)
                },
                points: rows.iter().map(|r| (r[0] as usize, r[3 + i])).collect(),
            })
            .collect();
        let val: Vec<(usize, f64)> = self
            .val_log
            .rows()?
            .into_iter()
            .filter(|r| r.len() >= 3)
            .map(|r| (r[0] as usize, r[2]))
            .collect();
        draw_loss_curves(&self.run.join(CURVES_FILE), &series, &val, self.refs)
    }
}

/// Mean of the losses since the last `metrics.csv` row.
#[derive(Default)]
struct LogWindow {
    sum: Vec<f64>,
    secs: f64,
    n: usize,
}

impl LogWindow {
    fn add(&mut self, values: &[f64], secs: f64) {
        if self.sum.len() < values.len() {
            self.sum.resize(values.len(), 0.0);
        }
        for (s, v) in self.sum.iter_mut().zip(values) {
            *s += v;
        }
        self.secs += secs;
        self.n += 1;
    }

    fn flush(&mut self, log: &CsvLog, step: usize, epoch: usize, lr: f64) -> Result<(), RunError> {
        if self.n == 0 {
            return Ok(());
        }
        let k = 1.0 / self.n as f64;
        let mut row = vec![step.to_string(), epoch.to_string(), format!("{lr:.6e}")];
        row.extend(self.sum.iter().map(|v| format!("{:.6}", v * k)));
        row.push(format!("{:.3}", self.secs * k));
        log.append(&row)?;
        *self = Self::default();
        Ok(())
    }
}

/// Forces the lazy initialisation of every float parameter.
struct Materialise;

impl ModuleVisitor for Materialise {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
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
