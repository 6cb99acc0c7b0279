//! UWNR training (released `train_ddp.py`, rewritten) as a [`uwnr_run::Task`]: the generator and
//! AdamW, the weighted loss of the paper, validation by rendering each validation pair at its
//! native resolution with the inference engine, and `generator.safetensors` in every checkpoint.
//! The loop, logs, checkpoints and exact resume are uwnr-run's ([`uwnr_run::learner`]); the run
//! folder's layout is described in [`uwnr_run::folder`].

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use burn::optim::{AdamWConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor, TensorData};
use uwnr_core::lightfield;
use uwnr_model::style::estimate_water_for;
use uwnr_model::weights::SOURCE_METADATA_KEY;
use uwnr_model::{Backend, ReferenceStyle, RenderOptions, Variant, WeightsDtype};
/// Where and how to train (what is not part of the run's config).
pub use uwnr_run::TrainOptions;
use uwnr_run::checkpoint::RunState;
use uwnr_run::folder::{check_run_folder, check_saved_config};
use uwnr_run::{Event, Prepared, Schedule, Scores, Task};

use crate::adversarial::{ADVERSARIAL_TERMS, Critic, adversarial_step};
use crate::augment::{TARGET_CHANNELS, WATER_VALUES};
use crate::burn_render::{RenderOn, network_from_generator};
use crate::burn_style::finish_tensor;
use crate::burn_weights::save_generator;
use crate::config::{AdversarialConfig, TrainConfig};
use crate::data::{LoadOptions, TrainData, ValPair, load_data};
use crate::error::{Result, TrainError};
use crate::generator::{Generator, GeneratorInit};
use crate::loader::{Batch, BatchSpec};
use crate::losses::{Criterion, LossValues, read_terms};
use crate::vgg::Vgg19Features;

/// The generator's weights inside each checkpoint folder, under the authors' key names with its
/// config: the file `uwnr render --weights` takes.
pub const GENERATOR_FILE: &str = "generator.safetensors";
/// `metrics.csv` columns of UWNR's loss terms and their legend names in `curves.png`.
const LOSS_TERMS: [(&str, &str); 5] = [
    ("reconstruction", "L1"),
    ("perceptual", "perceptual"),
    ("dark_channel", "dark channel"),
    ("light_field", "light field"),
    ("total", "total"),
];
/// Column headers of a validation contact sheet.
const SHEET_COLUMNS: [&str; 3] = ["clean", "render", "real underwater"];

/// How a session ended.
#[derive(Clone, Debug)]
pub struct TrainSummary {
    /// Steps done in total.
    pub step: usize,
    /// Steps done in this session.
    pub session_steps: usize,
    /// `(step, losses)` of every step of this session (empty in an adversarial run).
    pub losses: Vec<(usize, LossValues)>,
    /// `(step, [d_loss, adversarial, content, paired, total])` of every step of an adversarial
    /// run's session ([`crate::adversarial::ADVERSARIAL_TERMS`]; empty otherwise).
    pub adversarial: Vec<(usize, [f64; 5])>,
    /// The run reached its last epoch.
    pub finished: bool,
    /// The stop flag ended the session.
    pub interrupted: bool,
    /// Best validation PSNR and its step.
    pub best: Option<(f64, usize)>,
    /// The last validation of this session.
    pub last_val: Option<uwnr_run::ValResult>,
}

impl TrainSummary {
    /// The loop's summary of an adversarial run: its terms go to `adversarial`.
    fn adversarial(s: uwnr_run::Summary) -> Self {
        let terms = s
            .losses
            .iter()
            .map(|(step, v)| {
                let g = |i: usize| v.get(i).copied().unwrap_or(f64::NAN);
                (*step, [g(0), g(1), g(2), g(3), g(4)])
            })
            .collect();
        Self {
            adversarial: terms,
            losses: Vec::new(),
            ..s.into()
        }
    }
}

