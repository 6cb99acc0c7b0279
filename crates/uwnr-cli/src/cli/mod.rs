//! Command-line definitions (clap derive). Only this crate knows clap. This module holds the
//! command list and the options several commands share; `render.rs` the render wing's commands,
//! `train.rs` the training wing's (built with the `train` feature).

mod render;
#[cfg(feature = "train")]
mod train;

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand, ValueEnum};
use uwnr_render::{MethodKind, Precision};

pub use render::{
    ConvertArgs, DatasetAction, DatasetArgs, DatasetFormat, DatasetMakeArgs, DepthArgs, DtypeArg,
    EvalArgs, InfoArgs, LightfieldArgs, RenderArgs, ServeArgs,
};
#[cfg(feature = "train")]
pub use train::{
    DownstreamArgs, EnhanceAction, EnhanceApplyArgs, EnhanceArgs, EnhanceEvalArgs,
    EnhanceTrainArgs, ExperimentAction, ExperimentArgs, GanAction, GanArgs, GanLossArg,
    GanTrainArgs, LightFieldLossArg, RunOpts, TrainArgs, WaterAction, WaterArgs, WaterFitArgs,
};

/// Render clean photos into realistic underwater images (UWNR) and build paired datasets.
#[derive(Debug, Parser)]
#[command(name = "uwnr", version, about, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render clean images into underwater images styled after real underwater references.
    Render(Box<RenderArgs>),
    /// Compute the light-field map of a reference image (what the network sees of its style).
    Lightfield(LightfieldArgs),
    /// Compute the depth map a render would use for a clean image.
    Depth(DepthArgs),
    /// Describe the model: parameters, GMac at a size, where the weights came from.
    Info(InfoArgs),
    /// Convert weights (safetensors or the authors' PyTorch checkpoint) to safetensors with the
    /// authors' key names, the model config in the metadata, and a chosen precision.
    Convert(ConvertArgs),
    /// Train the generator on paired folders (underwater/ + clean/), with exact resume.
    #[cfg(feature = "train")]
    Train(TrainArgs),
    /// Score images with the field's metrics (PSNR, SSIM, UIQM, UCIQE, FD, KID).
    Eval(EvalArgs),
    /// Generate a paired dataset (K renders per clean image), resumable and shardable;
    /// `dataset verify` checks one, `dataset merge` joins shards.
    Dataset(Box<DatasetArgs>),
    /// Experiments: `experiment downstream` trains an enhancer on each method's synthetic data
    /// and scores it on real test pairs (the paper's Table 1).
    #[cfg(feature = "train")]
    Experiment(ExperimentArgs),
    /// The Shallow-UWnet enhancer of the downstream experiment: `enhance train` on paired
    /// folders, `enhance apply` to images, `enhance eval` on a paired test folder.
    #[cfg(feature = "train")]
    Enhance(EnhanceArgs),
    /// The UWGAN-style GAN baseline: `gan train` learns image-formation parameters from unpaired
    /// clean images (with depth) and real underwater images; `render --method uwgan` uses it.
    #[cfg(feature = "train")]
    Gan(GanArgs),
    /// Start a local web page to pick a clean image and references and compare every method's
    /// render side by side, with the commands that reproduce them (127.0.0.1 only by default).
    Serve(ServeArgs),
    /// Real waters: `water fit` fits the per-channel water of every real pair (underwater =
    /// gain x clean + offset) into a bank with the regressor that predicts a reference's water
    /// from its statistics (the bundled renderer's `assets/model/water-bank.json`).
    #[cfg(feature = "train")]
    Water(WaterArgs),
}

/// How clean images are paired with references when there are several.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Pairing {
    /// Clean image i takes reference i modulo the number of references (one reference: all use it).
    Cycle,
    /// Every clean image with every reference.
    All,
    /// Each clean image takes a reference drawn at random (seeded by --seed).
    Random,
}

/// Compute device for the neural network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DeviceArg {
    /// The dedicated CPU inference engine (uwnr-engine), which runs every render; commands that
    /// train run burn's flex backend.
    Engine,
    /// Pure-Rust CPU backend (burn flex), always available.
    Flex,
    /// libtorch backend (needs a build with `--features tch`).
    Tch,
}

