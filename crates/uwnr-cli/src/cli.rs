//! Command-line definitions (clap derive). Only this crate knows clap.

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand, ValueEnum};
use uwnr_render::{MethodKind, Precision};

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
    Render(RenderArgs),
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

#[derive(Debug, Args)]
pub struct WaterArgs {
    #[command(subcommand)]
    pub action: WaterAction,
}

#[derive(Debug, Subcommand)]
pub enum WaterAction {
    /// Fit the waters of paired folders (underwater/ + clean/) and the regressor; prints how
    /// well the predicted waters reproduce each folder's pairs.
    Fit(WaterFitArgs),
}

#[derive(Debug, Args)]
pub struct WaterFitArgs {
    /// Paired folders to fit (underwater/ and clean/ with the same file names).
    #[arg(required = true, value_name = "PAIRS")]
    pub pairs: Vec<PathBuf>,
    /// Paired folders that are only scored with the fitted regressor (held out).
    #[arg(long, value_name = "PAIRS", num_args = 1..)]
    pub check: Vec<PathBuf>,
    /// The bank to write (JSON).
    #[arg(long, short, value_name = "FILE")]
    pub output: PathBuf,
}

#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Folder of clean photos (searched recursively, as `uwnr dataset --clean` lists them).
    #[arg(long, value_name = "DIR")]
    pub clean: PathBuf,
    /// Folder of real underwater references (searched recursively).
    #[arg(long, value_name = "DIR")]
    pub references: PathBuf,
    /// Port to listen on (0: any free port).
    #[arg(long, default_value_t = uwnr_serve::DEFAULT_PORT)]
    pub port: u16,
    /// Address to listen on. The default serves this machine only; another address exposes the
    /// page (and your photos) to the network.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: std::net::IpAddr,
    /// Longer side of the previews, pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = uwnr_serve::DEFAULT_PREVIEW_SIZE)]
    pub preview_size: usize,
    /// Largest dropped file, MiB.
    #[arg(long, value_name = "MIB", default_value_t = uwnr_serve::DEFAULT_MAX_UPLOAD_BYTES / (1024 * 1024))]
    pub max_upload_mb: u64,
    /// Largest image accepted (dropped or in the folders), pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = uwnr_serve::DEFAULT_MAX_PIXELS)]
    pub max_pixels: u64,
    /// Largest side of an image accepted, pixels.
    #[arg(long, value_name = "PIXELS", default_value_t = uwnr_serve::DEFAULT_MAX_DIMENSION)]
    pub max_dimension: u32,
    /// Render threads (default: the CPU cores, at most 4).
    #[arg(long, value_name = "N")]
    pub workers: Option<usize>,
    /// Renders waiting before new requests are refused (HTTP 503, shown in the page).
    #[arg(long, value_name = "N", default_value_t = uwnr_serve::DEFAULT_QUEUE)]
    pub queue: usize,
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
    /// Images with more pixels than this are rendered in overlapping tiles (memory stays bounded).
    #[arg(long, value_name = "PIXELS", default_value_t = 1_048_576)]
    pub max_whole_pixels: usize,
    /// Tile edge in pixels for tiled rendering (a multiple of 16).
    #[arg(long, value_name = "PIXELS", default_value_t = 1024)]
    pub tile: usize,
    /// Overlap between tiles in pixels (a multiple of 16); at 192 or more the blend stays outside
    /// the network's 76-pixel reach from a cut edge, so tiled output equals whole-image output.
    #[arg(long, value_name = "PIXELS", default_value_t = 192)]
    pub overlap: usize,
}

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Clean images (files or directories of images).
    #[arg(required = true, value_name = "CLEAN")]
    pub clean: Vec<PathBuf>,
    /// Real underwater reference images (files or directories) whose style is rendered
    /// (needed by every method but jerlov and seathru with sampled or given coefficients).
    #[arg(long, short = 'r', num_args = 1.., value_name = "REF")]
    pub reference: Vec<PathBuf>,
    /// Rendering method: the UWNR network or a physical / statistical baseline.
    #[arg(long, value_parser = method_parser(), default_value = "uwnr")]
    pub method: MethodKind,
    #[command(flatten)]
    pub baseline: BaselineOpts,
    /// Output image file (one clean image, one reference) or output directory.
    #[arg(long, short = 'o', value_name = "PATH")]
    pub output: PathBuf,
    /// How clean images are paired with references.
    #[arg(long, value_enum, default_value_t = Pairing::Cycle)]
    pub pairing: Pairing,
    /// Seed for random pairing.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output format in directory mode.
    #[arg(long, value_enum, default_value_t = OutFormat::Png)]
    pub format: OutFormat,
    #[command(flatten)]
    pub depth: DepthOpts,
    #[command(flatten)]
    pub model: ModelOpts,
    /// Arithmetic of the network's convolutions (bf16 on the engine only).
    #[arg(long, value_enum, default_value_t = PrecisionArg::F32)]
    pub precision: PrecisionArg,
}

