//! `uwnr._uwnr`: the native half of the `uwnr` Python package (PyO3): the UWNR renderer (the
//! bundled model or any weights), the physical and statistical baselines, the light field map, the
//! built-in depth prior and the field's metrics, computed by the same library calls as the `uwnr`
//! command line, so the same inputs give the same pixels.
//!
//! Pixels cross the boundary as contiguous interleaved bytes with their shape: 8-bit codes
//! (read as `code / 255`, as the image decoder does) or native-endian f32 in [0, 1]. The module
//! therefore needs no NumPy C API and works with any NumPy; the Python half (`uwnr/__init__.py`)
//! checks shapes, dtypes and value ranges and turns arrays, PIL images and torch tensors into
//! those bytes and back.
//!
//! Every computation runs with the GIL released, inside a rayon pool owned by the current
//! process. A pool inherited through `fork` (a PyTorch DataLoader worker) has no threads left, so
//! a forked child builds its own on first use instead of waiting on the parent's forever. Panics
//! are caught and raised as `uwnr.Error`; they never reach the interpreter.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;
use serde_json::Value;

use uwnr_baselines::{
    Method, ReferenceCoefficients, RenderInput, SampledCoefficients, SeathruCoefficients,
};
use uwnr_core::Image;
use uwnr_core::lightfield::{LightFieldMap, light_field_with};
use uwnr_dataset::DepthPolicy;
use uwnr_dataset::renderer::{ReferenceInput, Renderer as DatasetRenderer};
use uwnr_model::{GeneratorConfig, ReferenceStyle, RenderOptions};

create_exception!(
    _uwnr,
    Error,
    PyException,
    "A weights, model or rendering problem in uwnr (bad input raises ValueError instead)."
);

/// Channels of an RGB image.
const RGB: usize = 3;
/// Bytes of one f32 sample.
const F32_BYTES: usize = 4;
/// The methods `Renderer` knows, in the order the docs list them.
const METHODS: [&str; 6] = ["uwnr", "uwgan", "jerlov", "uisa", "seathru", "reinhard"];

/// A failure inside a computation, sorted by the Python exception it becomes.
enum Failure {
    /// Bad input: `ValueError`.
    Value(String),
    /// A model or rendering problem: `uwnr.Error`.
    Model(String),
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> Self {
        match f {
            Failure::Value(m) => PyValueError::new_err(m),
            Failure::Model(m) => Error::new_err(m),
        }
    }
}

fn value(e: impl std::fmt::Display) -> Failure {
    Failure::Value(e.to_string())
}

fn model(e: impl std::fmt::Display) -> Failure {
    Failure::Model(e.to_string())
}

/// The sample type of pixel bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dtype {
    /// 8-bit codes, `code / 255`.
    U8,
    /// Native-endian f32 in [0, 1].
    F32,
}

impl Dtype {
    fn parse(name: &str) -> Result<Self, Failure> {
        match name {
            "uint8" => Ok(Self::U8),
            "float32" => Ok(Self::F32),
            other => Err(Failure::Value(format!(
                "pixel dtype {other:?} is not supported (uint8 or float32)"
            ))),
        }
    }
}

/// Pixels as the Python half passes them: `(bytes, height, width, channels, dtype)`.
#[derive(FromPyObject)]
struct Pixels<'py>(Bound<'py, PyBytes>, usize, usize, usize, String);

/// The same pixels, borrowed for use without the GIL.
struct PixelView<'a> {
    data: &'a [u8],
    height: usize,
    width: usize,
    channels: usize,
    dtype: Dtype,
}

impl<'py> Pixels<'py> {
    fn view(&self) -> Result<PixelView<'_>, Failure> {
        Ok(PixelView {
            data: self.0.as_bytes(),
            height: self.1,
            width: self.2,
            channels: self.3,
            dtype: Dtype::parse(&self.4)?,
        })
    }
}

