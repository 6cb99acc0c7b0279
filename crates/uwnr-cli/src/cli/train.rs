//! The arguments of the training wing's commands (the `train` feature): `train`, `enhance`,
//! `gan`, `experiment`, `water`.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};
use uwnr_render::MethodKind;

use super::{BaselineOpts, DepthOpts, DeviceArg, ModelOpts, OutFormat, method_parser};

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
    /// Calibrate the strength of the water-anchored model's pairs to this water (as `uwnr
    /// dataset --target`: a folder of real pairs or of underwater photos); the other methods'
    /// sets are made as without it. Default: the bundled model's real pairs.
    #[arg(long, value_name = "DIR")]
    pub target: Option<PathBuf>,
    /// The camera stage every method's renders go through (as `uwnr dataset --camera`):
    /// `matched`, `typical`, `none`, or a JSON object of blur, read_noise, shot_noise,
    /// jpeg_quality and clean.
    #[arg(long, value_name = "none|matched|typical|JSON", default_value = "matched", value_parser = super::render::parse_camera)]
    pub camera: uwnr_render::Camera,
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