/// The parser of `--method` and `--methods`: the methods of `uwnr-render`, each with its one-line
/// summary in `--help`.
fn method_parser() -> impl TypedValueParser<Value = MethodKind> {
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
    /// Full parameters of the baseline as JSON (e.g. `{"method":"jerlov","water_type":"3C"}`);
    /// the flags below override what it sets.
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

#[derive(Debug, Args)]
pub struct ExperimentArgs {
    #[command(subcommand)]
    pub action: ExperimentAction,
}

#[derive(Debug, Subcommand)]
pub enum ExperimentAction {
    /// Render one training set per method from the same clean images and references, train
    /// Shallow-UWnet on each with the same budget, score each on real paired test sets, and
    /// write OUT/results.md, OUT/results.json and OUT/examples.png (the paper's Table 1).
    Downstream(Box<DownstreamArgs>),
}

#[derive(Debug, Args)]
pub struct DownstreamArgs {
    /// Clean images: files or folders (searched recursively).
    #[arg(long, num_args = 1.., value_name = "DIR|FILE")]
    pub clean: Vec<PathBuf>,
    /// Real underwater references: files or folders (searched recursively).
    #[arg(long, num_args = 1.., value_name = "DIR|FILE")]
    pub references: Vec<PathBuf>,
    /// Real paired test sets (underwater/ + clean/).
    #[arg(long, num_args = 1.., value_name = "DIR", required = true)]
    pub test: Vec<PathBuf>,
    /// Real paired training sets, trained on with the same budget as reference rows.
    #[arg(long, num_args = 1.., value_name = "DIR")]
    pub real: Vec<PathBuf>,
    /// Output folder (run the same command again to continue).
    #[arg(long, short = 'o', value_name = "OUT", required = true)]
    pub out: PathBuf,
    /// Rendering methods, one training set each.
    #[arg(
        long,
        value_parser = method_parser(),
        value_delimiter = ',',
        default_value = "uwnr,uwgan,jerlov,uisa,seathru,reinhard"
    )]
    pub methods: Vec<MethodKind>,
    /// Renders per clean image, each after a different reference.
    #[arg(long, short = 'k', value_name = "K", default_value_t = 4)]
    pub per_image: usize,
    /// Size of the synthetic pairs: native or WxH (scaled to cover, centre-cropped).
    #[arg(long, value_name = "native|WxH", default_value = "256x256")]
    pub size: uwnr_dataset::Size,
    /// Seed of the reference draw, the methods' parameters and training.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Training samples each network sees (the same for every training set).
    #[arg(long, value_name = "SAMPLES", default_value_t = 6000)]
    pub budget: usize,
    /// Enhancer training config (JSON, see `uwnr enhance train`); epochs and learning-rate
    /// steps are set from the budget.
    #[arg(long, value_name = "FILE")]
    pub enhance_config: Option<PathBuf>,
    /// Override: enhancer crop side (default 128, or the --enhance-config file's).
    #[arg(long)]
    pub crop: Option<usize>,
    /// Override: enhancer batch size.
    #[arg(long)]
    pub batch_size: Option<usize>,
    /// VGG19 weights (safetensors, torchvision keys) for the enhancer's perceptual term.
    #[arg(long, value_name = "FILE")]
    pub vgg19: Option<PathBuf>,
    /// Test images with a longer side above this are downscaled to it before scoring
    /// (0 = score at native size).
    #[arg(long, value_name = "PIXELS", default_value_t = 512)]
    pub eval_max_side: usize,
    /// Test images per test set shown in examples.png.
    #[arg(long, value_name = "N", default_value_t = 2)]
    pub examples: usize,
    /// Rendering threads (default: the number of CPU cores).
    #[arg(long, short = 'j', value_name = "J")]
    pub jobs: Option<usize>,
    #[command(flatten)]
    pub baseline: BaselineOpts,
    #[command(flatten)]
    pub depth: DepthOpts,
    #[command(flatten)]
    pub model: ModelOpts,
    /// GAN generator for the uwgan set (`generator.safetensors` of a `uwnr gan train` run);
    /// default the bundled one. (--weights is the UWNR network's.)
    #[arg(long, value_name = "FILE")]
    pub gan_weights: Option<PathBuf>,
}