impl PixelView<'_> {
    /// Decodes the bytes into a planar f32 image in [0, 1].
    fn image(&self) -> Result<Image, Failure> {
        let (h, w, c) = (self.height, self.width, self.channels);
        if h == 0 || w == 0 {
            return Err(Failure::Value(format!("image is empty ({h}x{w})")));
        }
        let n = h
            .checked_mul(w)
            .and_then(|p| p.checked_mul(c))
            .ok_or_else(|| Failure::Value(format!("image shape {h}x{w}x{c} is too large")))?;
        let values: Vec<f32> = match self.dtype {
            Dtype::U8 => {
                check_len(self.data.len(), n, h, w, c)?;
                self.data
                    .iter()
                    .map(|&v| f32::from(v) / f32::from(u8::MAX))
                    .collect()
            }
            Dtype::F32 => {
                check_len(self.data.len(), n * F32_BYTES, h, w, c)?;
                self.data
                    .chunks_exact(F32_BYTES)
                    .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
                    .collect()
            }
        };
        Image::from_interleaved(w, h, c, &values).map_err(value)
    }
}

fn check_len(got: usize, expected: usize, h: usize, w: usize, c: usize) -> Result<(), Failure> {
    if got == expected {
        Ok(())
    } else {
        Err(Failure::Value(format!(
            "pixel buffer has {got} bytes, {expected} expected for shape {h}x{w}x{c}"
        )))
    }
}

/// Interleaved bytes of `img` in `dtype` (8-bit with the encoder's rounding, so a uint8 result
/// equals the PNG `uwnr render` writes).
fn image_bytes<'py>(py: Python<'py>, img: &Image, dtype: Dtype) -> Bound<'py, PyBytes> {
    match dtype {
        Dtype::U8 => PyBytes::new(py, &uwnr_core::io::to_rgb8(img)),
        Dtype::F32 => {
            let hwc = img.to_interleaved();
            let mut bytes = Vec::with_capacity(hwc.len() * F32_BYTES);
            for v in hwc {
                bytes.extend_from_slice(&v.to_ne_bytes());
            }
            PyBytes::new(py, &bytes)
        }
    }
}

/// The rayon pool of this process (rebuilt in a forked child, whose inherited pool has no
/// threads). `RAYON_NUM_THREADS` sets its size, as for rayon's global pool.
fn process_pool() -> Result<Arc<rayon::ThreadPool>, Failure> {
    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut slot = POOL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some((owner, pool)) = slot.as_ref()
        && *owner == pid
    {
        return Ok(pool.clone());
    }
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("uwnr-{i}"))
            .build()
            .map_err(|e| model(format!("starting the thread pool: {e}")))?,
    );
    *slot = Some((pid, pool.clone()));
    Ok(pool)
}

/// Runs `f` without the GIL in this process's pool, turning a panic into `uwnr.Error`.
fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> Result<T, Failure> + Send) -> PyResult<T> {
    py.detach(|| {
        let pool = process_pool()?;
        catch_unwind(AssertUnwindSafe(|| pool.install(f))).unwrap_or_else(|panic| {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown cause");
            Err(Failure::Model(format!("internal error: {what}")))
        })
    })
    .map_err(PyErr::from)
}

fn parse_map(name: &str) -> Result<LightFieldMap, Failure> {
    name.parse::<LightFieldMap>().map_err(value)
}

/// A real underwater reference, decoded once, with its light field maps computed on first use
/// and kept (one per normalisation).
#[pyclass(frozen, module = "uwnr._uwnr")]
struct NativeReference {
    image: Image,
    paper: OnceLock<Result<Image, String>>,
    absolute: OnceLock<Result<Image, String>>,
    water: OnceLock<Result<uwnr_model::Water, String>>,
    detail: OnceLock<[f32; 3]>,
}

impl NativeReference {
    /// The 256x256 light field map of this reference under `map`.
    fn field(&self, map: LightFieldMap) -> Result<&Image, Failure> {
        let cell = match map {
            LightFieldMap::Paper => &self.paper,
            LightFieldMap::Absolute => &self.absolute,
        };
        cell.get_or_init(|| light_field_with(&self.image, map).map_err(|e| e.to_string()))
            .as_ref()
            .map_err(|e| Failure::Model(format!("light field of the reference: {e}")))
    }