/// Arithmetic of the engine's heavy products (the Winograd convolutions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PrecisionArg {
    /// f32 throughout (the default).
    F32,
    /// bf16 operands with f32 sums: faster on CPUs with AVX512_BF16, outputs a little off the
    /// f32 ones (engine only).
    Bf16,
}

impl From<PrecisionArg> for Precision {
    fn from(p: PrecisionArg) -> Self {
        match p {
            PrecisionArg::F32 => Self::F32,
            PrecisionArg::Bf16 => Self::Bf16,
        }
    }
}

/// Where depth maps come from.
#[derive(Debug, Clone, Args)]
pub struct DepthOpts {
    /// Depth map for the clean image, or a directory of maps matched by file stem
    /// (grey 8-bit read as /255, 16-bit as /65535; bright = far unless --depth-invert).
    #[arg(long, value_name = "FILE|DIR", conflicts_with = "depth_model")]
    pub depth: Option<PathBuf>,
    /// ONNX monocular depth model (MiDaS / DPT / Depth-Anything style, relative inverse depth out).
    #[arg(long, value_name = "FILE.onnx")]
    pub depth_model: Option<PathBuf>,
    /// Flip the depth convention (for maps where near is bright, or models that output depth).
    #[arg(long)]
    pub depth_invert: bool,
    /// Min-max normalise depth maps to [0,1], making them relative (holes stored as 0 are
    /// filled from their neighbours first).
    #[arg(long)]
    pub depth_normalize: bool,
    /// What the values of depth maps mean: `relative` (code / largest code, the default), `mm`
    /// (16-bit millimetres: NYU-v2, Redwood), `m` (metres: float TIFF or .npy), or a number N of
    /// codes per metre (KITTI: 256). Metric maps put the scene's distances in metres into the
    /// water's attenuation; their holes (0) are filled from their neighbours.
    #[arg(long, value_name = "UNIT", value_parser = parse_depth_unit, conflicts_with = "depth_model")]
    pub depth_unit: Option<uwnr_depth::DepthUnit>,
    /// Trust in the built-in prior's depth differences within an image, 0 (none) to 1 (as a
    /// measured map). Default 0.075 for `render` (keeps self-reconstruction fidelity), 1 for
    /// `dataset` and `experiment` (no target; realism and variety count). Maps and depth models
    /// the user gives are always trusted fully.
    #[arg(long, value_name = "T")]
    pub prior_trust: Option<f32>,
    /// Input size WxH for ONNX depth models with a dynamic input shape.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub depth_input_size: Option<(usize, usize)>,
}

/// Model and device options shared by the commands that run the network.
#[derive(Debug, Clone, Args)]
pub struct ModelOpts {
    /// UWNR weights: safetensors (authors' key names) or the authors' PyTorch checkpoint; with
    /// --method uwgan, a GAN generator (`generator.safetensors` of a `uwnr gan train` run).
    #[arg(long, value_name = "FILE")]
    pub weights: Option<PathBuf>,
    /// Compute device.
    #[arg(long, value_enum, default_value_t = DeviceArg::Engine)]
    pub device: DeviceArg,
    /// With --weights: images with more pixels than this run the network in overlapping tiles
    /// (memory stays bounded) [default: 1048576]. The bundled model runs no network and takes
    /// none of the tiling flags.
    #[arg(long, value_name = "PIXELS")]
    pub max_whole_pixels: Option<usize>,
    /// With --weights: tile edge in pixels for tiled rendering (a multiple of 16) [default: 1024].
    #[arg(long, value_name = "PIXELS")]
    pub tile: Option<usize>,
    /// With --weights: overlap between tiles in pixels (a multiple of 16) [default: 192]; at 192
    /// or more the blend stays outside the network's 76-pixel reach from a cut edge, so tiled
    /// output equals whole-image output.
    #[arg(long, value_name = "PIXELS")]
    pub overlap: Option<usize>,
}