#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct DatasetArgs {
    #[command(subcommand)]
    pub action: Option<DatasetAction>,
    #[command(flatten)]
    pub make: DatasetMakeArgs,
}

#[derive(Debug, Subcommand)]
pub enum DatasetAction {
    /// Check a dataset folder: every manifest line, every file (present, decodable, recorded
    /// size), no stray files, no missing pairs. Exits non-zero and lists what is wrong.
    Verify {
        /// The dataset folder.
        #[arg(value_name = "OUT")]
        out: PathBuf,
    },
    /// Join the shards of a dataset into one manifest.jsonl (shards written into OUT, or into
    /// the folders named after it, whose pairs are copied into OUT).
    Merge {
        /// The dataset folder to complete.
        #[arg(value_name = "OUT")]
        out: PathBuf,
        /// Folders of shards that wrote elsewhere.
        #[arg(value_name = "SHARD_DIR")]
        sources: Vec<PathBuf>,
        /// Skip preview.png and index.html.
        #[arg(long)]
        no_gallery: bool,
    },
    /// Pack a finished dataset folder into WebDataset tar shards (OUT/webdataset/ by default):
    /// per pair the images, labels and manifest line, deterministic for the same folder.
    Export {
        /// The dataset folder (merged, if it was made in shards).
        #[arg(value_name = "OUT")]
        out: PathBuf,
        /// Where to write the shards (default OUT/webdataset).
        #[arg(long, value_name = "DIR")]
        to: Option<PathBuf>,
        /// Largest shard, e.g. 512M or 2G (a pair never spans two shards).
        #[arg(long, value_name = "SIZE", default_value = "512M", value_parser = uwnr_dataset::webdataset::parse_size)]
        shard_size: u64,
    },
}

/// How `uwnr dataset` delivers the pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DatasetFormat {
    /// Folders of PNG files (underwater/, clean/, labels/...) with manifest.jsonl.
    Folder,
    /// The folders, then WebDataset tar shards of them in OUT/webdataset/ when the run ends.
    Webdataset,
}