    /// What a network with `config` takes of this reference.
    fn style(&self, config: &GeneratorConfig) -> Result<ReferenceStyle, Failure> {
        let light_field = self.field(config.light_field)?.clone();
        let water = match config.variant {
            uwnr_model::Variant::Paper => None,
            uwnr_model::Variant::Anchored => {
                let water = *self
                    .water
                    .get_or_init(|| {
                        uwnr_model::style::estimate_water(&self.image).map_err(|e| e.to_string())
                    })
                    .as_ref()
                    .map_err(|e| Failure::Model(format!("water of the reference: {e}")))?;
                let detail = config.detail_retention.then(|| {
                    *self
                        .detail
                        .get_or_init(|| uwnr_model::style::detail_share(&self.image))
                });
                Some(uwnr_model::Water { detail, ..water })
            }
        };
        Ok(ReferenceStyle { light_field, water })
    }
}

#[pymethods]
impl NativeReference {
    #[new]
    fn new(py: Python<'_>, pixels: Pixels<'_>) -> PyResult<Self> {
        let view = pixels.view()?;
        let image = compute(py, || rgb_image(&view))?;
        Ok(Self {
            image,
            paper: OnceLock::new(),
            absolute: OnceLock::new(),
            water: OnceLock::new(),
            detail: OnceLock::new(),
        })
    }

    #[getter]
    fn width(&self) -> usize {
        self.image.width()
    }

    #[getter]
    fn height(&self) -> usize {
        self.image.height()
    }

    /// The 256x256x3 light field map as f32 bytes.
    fn light_field<'py>(&self, py: Python<'py>, map: &str) -> PyResult<Bound<'py, PyBytes>> {
        let map = parse_map(map)?;
        let field = compute(py, || self.field(map).cloned())?;
        Ok(image_bytes(py, &field, Dtype::F32))
    }

    /// The reference's pixels as f32 bytes (height x width x 3).
    fn pixels<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        image_bytes(py, &self.image, Dtype::F32)
    }
}

fn rgb_image(view: &PixelView<'_>) -> Result<Image, Failure> {
    if view.channels != RGB {
        return Err(Failure::Value(format!(
            "expected {RGB} channels, got {}",
            view.channels
        )));
    }
    view.image()
}

/// What renders.
enum Kind {
    /// The UWNR network, with the config its weights were trained with.
    Network {
        renderer: DatasetRenderer,
        config: GeneratorConfig,
    },
    /// The UWGAN-style GAN baseline (it reads no reference; the water code comes from the
    /// item's seed).
    Gan { renderer: DatasetRenderer },
    /// A baseline; `without_reference` is the variant used when a call gives no reference
    /// (Sea-thru with no coefficients chosen: fitted from the reference when there is one,
    /// sampled on the Jerlov manifold otherwise, as `uwnr render` does).
    Baseline {
        method: Method,
        without_reference: Option<Method>,
    },
}

/// What a depth map passed from Python stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DepthUnitArg {
    /// uwnr's absolute [0, 1]: 0 at the camera, 1 far away (the default).
    Absolute,
    /// Relative: only differences within the image act, over the renderer's scene scale.
    Relative,
    /// Metres (holes as 0 or NaN are filled from their neighbours).
    Metres,
}

impl DepthUnitArg {
    fn parse(name: &str) -> Result<Self, Failure> {
        match name {
            "absolute" => Ok(Self::Absolute),
            "relative" => Ok(Self::Relative),
            "m" => Ok(Self::Metres),
            other => Err(Failure::Value(format!(
                "depth_unit {other:?} is not one of absolute, relative, m, mm"
            ))),
        }
    }
}

/// A loaded renderer: the network (weights loaded once) or a baseline with its parameters.
#[pyclass(frozen, module = "uwnr._uwnr")]
struct NativeRenderer {
    kind: Kind,
    seed: u64,
    /// The network's scene scale and trust in the prior (`scene_scale`, `prior_trust`).
    policy: DepthPolicy,
    /// Where the weights came from, or the baseline's parameters as JSON.
    source: String,
}

/// One item of `render_batch` as Python passes it: clean pixels, reference, depth.
type BatchItem<'py> = (
    Pixels<'py>,
    Option<Bound<'py, NativeReference>>,
    Option<Pixels<'py>>,
);

/// One item of a render: the clean image, its reference and optional depth.
struct Job<'a> {
    clean: PixelView<'a>,
    reference: Option<&'a NativeReference>,
    depth: Option<PixelView<'a>>,
    depth_unit: DepthUnitArg,
    seed: u64,
}