impl From<uwnr_run::Summary> for TrainSummary {
    fn from(s: uwnr_run::Summary) -> Self {
        Self {
            step: s.step,
            session_steps: s.session_steps,
            losses: s
                .losses
                .iter()
                .map(|(step, v)| (*step, LossValues::from_slice(v)))
                .collect(),
            adversarial: Vec::new(),
            finished: s.finished,
            interrupted: s.interrupted,
            best: s.best,
            last_val: s.last_val,
        }
    }
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
    let prepared = Prepared {
        config_json: cfg.to_json()?,
        pairs: pairs.len(),
        report: report.to_text(),
    };
    let val_styles = val
        .iter()
        .map(|v| reference_style(cfg, v))
        .collect::<Result<Vec<_>>>()?;
    let device = opts.device.clone().autodiff();
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
    if cfg.loss.perceptual > 0.0 {
        observer(Event::Message(&format!(
            "perceptual term: {}",
            criterion.perceptual.describe()
        )));
    }
    if let Some(a) = &cfg.adversarial {
        observer(Event::Message(&format!(
            "adversarial: {} x L_G ({:?}) + {} x L1 to the uncorrected render; a {}-layer PatchGAN of width {} \
             on renders and real photos pooled by {}",
            a.weight,
            a.loss,
            a.content,
            a.discriminator.layers,
            a.discriminator.width,
            a.downsample
        )));
        if let Some(st) = &a.stages {
            observer(Event::Message(&format!(
                "the discriminator sees renders through the effects and the camera of a {} px frame \
                 (straight-through: the generator's gradient passes them unchanged)",
                st.frame
            )));
        }
    }
    let source = Arc::new(BatchSpec {
        pairs: Arc::new(pairs),
        seed: cfg.run.seed,
        batch_size: cfg.batch_size,
        crop: cfg.crop,
        augment: cfg.augment,
        light_field: cfg.model.light_field,
        variant: cfg.model.variant,
        detail_retention: cfg.model.detail_retention,
        anchor: cfg.model.anchor,
    });
    let task = UwnrTask {
        cfg,
        device,
        criterion,
        val,
        val_styles,
        steps_per_epoch: source.batches_per_epoch(),
    };
    let session = opts.session();
    let schedule = Schedule::new(&cfg.run, cfg.epochs, cfg.batch_size, None);
    Ok(match cfg.adversarial {
        None => uwnr_run::train(
            &task, source, &prepared, &schedule, &session, stop, observer,
        )?
        .into(),
        Some(adv) => {
            let task = AdversarialTask { base: task, adv };
            TrainSummary::adversarial(uwnr_run::train(
                &task, source, &prepared, &schedule, &session, stop, observer,
            )?)
        }
    })
}

/// The light field (and, for the anchored variant, the water) of a validation pair's real
/// underwater image, at the clean image's size.
fn reference_style(cfg: &TrainConfig, v: &ValPair) -> Result<ReferenceStyle> {
    let light_field = lightfield::light_field_for_with(
        &v.underwater,
        v.clean.width(),
        v.clean.height(),
        cfg.model.light_field,
    )?;
    let water = match cfg.model.variant {
        Variant::Paper => None,
        Variant::Anchored => Some(estimate_water_for(
            &v.underwater,
            cfg.model.anchor,
            cfg.model.detail_retention,
        )?),
    };
    Ok(ReferenceStyle {
        light_field: Some(light_field),
        water,
        chromaticity: None,
    })
}

/// UWNR's part of a run.
struct UwnrTask<'a> {
    cfg: &'a TrainConfig,
    /// The autodiff training device.
    device: Device,
    criterion: Criterion,
    val: Vec<ValPair>,
    val_styles: Vec<ReferenceStyle>,
    steps_per_epoch: usize,
}