#[derive(Debug, Args)]
pub struct DatasetMakeArgs {
    /// Clean images: files or folders (searched recursively).
    #[arg(long, num_args = 1.., value_name = "DIR|FILE", required = true)]
    pub clean: Vec<PathBuf>,
    /// Real underwater references: files or folders (searched recursively).
    #[arg(long, num_args = 1.., value_name = "DIR|FILE")]
    pub references: Vec<PathBuf>,
    /// Output folder (created; run the same command again to resume).
    #[arg(long, short = 'o', value_name = "OUT", required = true)]
    pub output: Option<PathBuf>,
    /// Renders per clean image, each after a different reference (drawn without replacement).
    #[arg(long, short = 'k', value_name = "K", default_value_t = 1)]
    pub per_image: usize,
    /// Rendering method.
    #[arg(long, value_parser = method_parser(), default_value = "uwnr")]
    pub method: MethodKind,
    #[command(flatten)]
    pub baseline: BaselineOpts,
    /// Seed of the reference draw and of the baselines' random parameters.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Render only shard I of N (0-based), e.g. 3/8; join shards with `uwnr dataset merge`.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<uwnr_dataset::Shard>,
    /// Pair size: native (each clean image's own) or WxH (scaled to cover, centre-cropped).
    #[arg(long, value_name = "native|WxH", default_value = "native")]
    pub size: uwnr_dataset::Size,
    /// Worker threads (default: the number of CPU cores).
    #[arg(long, short = 'j', value_name = "J")]
    pub jobs: Option<usize>,
    /// Also write depth/NAME_k.png (16-bit, bright = far).
    #[arg(long)]
    pub save_depth: bool,
    /// Also write lightfield/NAME_k.png (the light field the network saw).
    #[arg(long)]
    pub save_lightfield: bool,
    /// Skip preview.png and index.html.
    #[arg(long)]
    pub no_gallery: bool,
    /// COCO instances file of the clean images: written for every pair (labels/NAME_k.json and
    /// OUT/coco.json), boxes, polygons, RLE masks and keypoints scaled and cropped with --size.
    #[arg(long, value_name = "FILE", conflicts_with = "yolo")]
    pub coco: Option<PathBuf>,
    /// Folder of YOLO label files (NAME.txt, matched by the path below --clean, else by name):
    /// written for every pair as labels/NAME_k.txt.
    #[arg(long, value_name = "DIR")]
    pub yolo: Option<PathBuf>,
    /// Folder of segmentation label PNGs (matched like --yolo): written for every pair as
    /// masks/NAME_k.png, resized by nearest neighbour, values unchanged.
    #[arg(long, value_name = "DIR")]
    pub masks: Option<PathBuf>,
    /// Calibrate the strength of the pairs (PSNR(underwater, clean)) to your own water: a folder
    /// of real pairs (underwater/ + clean/: their strengths and colour shifts are matched) or of
    /// underwater photos (their waters are read off their statistics). Default: the real UIEB and
    /// LSUI training pairs the bundled water bank was fitted on. Needs a water-anchored model.
    #[arg(long, value_name = "DIR")]
    pub target: Option<PathBuf>,
    /// Output format: folders only, or folders then WebDataset tar shards.
    #[arg(long, value_enum, default_value_t = DatasetFormat::Folder)]
    pub format: DatasetFormat,
    /// Largest WebDataset shard with --format webdataset, e.g. 512M or 2G.
    #[arg(long, value_name = "SIZE", default_value = "512M", value_parser = uwnr_dataset::webdataset::parse_size)]
    pub shard_size: u64,
    #[command(flatten)]
    pub depth: DepthOpts,
    #[command(flatten)]
    pub model: ModelOpts,
    /// Arithmetic of the network's convolutions (bf16 on the engine only).
    #[arg(long, value_enum, default_value_t = PrecisionArg::F32)]
    pub precision: PrecisionArg,
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

#[derive(Debug, Args)]
pub struct LightfieldArgs {
    /// Reference underwater image.
    #[arg(value_name = "REF")]
    pub reference: PathBuf,
    /// Output image (PNG or JPEG by extension).
    #[arg(long, short = 'o', value_name = "MAP.png")]
    pub output: PathBuf,
    /// Write the map at this size WxH instead of the 256x256 the network's style is computed at.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    pub size: Option<(usize, usize)>,
    /// Normalisation: `paper` (min-max over the map, as the released code) or `absolute` (a fixed
    /// range, so the reference's brightness is kept; what the bundled model is fed).
    #[arg(long, value_name = "MAP", default_value = "paper")]
    pub map: uwnr_core::lightfield::LightFieldMap,
}

#[derive(Debug, Args)]
pub struct DepthArgs {
    /// Clean image.
    #[arg(value_name = "CLEAN")]
    pub clean: PathBuf,
    /// Output grey image (PNG or JPEG by extension); bright = far.
    #[arg(long, short = 'o', value_name = "DEPTH.png")]
    pub output: PathBuf,
    #[command(flatten)]
    pub depth: DepthOpts,
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Weights to describe (default: the bundled model, if this build has one).
    #[arg(long, value_name = "FILE")]
    pub weights: Option<PathBuf>,
    /// Image size WxH for the GMac figure.
    #[arg(long, value_name = "WxH", value_parser = parse_size, default_value = "256x256")]
    pub size: (usize, usize),
    /// Base width of the architecture when no weights are given.
    #[arg(long, default_value_t = 64)]
    pub base_width: usize,
}

#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// Weights to read: safetensors, or the authors' checkpoint (`torch.save({'G1': ...})`).
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// Safetensors file to write.
    #[arg(value_name = "OUT.safetensors")]
    pub output: PathBuf,
    /// Precision of the written tensors.
    #[arg(long, value_enum, default_value_t = DtypeArg::F32)]
    pub dtype: DtypeArg,
    /// Provenance recorded in the file's metadata (`uwnr.source`); default: kept from the
    /// input, or the input's file name.
    #[arg(long, value_name = "TEXT")]
    pub source: Option<String>,
}