impl NativeRenderer {
    fn method_name(&self) -> &'static str {
        match &self.kind {
            Kind::Network { .. } => "uwnr",
            Kind::Gan { .. } => "uwgan",
            Kind::Baseline { method, .. } => method.name(),
        }
    }

    fn render_job(&self, job: &Job<'_>) -> Result<Image, Failure> {
        let clean = rgb_image(&job.clean)?;
        let depth = match &job.depth {
            Some(d) => given_depth(d, job.depth_unit, clean.size())?,
            None => uwnr_depth::Depth {
                map: uwnr_depth::builtin_depth(&clean).map_err(model)?,
                notes: Vec::new(),
                relative: true,
                metric_max: None,
                prior: true,
            },
        };
        let response = self.policy.response(&depth, job.seed);
        let depth = depth.map;
        match &self.kind {
            Kind::Network { renderer, config } => {
                let reference = job.reference.ok_or_else(|| {
                    Failure::Value("method uwnr needs a reference (a real underwater image)".into())
                })?;
                let style = reference.style(config)?;
                let input = ReferenceInput {
                    image: None,
                    style: &style,
                };
                let worker = renderer.worker().map_err(model)?;
                let (out, _params) = worker
                    .render(&clean, &depth, &response, Some(input), job.seed)
                    .map_err(Failure::Model)?;
                Ok(out)
            }
            Kind::Gan { renderer } => {
                let worker = renderer.worker().map_err(model)?;
                let (out, _params) = worker
                    .render(&clean, &depth, &response, None, job.seed)
                    .map_err(Failure::Model)?;
                Ok(out)
            }
            Kind::Baseline {
                method,
                without_reference,
            } => {
                let method = match (job.reference, without_reference) {
                    (None, Some(m)) => m,
                    _ => method,
                };
                if method.needs_reference() && job.reference.is_none() {
                    return Err(Failure::Value(format!(
                        "method {} needs a reference (a real underwater image)",
                        method.name()
                    )));
                }
                let input = RenderInput {
                    clean: &clean,
                    depth: &depth,
                    reference: job.reference.map(|r| &r.image),
                };
                uwnr_baselines::render(method, &input, job.seed)
                    .map(|r| r.image)
                    .map_err(|e| model(format!("rendering with {}: {e}", method.name())))
            }
        }
    }
}

/// A depth map passed from Python, at the clean image's size, as `unit` says to read it: a
/// metric map has its holes filled and keeps its metres, a relative or absolute one its values.
fn given_depth(
    d: &PixelView<'_>,
    unit: DepthUnitArg,
    size: (usize, usize),
) -> Result<uwnr_depth::Depth, Failure> {
    if d.channels != 1 {
        return Err(Failure::Value(format!(
            "depth must have 1 channel, got {}",
            d.channels
        )));
    }
    let mut map = d.image()?;
    let mut metric_max = None;
    if unit == DepthUnitArg::Metres {
        let (w, h) = map.size();
        if !uwnr_depth::fill_holes(map.plane_mut(0), w, h) {
            return Err(Failure::Value(
                "depth holds no measured value (every value is 0 or not finite)".into(),
            ));
        }
        let far = map.plane(0).iter().fold(0.0f32, |m, &v| m.max(v));
        for v in map.plane_mut(0) {
            *v /= far;
        }
        metric_max = Some(far);
    }
    if map.size() != size {
        map = uwnr_core::resize::resize_bilinear(&map, size.0, size.1).map_err(value)?;
    }
    Ok(uwnr_depth::Depth {
        map,
        notes: Vec::new(),
        relative: unit == DepthUnitArg::Relative,
        metric_max,
        prior: false,
    })
}

/// The network's depth options (`scene_scale`: metres, or `[min, max]` drawn per image;
/// `prior_trust`), over `uwnr render`'s defaults; any other key is an error.
fn network_policy(options: &Value) -> Result<DepthPolicy, Failure> {
    let mut policy = DepthPolicy::render();
    let Value::Object(m) = options else {
        return Err(Failure::Value("method options must be a mapping".into()));
    };
    let number = |key: &str, v: &Value| {
        v.as_f64()
            .map(|x| x as f32)
            .ok_or_else(|| Failure::Value(format!("{key} must be a number, got {v}")))
    };
    for (key, v) in m {
        match key.as_str() {
            "scene_scale" => {
                policy.scene_scale_m = match v {
                    Value::Array(a) if a.len() == 2 => (number(key, &a[0])?, number(key, &a[1])?),
                    other => {
                        let x = number(key, other)?;
                        (x, x)
                    }
                };
            }
            "prior_trust" => policy.prior_trust = number(key, v)?,
            other => {
                return Err(Failure::Value(format!(
                    "option {other:?} does not apply to method uwnr (it takes weights, device, \
                     the tiling options, scene_scale and prior_trust)"
                )));
            }
        }
    }
    policy.validate().map_err(value)?;
    Ok(policy)
}

