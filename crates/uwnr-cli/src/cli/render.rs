//! The arguments of the render wing's commands: `render`, `dataset`, `eval`, `serve`,
//! `lightfield`, `depth`, `info`, `convert`.

use std::path::PathBuf;

use clap::{Args, Subcommand, ValueEnum};
use uwnr_render::MethodKind;

use super::{
    BaselineOpts, DepthOpts, ModelOpts, OutFormat, Pairing, PrecisionArg, method_parser, parse_size,
};

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
    /// Memory that decodes and renders in flight may hold together, MiB; beyond, requests are
    /// answered 503 and renders wait.
    #[arg(long, value_name = "MIB", default_value_t = uwnr_serve::DEFAULT_MEMORY_BYTES / (1024 * 1024))]
    pub memory_mb: u64,
    /// A host name the page may be reached by besides localhost and this machine's addresses
    /// (repeat for several): requests naming any other host are refused (DNS rebinding).
    #[arg(long, value_name = "NAME")]
    pub allow_host: Vec<String>,
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
    /// Rendering method: uwnr's model, the GAN baseline, or a physical / statistical baseline.
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
    /// The camera stage every underwater render goes through, whatever the method: `matched`
    /// (the fine detail and noise of real underwater photos: 0.4 px lens blur at 256 px, read and
    /// shot noise, JPEG at quality 80), `typical` (a heavier camera: 0.8 px, JPEG at 70), `none`,
    /// or a JSON object of blur, read_noise, shot_noise, jpeg_quality and clean (none, lens or
    /// camera: what the camera does to the clean side; a real pair's clean side has it all; missing
    /// fields take `matched`'s values). Recorded in dataset.json.
    #[arg(long, value_name = "none|matched|typical|JSON", default_value = "matched", value_parser = parse_camera)]
    pub camera: uwnr_render::Camera,
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

pub(crate) fn parse_camera(text: &str) -> Result<uwnr_render::Camera, String> {
    uwnr_render::Camera::parse(text).map_err(|e| e.to_string())
}