/// Tensor precision of written weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DtypeArg {
    F32,
    F16,
    Bf16,
}

/// Light-field loss variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LightFieldLossArg {
    /// The paper's multi-scale Gaussian light-field maps of output and target, L1.
    Paper,
    /// The released code's behaviour (blur radius 0): a plain L1.
    Released,
}

/// The data arguments of the paired trainers (`uwnr train`, `uwnr enhance train`), and the run
/// options every trainer shares.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Training folders, each with `underwater/` + `clean/` (or `raw-890/` + `reference-890/`)
    /// matched by file name (`uwnr train` also reads an optional `depth/`).
    #[arg(long, required = true, num_args = 1.., value_name = "DIR")]
    pub data: Vec<PathBuf>,
    /// Validation folder (same layout), scored at native resolution (PSNR/SSIM).
    #[arg(long, value_name = "DIR")]
    pub val: Option<PathBuf>,
    /// VGG19 weights (safetensors, torchvision keys `features.N.weight`) for the perceptual loss;
    /// without them a 1 - SSIM structure term stands in.
    #[arg(long, value_name = "FILE")]
    pub vgg19: Option<PathBuf>,
    #[command(flatten)]
    pub opts: RunOpts,
}

/// The run options every trainer shares (`uwnr train`, `uwnr enhance train`, `uwnr gan train`).
#[derive(Debug, Args)]
pub struct RunOpts {
    /// Run folder: config, logs, curves, contact sheets, checkpoints.
    #[arg(long, value_name = "RUN_DIR")]
    pub run: PathBuf,
    /// Training config (JSON); fields not given keep their defaults.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Continue the run in --run from its last checkpoint (its config.json is used).
    #[arg(long)]
    pub resume: bool,
    /// Compute device.
    #[arg(long, value_enum, default_value_t = DeviceArg::Flex)]
    pub device: DeviceArg,
    /// Override: epochs.
    #[arg(long)]
    pub epochs: Option<usize>,
    /// Override: batch size.
    #[arg(long)]
    pub batch_size: Option<usize>,
    /// Override: crop side.
    #[arg(long)]
    pub crop: Option<usize>,
    /// Override: seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override: learning rate.
    #[arg(long)]
    pub lr: Option<f64>,
    /// Override: validate every N epochs.
    #[arg(long, value_name = "N")]
    pub val_every: Option<usize>,
    /// Stop (with a checkpoint) after this many steps in this session.
    #[arg(long, value_name = "N")]
    pub max_steps: Option<usize>,
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    #[command(flatten)]
    pub common: RunArgs,
    /// Override: base width of the generator (64 = the paper's network).
    #[arg(long)]
    pub width: Option<usize>,
    /// Override: light-field loss variant.
    #[arg(long, value_enum)]
    pub light_field_loss: Option<LightFieldLossArg>,
    /// Override: the light-field map the network is fed, `paper` (min-max, the released code) or
    /// `absolute` (keeps the reference's brightness); recorded in the weights' config.
    #[arg(long, value_name = "MAP")]
    pub light_field_map: Option<uwnr_core::lightfield::LightFieldMap>,
    /// Override: enable the colour-cast augmentation with its default ranges.
    #[arg(long)]
    pub color_cast: bool,
    /// PSNR reference lines for the validation curve (e.g. baselines), comma-separated.
    #[arg(long, value_name = "DB,...", value_delimiter = ',')]
    pub val_refs: Vec<f64>,
}

#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Predictions (full-reference mode), paired with --target by file stem.
    #[arg(
        long,
        value_name = "DIR",
        requires = "target",
        conflicts_with = "images"
    )]
    pub pred: Option<PathBuf>,
    /// Targets (full-reference mode).
    #[arg(long, value_name = "DIR", requires = "pred")]
    pub target: Option<PathBuf>,
    /// Images to score without reference (UIQM, UCIQE; distances with --real).
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    /// Real images to compare the --images set with (Frechet distance and KID).
    #[arg(long, value_name = "DIR", requires = "images")]
    pub real: Option<PathBuf>,
    /// InceptionV3 ONNX model (pool3 output) for FID/KID; without it the built-in
    /// colour-texture features are used (reported as FD-ct / KID-ct, not FID).
    #[arg(long, value_name = "FILE.onnx", requires = "real")]
    pub inception: Option<PathBuf>,
    /// PSNR and SSIM on luma (ITU-R BT.601) instead of RGB.
    #[arg(long)]
    pub gray: bool,
    /// Seed for KID's subset sampling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write means, set metrics and per-image scores as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write per-image scores as CSV.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct EnhanceArgs {
    #[command(subcommand)]
    pub action: EnhanceAction,
}