/// The baseline `name` with the user's options (a JSON object), checked so that an option the
/// method does not have is an error rather than silently ignored.
fn baseline(name: &str, options: &Value) -> Result<(Method, Option<Method>), Failure> {
    let Value::Object(given) = options else {
        return Err(Failure::Value("method options must be a mapping".into()));
    };
    let mut tagged = given.clone();
    tagged.insert("method".into(), Value::String(name.into()));
    let mut method: Method = serde_json::from_value(Value::Object(tagged))
        .map_err(|e| Failure::Value(format!("options of method {name}: {e}")))?;
    let known = serde_json::to_value(&method).map_err(model)?;
    if let Value::Object(known) = &known {
        let mut names: Vec<&String> = known.keys().filter(|k| *k != "method").collect();
        names.sort();
        for key in given.keys() {
            if !known.contains_key(key) || key == "method" {
                let list: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
                return Err(Failure::Value(format!(
                    "method {name} has no option {key:?} (options: {})",
                    list.join(", ")
                )));
            }
        }
    }
    let mut without_reference = None;
    if let Method::Seathru(p) = &mut method
        && !given.contains_key("coefficients")
    {
        p.coefficients = SeathruCoefficients::FromReference(ReferenceCoefficients::default());
        let mut sampled = p.clone();
        sampled.coefficients = SeathruCoefficients::Sampled(SampledCoefficients::default());
        without_reference = Some(Method::Seathru(sampled));
    }
    Ok((method, without_reference))
}

/// Loads the network from `weights`, or the bundled model.
fn network(
    weights: Option<PathBuf>,
    device: &str,
    options: RenderOptions,
) -> Result<(DatasetRenderer, GeneratorConfig, String), Failure> {
    let backend = uwnr_model::backend_from_name(device).map_err(value)?;
    let (bytes, source): (std::borrow::Cow<'static, [u8]>, String) = match &weights {
        Some(path) => (
            std::fs::read(path)
                .map_err(|e| model(format!("reading weights {}: {e}", path.display())))?
                .into(),
            path.display().to_string(),
        ),
        None => (
            uwnr_model::bundled_weights()
                .ok_or_else(|| {
                    Failure::Model(
                        "this build has no bundled model: pass weights=PATH (safetensors or the \
                         authors' checkpoint)"
                            .into(),
                    )
                })?
                .into(),
            uwnr_model::BUNDLED_MODEL_NAME.to_string(),
        ),
    };
    let (network, _info) = uwnr_model::Network::load_from_bytes(&bytes, &backend)
        .map_err(|e| model(format!("loading weights {source}: {e}")))?;
    let config = *network.config();
    let renderer = DatasetRenderer::network(network, options, source.clone(), &bytes);
    Ok((renderer, config, source))
}

/// Loads the GAN baseline's generator from `weights`, or the bundled one.
fn gan(weights: Option<PathBuf>, device: &str) -> Result<(DatasetRenderer, String), Failure> {
    // The generator runs on burn: the engine's name means burn's CPU backend here.
    let name = if device == uwnr_model::ENGINE_NAME {
        "flex"
    } else {
        device
    };
    let device = uwnr_model::device_from_name(name).map_err(value)?;
    let (generator, bytes, source) =
        uwnr_gan::generator_or_bundled(weights.as_deref(), &device).map_err(model)?;
    let renderer = DatasetRenderer::gan(generator, device, source.clone(), &bytes);
    Ok((renderer, source))
}

