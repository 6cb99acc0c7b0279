//! One module per subcommand; shared pieces (model and depth set-up) live here.

mod convert;
mod dataset;
mod depth;
#[cfg(feature = "train")]
mod enhance;
mod eval;
#[cfg(feature = "train")]
mod experiment;
#[cfg(feature = "train")]
mod gan;
mod info;
mod lightfield;
mod method;
mod render;
mod serve;
#[cfg(feature = "train")]
mod train;
#[cfg(feature = "train")]
mod training;
#[cfg(feature = "train")]
mod water;

use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressStyle};

use anyhow::{Context, Result, bail};
use uwnr_depth::DepthSource;
use uwnr_model::{GeneratorConfig, LoadedWeights, WeightsInfo};

#[cfg(feature = "train")]
use crate::cli::DeviceArg;
use crate::cli::{Cli, Command, DepthOpts};

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Render(a) => render::run(&a),
        Command::Lightfield(a) => lightfield::run(&a),
        Command::Depth(a) => depth::run(&a),
        Command::Info(a) => info::run(&a),
        Command::Convert(a) => convert::run(&a),
        #[cfg(feature = "train")]
        Command::Train(a) => train::run(&a),
        Command::Eval(a) => eval::run(&a),
        Command::Dataset(a) => dataset::run(&a),
        #[cfg(feature = "train")]
        Command::Experiment(a) => experiment::run(&a),
        #[cfg(feature = "train")]
        Command::Enhance(a) => enhance::run(&a),
        #[cfg(feature = "train")]
        Command::Gan(a) => gan::run(&a),
        Command::Serve(a) => serve::run(&a),
        #[cfg(feature = "train")]
        Command::Water(a) => water::run(&a),
    }
}

/// The burn device training runs on, named on the command line (`engine` is the render
/// engine, not a burn device: what burn runs beside it, such as training, runs on flex).
#[cfg(feature = "train")]
pub fn device(arg: DeviceArg) -> Result<uwnr_train::Device> {
    let name = match arg {
        DeviceArg::Engine | DeviceArg::Flex => "flex",
        DeviceArg::Tch => "tch",
    };
    uwnr_train::device_from_name(name).with_context(|| format!("selecting device {name:?}"))
}

/// Reads the generator's weights from `path` and checks that they build the network (every key
/// and shape, as a render would); returns them with where they came from.
pub fn load_model(path: &Path) -> Result<(LoadedWeights, String)> {
    let loaded = uwnr_model::read_weights(path)
        .with_context(|| format!("loading weights {}", path.display()))?;
    let source = path.display().to_string();
    let (_, ignored) = uwnr_model::weights::engine_weights(&loaded.config, loaded.tensors.clone())
        .with_context(|| format!("loading weights {source}"))?;
    let mut loaded = loaded;
    loaded.info.ignored_keys = ignored;
    Ok((loaded, source))
}

/// The config and facts of [`load_model`]'s weights.
pub fn model_facts(path: &Path) -> Result<(GeneratorConfig, WeightsInfo, String)> {
    let (loaded, source) = load_model(path)?;
    Ok((loaded.config, loaded.info, source))
}

/// The depth source chosen by the depth options.
pub fn depth_source(o: &DepthOpts) -> Result<DepthSource> {
    let unit = o.depth_unit.unwrap_or_default();
    if unit.is_metric() && o.depth_invert {
        bail!("--depth-invert does not apply to a metric --depth-unit (its values are distances)");
    }
    if unit.is_metric() && o.depth_normalize {
        bail!(
            "--depth-normalize does not apply to a metric --depth-unit (it would drop the metres; \
             use --depth-unit relative to normalise)"
        );
    }
    Ok(if let Some(model) = &o.depth_model {
        DepthSource::Onnx {
            model: model.clone(),
            invert: o.depth_invert,
            input_size: o.depth_input_size,
        }
    } else if let Some(path) = &o.depth {
        DepthSource::Maps {
            path: path.clone(),
            invert: o.depth_invert,
            normalize: o.depth_normalize,
            unit,
        }
    } else {
        DepthSource::Builtin
    })
}

/// How depth is read and trusted: `--depth-unit` for maps found beside the clean images,
/// `--depth-scale` for the scene scale of relative maps (uwnr), `--prior-trust`, each with the
/// command's default (`dataset`: [`uwnr_render::DepthPolicy::default`]; `render`:
/// [`uwnr_render::DepthPolicy::render`]).
pub fn depth_policy(
    o: &DepthOpts,
    scale: Option<(f64, f64)>,
    defaults: uwnr_render::DepthPolicy,
) -> uwnr_render::DepthPolicy {
    uwnr_render::DepthPolicy {
        unit: o.depth_unit.unwrap_or(defaults.unit),
        scene_scale_m: scale.map_or(defaults.scene_scale_m, |(a, b)| (a as f32, b as f32)),
        prior_trust: o.prior_trust.unwrap_or(defaults.prior_trust),
        ..defaults
    }
}

/// A stop flag that Ctrl-C raises: the first press prints `message` and lets the command stop at
/// its next safe point; a second press exits at once with status 130.
pub fn stop_on_ctrl_c(message: &'static str) -> Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
        eprintln!("\nuwnr: {message}");
    })
    .context("installing the Ctrl-C handler")?;
    Ok(stop)
}

/// A progress bar drawn with the indicatif `template` (length set later).
pub fn progress_bar(template: &str) -> ProgressBar {
    let bar = ProgressBar::new(0);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
