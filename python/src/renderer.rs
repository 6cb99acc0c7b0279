//! `NativeReference` (a decoded reference with its light fields, computed once) and
//! `NativeRenderer` (a `uwnr_render::Renderer` with the run seed and the network's depth
//! policy), the classes behind `uwnr.Reference` and `uwnr.Renderer`.

use std::path::PathBuf;
use std::sync::OnceLock;

use pyo3::exceptions::{PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;
use serde_json::{Map, Value};

use uwnr_core::Image;
use uwnr_core::lightfield::{LightFieldMap, light_field_with};
use uwnr_model::{GeneratorConfig, ReferenceStyle};
use uwnr_render::{
    DepthPolicy, JobWorker, MethodKind, ReferenceInput, ReferenceUse, RenderError, Renderer,
};

use crate::convert::{Dtype, PixelView, Pixels, image_bytes};
use crate::{Failure, compute, model, value};

fn parse_map(name: &str) -> Result<LightFieldMap, Failure> {
    name.parse::<LightFieldMap>().map_err(value)
}

/// A render method's error, sorted: what the caller gave wrong is a `ValueError`, the rest
/// `uwnr.Error`.
fn failure(e: RenderError) -> Failure {
    match e {
        RenderError::UnknownMethod { .. }
        | RenderError::UnknownOption { .. }
        | RenderError::BadOptions { .. }
        | RenderError::NeedsReference { .. }
        | RenderError::Invalid(_) => Failure::Value(e.to_string()),
        RenderError::Weights { .. } | RenderError::Failed { .. } => Failure::Model(e.to_string()),
    }
}

/// A real underwater reference, decoded once, with its light field maps (one per normalisation),
/// waters and chromaticity computed on first use and kept.
#[pyclass(frozen, module = "uwnr._uwnr")]
pub(crate) struct NativeReference {
    image: Image,
    paper: OnceLock<Result<Image, String>>,
    absolute: OnceLock<Result<Image, String>>,
    global: OnceLock<Result<Image, String>>,
    /// The water per (anchor, detail retention) a network has asked for.
    water: std::sync::Mutex<Vec<((uwnr_model::AnchorKind, bool), uwnr_model::Water)>>,
    /// The chromaticity, for a clean balance that follows the water.
    chromaticity: OnceLock<Option<[f32; 3]>>,
}

impl NativeReference {
    /// The 256x256 light field map of this reference under `map`.
    fn field(&self, map: LightFieldMap) -> Result<&Image, Failure> {
        let cell = match map {
            LightFieldMap::Paper => &self.paper,
            LightFieldMap::Absolute => &self.absolute,
            LightFieldMap::Global => &self.global,
        };
        cell.get_or_init(|| light_field_with(&self.image, map).map_err(|e| e.to_string()))
            .as_ref()
            .map_err(|e| Failure::Model(format!("light field of the reference: {e}")))
    }

    /// What a model with `config` takes of this reference (the light field only when its
    /// renders read one; the chromaticity only when the clean balance follows the water).
    fn style(
        &self,
        config: &GeneratorConfig,
        chromaticity: bool,
    ) -> Result<ReferenceStyle, Failure> {
        let light_field = if config.reads_light_field() {
            Some(self.field(config.light_field)?.clone())
        } else {
            None
        };
        let water = match config.variant {
            uwnr_model::Variant::Paper => None,
            uwnr_model::Variant::Anchored => {
                let key = (config.anchor, config.detail_retention);
                let mut cache = self
                    .water
                    .lock()
                    .map_err(|_| Failure::Model("the reference's cache is poisoned".into()))?;
                let water = match cache.iter().find(|(k, _)| *k == key) {
                    Some((_, w)) => *w,
                    None => {
                        let w = uwnr_model::style::estimate_water_for(&self.image, key.0, key.1)
                            .map_err(|e| Failure::Model(format!("water of the reference: {e}")))?;
                        cache.push((key, w));
                        w
                    }
                };
                Some(water)
            }
        };
        Ok(ReferenceStyle {
            light_field,
            water,
            chromaticity: chromaticity
                .then(|| {
                    *self
                        .chromaticity
                        .get_or_init(|| uwnr_model::water::chromaticity(&self.image))
                })
                .flatten(),
        })
    }
}

#[pymethods]
impl NativeReference {
    #[new]
    fn new(py: Python<'_>, pixels: Pixels<'_>) -> PyResult<Self> {
        let view = pixels.view()?;
        let image = compute(py, || view.rgb())?;
        Ok(Self {
            image,
            paper: OnceLock::new(),
            absolute: OnceLock::new(),
            global: OnceLock::new(),
            water: std::sync::Mutex::new(Vec::new()),
            chromaticity: OnceLock::new(),
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

/// A loaded render method with the run seed.
#[pyclass(frozen, module = "uwnr._uwnr")]
pub(crate) struct NativeRenderer {
    renderer: Renderer,
    seed: u64,
    /// The network's scene scale and trust in the prior (`scene_scale`, `prior_trust`).
    policy: DepthPolicy,
    /// Where the weights came from, or the method's settings as JSON.
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
    fn render_job(&self, job: &Job<'_>) -> Result<Image, Failure> {
        let clean = job.clean.rgb()?;
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
        // The network reads the reference's style (cached per reference object, which any
        // renderer may take, so its light fields are shared between networks), the baselines
        // its pixels.
        let style = match (job.reference, self.renderer.generator_config()) {
            (Some(r), Some(config)) => {
                Some(r.style(config, self.renderer.balance_follows_water())?)
            }
            _ => None,
        };
        let input = job.reference.map(|r| ReferenceInput {
            image: Some(&r.image),
            style: style.as_ref(),
        });
        let worker = JobWorker::new(self.renderer.worker(), &self.policy);
        worker
            .render(&clean, &depth, input, job.seed)
            .map(|r| r.image)
            .map_err(failure)
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

/// The network's depth options taken out of `options` (`scene_scale`: metres, or `[min, max]`
/// drawn per image; `prior_trust`), over `uwnr render`'s defaults.
fn network_policy(options: &mut Map<String, Value>) -> Result<DepthPolicy, Failure> {
    let mut policy = DepthPolicy::render();
    let number = |key: &str, v: &Value| {
        v.as_f64()
            .map(|x| x as f32)
            .ok_or_else(|| Failure::Value(format!("{key} must be a number, got {v}")))
    };
    if let Some(v) = options.remove("scene_scale") {
        policy.scene_scale_m = match &v {
            Value::Array(a) if a.len() == 2 => {
                (number("scene_scale", &a[0])?, number("scene_scale", &a[1])?)
            }
            other => {
                let x = number("scene_scale", other)?;
                (x, x)
            }
        };
    }
    if let Some(v) = options.remove("prior_trust") {
        policy.prior_trust = number("prior_trust", &v)?;
    }
    policy.validate().map_err(value)?;
    Ok(policy)
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
        let kind: MethodKind = method.parse().map_err(failure)?;
        let options: Value = serde_json::from_str(options_json)
            .map_err(|e| PyValueError::new_err(format!("method options: {e}")))?;
        let Value::Object(mut keywords) = options else {
            return Err(PyValueError::new_err("method options must be a mapping"));
        };
        let policy = if kind == MethodKind::Uwnr {
            network_policy(&mut keywords)?
        } else {
            DepthPolicy::default()
        };
        if kind.loads_weights() {
            if let Some(path) = &weights
                && !path.exists()
            {
                return Err(PyFileNotFoundError::new_err(format!(
                    "weights file {} does not exist",
                    path.display()
                )));
            }
            for key in keywords.keys() {
                if matches!(
                    key.as_str(),
                    "weights" | "device" | "max_whole_pixels" | "tile" | "overlap"
                ) {
                    return Err(PyValueError::new_err(format!(
                        "option {key:?} is a parameter of Renderer, not a method option"
                    )));
                }
            }
            let path = weights.map(|p| Value::String(p.to_string_lossy().into_owned()));
            keywords.insert("weights".into(), path.unwrap_or(Value::Null));
            keywords.insert("device".into(), Value::String(device.into()));
            if kind == MethodKind::Uwnr {
                keywords.insert("max_whole_pixels".into(), max_whole_pixels.into());
                keywords.insert("tile".into(), tile.into());
                keywords.insert("overlap".into(), overlap.into());
            }
        } else if weights.is_some() {
            return Err(PyValueError::new_err(format!(
                "weights apply only to methods uwnr and uwgan, not {method}"
            )));
        }
        let renderer = compute(py, || {
            Renderer::load_keywords(kind, &keywords).map_err(|e| match e {
                RenderError::UnknownOption {
                    method: "uwnr",
                    option,
                    known,
                } => Failure::Value(format!(
                    "option {option:?} does not apply to method uwnr (its options: {known}, \
                     scene_scale, prior_trust)"
                )),
                e => failure(e),
            })
        })?;
        let source = match renderer.weights_source() {
            Some(s) => s.to_string(),
            None => serde_json::to_string(renderer.spec()).map_err(model)?,
        };
        Ok(Self {
            renderer,
            seed,
            policy,
            source,
        })
    }

    /// The method's name.
    #[getter]
    fn method(&self) -> &'static str {
        self.renderer.name()
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

    /// What a render does with a reference: `"ignored"`, `"optional"` or `"required"`.
    #[getter]
    fn reference_use(&self) -> &'static str {
        match self.renderer.reference_use() {
            ReferenceUse::Ignored => "ignored",
            ReferenceUse::Optional => "optional",
            ReferenceUse::Required => "required",
        }
    }

    /// The light field map the network reads (`None` for the other methods).
    #[getter]
    fn light_field_map(&self) -> Option<&'static str> {
        self.renderer
            .generator_config()
            .map(|c| c.light_field.name())
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
            seed: uwnr_core::seed::item_seed(seed.unwrap_or(self.seed), index),
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
                    seed: uwnr_core::seed::item_seed(seed, i),
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