impl ModelOpts {
    /// The tiling flag given, if any (they apply to a network only).
    #[must_use]
    pub fn tiling_flag(&self) -> Option<&'static str> {
        [
            ("--max-whole-pixels", self.max_whole_pixels.is_some()),
            ("--tile", self.tile.is_some()),
            ("--overlap", self.overlap.is_some()),
        ]
        .into_iter()
        .find_map(|(name, given)| given.then_some(name))
    }
}

/// The parser of `--method` and `--methods`: the methods of `uwnr-render`, each with its one-line
/// summary in `--help`.
pub(crate) fn method_parser() -> impl TypedValueParser<Value = MethodKind> {
    PossibleValuesParser::new(
        MethodKind::ALL.map(|k| PossibleValue::new(k.name()).help(k.summary())),
    )
    .try_map(|name| name.parse::<MethodKind>())
}

/// Where Sea-thru coefficients come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SeathruSource {
    /// Sampled per image from the documented ranges.
    Sampled,
    /// Fitted from the reference image.
    Reference,
    /// Given with --beta-d, --beta-b and --b-inf.
    Given,
}

/// Jerlov water types of `--water-type`, as the paper names them (Roman numerals, not acronyms).
#[allow(clippy::upper_case_acronyms)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WaterTypeArg {
    /// Oceanic I (clearest).
    #[value(name = "I")]
    I,
    /// Oceanic IA.
    #[value(name = "IA")]
    IA,
    /// Oceanic IB.
    #[value(name = "IB")]
    IB,
    /// Oceanic II.
    #[value(name = "II")]
    II,
    /// Oceanic III.
    #[value(name = "III")]
    III,
    /// Coastal 1C.
    #[value(name = "1C")]
    C1,
    /// Coastal 3C.
    #[value(name = "3C")]
    C3,
    /// Coastal 5C.
    #[value(name = "5C")]
    C5,
    /// Coastal 7C.
    #[value(name = "7C")]
    C7,
    /// Coastal 9C (murkiest).
    #[value(name = "9C")]
    C9,
}

impl From<WaterTypeArg> for uwnr_baselines::WaterType {
    fn from(w: WaterTypeArg) -> Self {
        use uwnr_baselines::WaterType as W;
        match w {
            WaterTypeArg::I => W::I,
            WaterTypeArg::IA => W::IA,
            WaterTypeArg::IB => W::IB,
            WaterTypeArg::II => W::II,
            WaterTypeArg::III => W::III,
            WaterTypeArg::C1 => W::C1,
            WaterTypeArg::C3 => W::C3,
            WaterTypeArg::C5 => W::C5,
            WaterTypeArg::C7 => W::C7,
            WaterTypeArg::C9 => W::C9,
        }
    }
}

/// Colour spaces of `--reinhard-space`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ReinhardSpaceArg {
    /// Ruderman's lαβ, as in the paper.
    #[value(name = "lalphabeta", alias = "lab-ruderman")]
    LAlphaBeta,
    /// CIE L*a*b* (D65).
    #[value(name = "lab", alias = "cielab")]
    Lab,
    /// The stored RGB values.
    Rgb,
}

impl From<ReinhardSpaceArg> for uwnr_baselines::ColourSpace {
    fn from(s: ReinhardSpaceArg) -> Self {
        match s {
            ReinhardSpaceArg::LAlphaBeta => Self::LAlphaBeta,
            ReinhardSpaceArg::Lab => Self::Lab,
            ReinhardSpaceArg::Rgb => Self::Rgb,
        }
    }
}