#[derive(Debug, Subcommand)]
pub enum EnhanceAction {
    /// Train Shallow-UWnet on paired folders (underwater/ -> clean/), with exact resume.
    Train(EnhanceTrainArgs),
    /// Enhance underwater images (files or folders) with trained weights.
    Apply(EnhanceApplyArgs),
    /// Score weights, or no enhancement, on a paired test folder (PSNR, SSIM, UIQM, UCIQE).
    Eval(EnhanceEvalArgs),
}

#[derive(Debug, Args)]
pub struct EnhanceTrainArgs {
    #[command(flatten)]
    pub common: RunArgs,
}

#[derive(Debug, Args)]
pub struct EnhanceApplyArgs {
    /// Underwater images (files or directories of images).
    #[arg(required = true, value_name = "IMAGES")]
    pub images: Vec<PathBuf>,
    /// Enhancer weights (`enhancer.safetensors` of a run, or a Shallow-UWnet state dict).
    #[arg(long, value_name = "FILE")]
    pub weights: PathBuf,
    /// Output image file (one input image) or output directory.
    #[arg(long, short = 'o', value_name = "PATH")]
    pub output: PathBuf,
    /// Output format in directory mode.
    #[arg(long, value_enum, default_value_t = OutFormat::Png)]
    pub format: OutFormat,
    /// Compute device.
    #[arg(long, value_enum, default_value_t = DeviceArg::Flex)]
    pub device: DeviceArg,
}

#[derive(Debug, Args)]
pub struct EnhanceEvalArgs {
    /// Enhancer weights; without them the underwater input itself is scored (no enhancement).
    #[arg(long, value_name = "FILE")]
    pub weights: Option<PathBuf>,
    /// Paired test folder (`underwater/` + `clean/`, or `raw-890/` + `reference-890/`).
    #[arg(long, value_name = "DIR")]
    pub data: PathBuf,
    /// Write each output there as STEM.png.
    #[arg(long, value_name = "DIR")]
    pub save: Option<PathBuf>,
    /// Downscale pairs whose longer side exceeds N pixels (aspect kept) before enhancing and
    /// scoring.
    #[arg(long, value_name = "N")]
    pub max_side: Option<usize>,
    /// Write the scores (per image and means) as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Compute device.
    #[arg(long, value_enum, default_value_t = DeviceArg::Flex)]
    pub device: DeviceArg,
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

#[derive(Debug, Args)]
pub struct GanArgs {
    #[command(subcommand)]
    pub action: GanAction,
}

#[derive(Debug, Subcommand)]
pub enum GanAction {
    /// Train the GAN baseline on unpaired folders (clean in-air images with depth, real
    /// underwater references), with exact resume.
    Train(GanTrainArgs),
}

#[derive(Debug, Args)]
pub struct GanTrainArgs {
    /// Clean in-air folders: `rgb/` + `depth/` (RGB-D sets), a paired folder's `clean/`, or
    /// images directly in the folder (depth from a `depth/` subfolder or the built-in prior).
    #[arg(long, required = true, num_args = 1.., value_name = "DIR")]
    pub clean: Vec<PathBuf>,
    /// Real underwater folders: a paired folder's `underwater/`, UIEB's `raw-890/`, or images
    /// directly in the folder.
    #[arg(long, required = true, num_args = 1.., value_name = "DIR")]
    pub references: Vec<PathBuf>,
    #[command(flatten)]
    pub opts: RunOpts,
    /// Override: the adversarial loss.
    #[arg(long, value_enum)]
    pub loss: Option<GanLossArg>,
}

/// Adversarial losses of `uwnr gan train --loss`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GanLossArg {
    /// Sigmoid cross-entropy, the generator's non-saturating objective (UWGAN, WaterGAN).
    NonSaturating,
    /// Least squares (LSGAN).
    LeastSquares,
}