#[pymethods]
impl NativeRenderer {
    #[new]
    #[pyo3(signature = (method, weights, options_json, seed, device, max_whole_pixels, tile, overlap))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        method: &str,
        weights: Option<PathBuf>,
        options_json: &str,
        seed: u64,
        device: &str,
        max_whole_pixels: usize,
        tile: usize,
        overlap: usize,
    ) -> PyResult<Self> {
        if !METHODS.contains(&method) {
            return Err(PyValueError::new_err(format!(
                "unknown method {method:?} (one of {})",
                METHODS.join(", ")
            )));
        }
        let options: Value = serde_json::from_str(options_json)
            .map_err(|e| PyValueError::new_err(format!("method options: {e}")))?;
        if method == "uwnr" {
            let policy = network_policy(&options)?;
            if let Some(path) = &weights
                && !path.exists()
            {
                return Err(PyFileNotFoundError::new_err(format!(
                    "weights file {} does not exist",
                    path.display()
                )));
            }
            let opts = RenderOptions {
                max_tile_pixels: max_whole_pixels,
                tile,
                overlap,
                ..Default::default()
            };
            opts.validate()
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            let (renderer, config, source) = compute(py, || network(weights, device, opts))?;
            return Ok(Self {
                kind: Kind::Network { renderer, config },
                seed,
                policy,
                source,
            });
        }
        if method == "uwgan" {
            if let Value::Object(m) = &options
                && let Some(key) = m.keys().next()
            {
                return Err(PyValueError::new_err(format!(
                    "option {key:?} does not apply to method uwgan (it takes weights and device)"
                )));
            }
            if let Some(path) = &weights
                && !path.exists()
            {
                return Err(PyFileNotFoundError::new_err(format!(
                    "weights file {} does not exist",
                    path.display()
                )));
            }
            let (renderer, source) = compute(py, || gan(weights, device))?;
            return Ok(Self {
                kind: Kind::Gan { renderer },
                seed,
                policy: DepthPolicy::default(),
                source,
            });
        }
        if weights.is_some() {
            return Err(PyValueError::new_err(format!(
                "weights apply only to methods uwnr and uwgan, not {method}"
            )));
        }
        let (method, without_reference) = baseline(method, &options)?;
        let source = serde_json::to_string(&method).unwrap_or_default();
        Ok(Self {
            kind: Kind::Baseline {
                method,
                without_reference,
            },
            seed,
            policy: DepthPolicy::default(),
            source,
        })
    }

    /// The method's name.
    #[getter]
    fn method(&self) -> &'static str {
        self.method_name()
    }

    /// Where the weights came from (`"bundled model"` or a path), or a baseline's parameters.
    #[getter]
    fn source(&self) -> &str {
        &self.source
    }

    /// The run seed (each call mixes it with the item index).
    #[getter]
    fn seed(&self) -> u64 {
        self.seed
    }

    /// The light field map the network reads (`None` for baselines).
    #[getter]
    fn light_field_map(&self) -> Option<&'static str> {
        match &self.kind {
            Kind::Network { config, .. } => Some(config.light_field.name()),
            Kind::Gan { .. } | Kind::Baseline { .. } => None,
        }
    }

    /// Renders one image; returns its interleaved bytes in the clean image's dtype.
    #[pyo3(signature = (clean, reference, depth, depth_unit, seed, index))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        clean: Pixels<'py>,
        reference: Option<Bound<'py, NativeReference>>,
        depth: Option<Pixels<'py>>,
        depth_unit: &str,
        seed: Option<u64>,
        index: usize,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let job = Job {
            clean: clean.view()?,
            reference: reference.as_ref().map(Bound::get),
            depth: depth.as_ref().map(Pixels::view).transpose()?,
            depth_unit: DepthUnitArg::parse(depth_unit)?,
            seed: uwnr_baselines::item_seed(seed.unwrap_or(self.seed), index),
        };
        let dtype = job.clean.dtype;
        let out = compute(py, || self.render_job(&job))?;
        Ok(image_bytes(py, &out, dtype))
    }

    /// Renders many images in parallel; item `i` uses seed `item_seed(seed, i)`.
    #[pyo3(signature = (items, depth_unit, seed))]
    fn render_batch<'py>(
        &self,
        py: Python<'py>,
        items: Vec<BatchItem<'py>>,
        depth_unit: &str,
        seed: Option<u64>,
    ) -> PyResult<Vec<Bound<'py, PyBytes>>> {
        let seed = seed.unwrap_or(self.seed);
        let depth_unit = DepthUnitArg::parse(depth_unit)?;
        let jobs = items
            .iter()
            .enumerate()
            .map(|(i, (clean, reference, depth))| {
                Ok(Job {
                    clean: clean.view()?,
                    reference: reference.as_ref().map(Bound::get),
                    depth: depth.as_ref().map(Pixels::view).transpose()?,
                    depth_unit,
                    seed: uwnr_baselines::item_seed(seed, i),
                })
            })
            .collect::<Result<Vec<_>, Failure>>()?;
        let outs = compute(py, || {
            jobs.par_iter()
                .enumerate()
                .map(|(i, job)| {
                    self.render_job(job).map_err(|f| match f {
                        Failure::Value(m) => Failure::Value(format!("item {i}: {m}")),
                        Failure::Model(m) => Failure::Model(format!("item {i}: {m}")),
                    })
                })
                .collect::<Result<Vec<_>, Failure>>()
        })?;
        Ok(outs
            .iter()
            .zip(&jobs)
            .map(|(img, job)| image_bytes(py, img, job.clean.dtype))
            .collect())
    }
}