/// Options of the physical and statistical baselines; each is refused by a method it does not
/// apply to.
#[derive(Debug, Clone, Args)]
pub struct BaselineOpts {
    /// Full parameters of the method as JSON (e.g. `{"method":"jerlov","water_type":"3C"}`, or
    /// `{"method":"uwnr","effects":{}}` for uwnr without its effects stages); the flags below
    /// (and, for uwnr, --weights and the tiling flags) override what it sets. Not for uwgan.
    #[arg(long, value_name = "FILE.json")]
    pub method_config: Option<PathBuf>,
    /// Jerlov water type (with --method jerlov); random per image if absent.
    #[arg(long, value_enum, ignore_case = true, value_name = "TYPE")]
    pub water_type: Option<WaterTypeArg>,
    /// Range MIN,MAX (metres) that a depth map's [0,1] is scaled to, sampled per image (or one
    /// value M). jerlov, seathru: their scene depths. uwnr: the scene scale of relative maps
    /// (the prior, depth models, normalised maps; default 4 m for render, 1.5,8 per pair for
    /// datasets); metric maps keep their own metres.
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_range)]
    pub depth_scale: Option<(f64, f64)>,
    /// Range MIN,MAX (metres) of the background distance, sampled per image.
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_range)]
    pub background_depth: Option<(f64, f64)>,
    /// Where Sea-thru coefficients come from (default: reference when one is given, else sampled).
    #[arg(long, value_enum)]
    pub seathru: Option<SeathruSource>,
    /// Sea-thru direct-signal attenuation R,G,B (1/m), with --seathru given.
    #[arg(long, value_name = "R,G,B", value_parser = parse_triple)]
    pub beta_d: Option<[f64; 3]>,
    /// Sea-thru backscatter coefficient R,G,B (1/m), with --seathru given.
    #[arg(long, value_name = "R,G,B", value_parser = parse_triple)]
    pub beta_b: Option<[f64; 3]>,
    /// Sea-thru veiling light R,G,B in [0,1], with --seathru given.
    #[arg(long, value_name = "R,G,B", value_parser = parse_triple)]
    pub b_inf: Option<[f64; 3]>,
    /// Colour space of the Reinhard transfer (with --method reinhard).
    #[arg(long, value_enum, ignore_case = true, value_name = "SPACE")]
    pub reinhard_space: Option<ReinhardSpaceArg>,
    /// Reinhard: shift the channel means only, without matching the spread (with
    /// `--reinhard-space rgb`, the plain per-channel mean shift baseline).
    #[arg(long)]
    pub mean_only: bool,
}

/// Parses `--depth-unit`: `relative`, `mm`, `m`, or N codes per metre.
pub fn parse_depth_unit(s: &str) -> Result<uwnr_depth::DepthUnit, String> {
    use uwnr_depth::DepthUnit;
    match s.trim().to_ascii_lowercase().as_str() {
        "relative" => Ok(DepthUnit::Relative),
        "mm" | "millimetres" | "millimeters" => Ok(DepthUnit::Millimetres),
        "m" | "metres" | "meters" => Ok(DepthUnit::Metres),
        other => match other.parse::<u32>() {
            Ok(n) if n > 0 => Ok(DepthUnit::CodesPerMetre(n)),
            _ => Err(format!(
                "expected relative, mm, m or a positive number of codes per metre, got {s:?}"
            )),
        },
    }
}

/// Parses `MIN,MAX`, or one value `M` for `M,M`.
pub fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').unwrap_or((s, s));
    let a: f64 = a
        .trim()
        .parse()
        .map_err(|_| format!("bad number in {s:?}"))?;
    let b: f64 = b
        .trim()
        .parse()
        .map_err(|_| format!("bad number in {s:?}"))?;
    if !(a.is_finite() && b.is_finite() && a <= b) {
        return Err(format!("expected finite MIN <= MAX, got {s:?}"));
    }
    Ok((a, b))
}

/// Parses `R,G,B`.
pub fn parse_triple(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected R,G,B numbers, got {s:?}"))?;
    match v.as_slice() {
        [r, g, b] if v.iter().all(|x| x.is_finite()) => Ok([*r, *g, *b]),
        _ => Err(format!("expected three finite numbers R,G,B, got {s:?}")),
    }
}

/// Image format written in directory mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OutFormat {
    Png,
    Jpg,
}

impl OutFormat {
    pub fn extension(self) -> &'static str {
        match self {
            OutFormat::Png => "png",
            OutFormat::Jpg => "jpg",
        }
    }
}

/// Parses `WxH` (e.g. `640x480`).
pub fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, got {s:?}"))?;
    let w: usize = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in {s:?}"))?;
    let h: usize = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in {s:?}"))?;
    if w == 0 || h == 0 {
        return Err(format!("size must be positive, got {s:?}"));
    }
    Ok((w, h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").is_err());
        assert!(parse_size("0x4").is_err());
    }
}