impl Task for UwnrTask<'_> {
    type Model = Generator;
    type Error = TrainError;
    type Source = BatchSpec;

    fn loss_terms(&self) -> Vec<(String, String)> {
        owned_terms(&LOSS_TERMS)
    }

    fn device(&self) -> &Device {
        &self.device
    }

    fn build(&self) -> Result<Generator> {
        Ok(self.cfg.model.init(&self.device)?)
    }

    fn optimizer(&self) -> ModuleOptimizer {
        AdamWConfig::new()
            .with_beta_1(self.cfg.betas.0)
            .with_beta_2(self.cfg.betas.1)
            .with_epsilon(self.cfg.epsilon)
            .with_weight_decay(self.cfg.weight_decay)
            .init()
    }

    fn lr(&self, step: usize, _epoch: usize) -> f64 {
        self.cfg.lr_at(step, self.steps_per_epoch)
    }

    fn step(
        &self,
        model: Generator,
        optim: &mut ModuleOptimizer,
        batch: Batch,
        _step: usize,
        lr: f64,
    ) -> Result<(Generator, Vec<f64>)> {
        let (model, values) = train_step(model, optim, &self.criterion, &batch, lr, &self.device)?;
        Ok((model, values.as_array().to_vec()))
    }

    fn has_validation(&self) -> bool {
        !self.val.is_empty()
    }

    /// Renders each validation pair with the inference engine, as `uwnr render` does by default.
    fn validate(&self, model: &Generator, sheet_rows: usize) -> Result<Scores> {
        let g = network_from_generator(model, &self.cfg.model, &RenderOn::Engine(Backend::Engine))?;
        let opts = RenderOptions::default();
        let mut scores = Scores::default();
        for (v, style) in self.val.iter().zip(&self.val_styles) {
            let out = g.render(&v.clean, &v.depth, style, &opts)?;
            scores.add(&v.name, out, &v.underwater, sheet_rows, |out| {
                vec![v.clean.clone(), out, v.underwater.clone()]
            })?;
        }
        Ok(scores)
    }

    fn sheet_columns(&self) -> Vec<String> {
        SHEET_COLUMNS.iter().map(|c| (*c).to_string()).collect()
    }

    fn export(&self, model: &Generator, dir: &Path, state: &RunState) -> Result<()> {
        let mut meta = BTreeMap::new();
        meta.insert(
            SOURCE_METADATA_KEY.to_string(),
            format!("uwnr train, step {}, epoch {}", state.step, state.epoch),
        );
        save_generator(
            model,
            &self.cfg.model,
            &dir.join(GENERATOR_FILE),
            WeightsDtype::F32,
            &meta,
        )?;
        Ok(())
    }
}

/// An adversarial run: UWNR's task (data, validation, export) with the critic's step.
struct AdversarialTask<'a> {
    base: UwnrTask<'a>,
    adv: AdversarialConfig,
}

impl Task for AdversarialTask<'_> {
    type Model = Critic;
    type Error = TrainError;
    type Source = BatchSpec;

    fn loss_terms(&self) -> Vec<(String, String)> {
        owned_terms(&ADVERSARIAL_TERMS)
    }

    fn device(&self) -> &Device {
        self.base.device()
    }

    fn build(&self) -> Result<Critic> {
        let discriminator = self
            .adv
            .discriminator
            .init(self.base.device())
            .map_err(|e| TrainError::InvalidConfig {
                field: "adversarial.discriminator",
                reason: e.to_string(),
            })?;
        Ok(Critic {
            generator: self.base.build()?,
            discriminator,
        })
    }

    fn optimizer(&self) -> ModuleOptimizer {
        self.base.optimizer()
    }

    fn lr(&self, step: usize, epoch: usize) -> f64 {
        self.base.lr(step, epoch)
    }

    fn step(
        &self,
        model: Critic,
        optim: &mut ModuleOptimizer,
        batch: Batch,
        step: usize,
        lr: f64,
    ) -> Result<(Critic, Vec<f64>)> {
        // The stages' particles and noise are drawn from the run's seed and the step, so a
        // resumed run draws what an uninterrupted one would.
        let seed = uwnr_core::seed::mix(self.base.cfg.run.seed ^ (step as u64));
        let (model, values) = adversarial_step(
            model,
            optim,
            &self.base.criterion,
            &self.adv,
            &batch,
            (lr, seed),
            self.base.device(),
        )?;
        Ok((model, values.to_vec()))
    }

    fn has_validation(&self) -> bool {
        self.base.has_validation()
    }

    fn validate(&self, model: &Critic, sheet_rows: usize) -> Result<Scores> {
        self.base.validate(&model.generator, sheet_rows)
    }

    fn sheet_columns(&self) -> Vec<String> {
        self.base.sheet_columns()
    }

    fn export(&self, model: &Critic, dir: &Path, state: &RunState) -> Result<()> {
        self.base.export(&model.generator, dir, state)
    }
}

/// `(csv column, legend name)` pairs as the loop takes them.
fn owned_terms(terms: &[(&str, &str)]) -> Vec<(String, String)> {
    terms
        .iter()
        .map(|(c, l)| ((*c).to_string(), (*l).to_string()))
        .collect()
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