/// The built-in depth prior of an RGB image: f32 bytes, height x width, bright = far.
#[pyfunction]
fn builtin_depth<'py>(py: Python<'py>, clean: Pixels<'py>) -> PyResult<Bound<'py, PyBytes>> {
    let view = clean.view()?;
    let depth = compute(py, || {
        uwnr_depth::builtin_depth(&rgb_image(&view)?).map_err(model)
    })?;
    Ok(image_bytes(py, &depth, Dtype::F32))
}

/// Decodes an image file with uwnr's decoder (as `uwnr render` reads its inputs): f32 RGB bytes,
/// height, width. An unreadable file is a `ValueError`.
#[pyfunction]
fn load_rgb(py: Python<'_>, path: PathBuf) -> PyResult<(Bound<'_, PyBytes>, usize, usize)> {
    let img = compute(py, || {
        uwnr_core::io::load_rgb(&path, &uwnr_core::io::DecodeLimits::default()).map_err(value)
    })?;
    Ok((image_bytes(py, &img, Dtype::F32), img.height(), img.width()))
}

/// The metric `name` of `pred` against `target` (full-reference) or of `pred` alone.
#[pyfunction]
#[pyo3(signature = (name, pred, target, gray))]
fn metric<'py>(
    py: Python<'py>,
    name: &str,
    pred: Pixels<'py>,
    target: Option<Pixels<'py>>,
    gray: bool,
) -> PyResult<f64> {
    let pred = pred.view()?;
    let target = target.as_ref().map(Pixels::view).transpose()?;
    let name = name.to_string();
    compute(py, move || {
        let a = rgb_image(&pred)?;
        let b = target.as_ref().map(rgb_image).transpose()?;
        let range = uwnr_metrics::DEFAULT_DATA_RANGE;
        let score = match (name.as_str(), &b, gray) {
            ("psnr", Some(b), false) => uwnr_metrics::psnr(&a, b, range),
            ("psnr", Some(b), true) => uwnr_metrics::psnr_gray(&a, b, range),
            ("ssim", Some(b), false) => uwnr_metrics::ssim(&a, b, range),
            ("ssim", Some(b), true) => uwnr_metrics::ssim_gray(&a, b, range),
            ("uiqm", None, _) => uwnr_metrics::uiqm(&a),
            ("uciqe", None, _) => uwnr_metrics::uciqe(&a),
            _ => return Err(Failure::Value(format!("unknown metric call {name:?}"))),
        };
        score.map_err(value)
    })
}

/// The native module `uwnr._uwnr`.
#[pymodule]
fn _uwnr(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<NativeReference>()?;
    m.add_class::<NativeRenderer>()?;
    m.add_function(wrap_pyfunction!(builtin_depth, m)?)?;
    m.add_function(wrap_pyfunction!(metric, m)?)?;
    m.add_function(wrap_pyfunction!(load_rgb, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BUNDLED_MODEL", uwnr_model::bundled_weights().is_some())?;
    m.add("BUNDLED_GAN", uwnr_gan::bundled_gan_weights().is_some())?;
    m.add("DEVICES", uwnr_model::backend_names())?;
    Ok(())
}
