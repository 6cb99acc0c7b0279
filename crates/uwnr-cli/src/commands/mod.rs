//! One module per subcommand; shared pieces (model and depth set-up) live here.

mod convert;
mod dataset;
mod depth;
mod enhance;
mod eval;
pub(crate) mod experiment;
mod gan;
mod info;
mod lightfield;
mod method;
mod render;
mod train;
mod training;

use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressStyle};

use anyhow::{Context, Result, bail};
use uwnr_depth::DepthSource;
use uwnr_model::{Backend, Device, Generator, GeneratorConfig, Network, WeightsInfo};

use crate::cli::{Cli, Command, DepthOpts, DeviceArg, PrecisionArg};

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Render(a) => render::run(&a),
        Command::Lightfield(a) => lightfield::run(&a),
        Command::Depth(a) => depth::run(&a),
        Command::Info(a) => info::run(&a),
        Command::Convert(a) => convert::run(&a),
        Command::Train(a) => train::run(&a),
        Command::Eval(a) => eval::run(&a),
        Command::Dataset(a) => dataset::run(&a),
        Command::Experiment(a) => experiment::run(&a),
        Command::Enhance(a) => enhance::run(&a),
        Command::Gan(a) => gan::run(&a),
    }
}

/// The burn device named on the command line (`engine` is an inference engine, not a burn
/// device: what burn runs beside it, such as training, runs on flex).
pub fn device(arg: DeviceArg) -> Result<Device> {
    let name = match arg {
        DeviceArg::Engine | DeviceArg::Flex => "flex",
        DeviceArg::Tch => "tch",
    };
    uwnr_model::device_from_name(name).with_context(|| format!("selecting device {name:?}"))
}

/// What runs the generator for rendering: the engine, or burn on the named device.
pub fn backend(arg: DeviceArg) -> Result<Backend> {
    match arg {
        DeviceArg::Engine => Ok(Backend::Engine),
        DeviceArg::Flex | DeviceArg::Tch => Ok(Backend::Burn(device(arg)?)),
    }
}

/// [`backend`] at `precision`: bf16 exists on the engine only, so it is refused elsewhere.
pub fn backend_at(arg: DeviceArg, precision: PrecisionArg) -> Result<Backend> {
    match (arg, precision) {
        (_, PrecisionArg::F32) => backend(arg),
        (DeviceArg::Engine, PrecisionArg::Bf16) => Ok(Backend::EngineBf16),
        (DeviceArg::Flex | DeviceArg::Tch, PrecisionArg::Bf16) => {
            bail!("--precision bf16 runs on the engine only: drop --device or pass --precision f32")
        }
    }
}

/// Weights of the model shipped inside this binary (`uwnr_model::bundled_weights`).
pub fn bundled_weights() -> Option<&'static [u8]> {
    uwnr_model::bundled_weights()
}

/// Loads the generator from `--weights`, or the bundled model.
pub fn load_model(
    weights: Option<&Path>,
    device: &Device,
) -> Result<(Generator, GeneratorConfig, WeightsInfo, String)> {
    if let Some(path) = weights {
        let (g, c, i) = uwnr_model::load_generator(path, device)
            .with_context(|| format!("loading weights {}", path.display()))?;
        return Ok((g, c, i, path.display().to_string()));
    }
    match bundled_weights() {
        Some(bytes) => {
            let (g, c, i) = uwnr_model::load_generator_from_bytes(bytes, device)
                .context("loading the bundled model")?;
            Ok((g, c, i, uwnr_model::BUNDLED_MODEL_NAME.to_string()))
        }
        None => bail!(
            "this build has no bundled model: pass --weights FILE (safetensors or the authors' checkpoint)"
        ),
    }
}

/// Loads the network from `--weights`, or the bundled model, for `backend`; returns it with
/// the file's facts and a name for where it came from.
pub fn load_network(
    weights: Option<&Path>,
    backend: &Backend,
) -> Result<(Network, WeightsInfo, String)> {
    if let Some(path) = weights {
        let (n, i) = Network::load(path, backend)
            .with_context(|| format!("loading weights {}", path.display()))?;
        return Ok((n, i, path.display().to_string()));
    }
    match bundled_weights() {
        Some(bytes) => {
            let (n, i) =
                Network::load_from_bytes(bytes, backend).context("loading the bundled model")?;
            Ok((n, i, uwnr_model::BUNDLED_MODEL_NAME.to_string()))
        }
        None => bail!(
            "this build has no bundled model: pass --weights FILE (safetensors or the authors' checkpoint)"
        ),
    }
}

/// The GAN baseline's generator from `--weights`, or the bundled one, with the device it runs
/// on, its weight bytes and where they came from. It runs on burn (`--device engine` means flex
/// here); bf16 products are an engine feature, so `--precision bf16` is refused.
pub fn load_gan(
    model: &crate::cli::ModelOpts,
    precision: PrecisionArg,
) -> Result<(uwnr_gan::Generator, Device, Vec<u8>, String)> {
    if precision == PrecisionArg::Bf16 {
        bail!("--precision bf16 applies to --method uwnr only (the UWGAN generator runs in f32)");
    }
    let device = device(model.device)?;
    let (generator, bytes, source) =
        uwnr_gan::generator_or_bundled(model.weights.as_deref(), &device)
            .context("loading the UWGAN generator")?;
    Ok((generator, device, bytes, source))
}

/// [`load_gan`] as a dataset renderer.
pub fn gan_renderer(
    model: &crate::cli::ModelOpts,
    precision: PrecisionArg,
) -> Result<uwnr_dataset::Renderer> {
    let (generator, device, bytes, source) = load_gan(model, precision)?;
    Ok(uwnr_dataset::Renderer::gan(
        generator, device, source, &bytes,
    ))
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
/// command's default (`dataset`: [`uwnr_dataset::DepthPolicy::default`]; `render`:
/// [`uwnr_dataset::DepthPolicy::render`]).
pub fn depth_policy(
    o: &DepthOpts,
    scale: Option<(f64, f64)>,
    defaults: uwnr_dataset::DepthPolicy,
) -> uwnr_dataset::DepthPolicy {
    uwnr_dataset::DepthPolicy {
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

/// The UWNR network as a dataset renderer: `--weights` or the bundled model, with the weight
/// bytes fingerprinted into the dataset's settings.
pub fn network_renderer(model: &crate::cli::ModelOpts) -> Result<uwnr_dataset::Renderer> {
    network_renderer_at(model, PrecisionArg::F32)
}

/// [`network_renderer`] at `precision`.
pub fn network_renderer_at(
    model: &crate::cli::ModelOpts,
    precision: PrecisionArg,
) -> Result<uwnr_dataset::Renderer> {
    let backend = backend_at(model.device, precision)?;
    let (network, _info, source) = load_network(model.weights.as_deref(), &backend)?;
    let bytes = match &model.weights {
        Some(p) => std::fs::read(p).with_context(|| format!("reading {}", p.display()))?,
        None => bundled_weights().unwrap_or_default().to_vec(),
    };
    Ok(uwnr_dataset::Renderer::network(
        network,
        uwnr_model::RenderOptions {
            max_tile_pixels: model.max_whole_pixels,
            tile: model.tile,
            overlap: model.overlap,
            ..Default::default()
        },
        source,
        &bytes,
    ))
}
