//! [`Renderer`]: a [`MethodSpec`] loaded (weights read once) and ready to render, and its
//! per-thread [`Worker`].

use std::path::Path;
use std::sync::Arc;

use serde::Serialize;
use serde_json::{Map, Value};
use uwnr_baselines::{Method, RenderInput};
use uwnr_core::Image;
use uwnr_core::error::Cause;
use uwnr_model::water::CleanBalance;
use uwnr_model::{
    Backend, DepthResponse, GeneratorConfig, ReferenceStyle, RenderOptions, WaterEffects,
};

use crate::error::{RenderError, Result};
use crate::haze::{self, HazeParams};
use crate::method::{
    CleanSide, ComputeDevice, MethodKind, MethodSpec, Precision, ReferenceUse, UwganSpec, UwnrSpec,
};
use crate::record::{MethodRecord, UwganRecord, UwnrRecord, depth_record, fingerprint};
use crate::revised::{self, RevisedParams};

/// The UWNR model, loaded.
struct Network {
    /// Cloned once per worker (cheap: the engine's weights are shared, and the bundled model has
    /// no network).
    generator: uwnr_model::Network,
    config: GeneratorConfig,
    options: RenderOptions,
    /// Where the weights came from (a path, or "bundled model").
    weights: String,
    /// A fingerprint of the weight bytes.
    fingerprint: String,
    precision: Precision,
    /// The stages after the water (`uwnr_model::effects`).
    effects: WaterEffects,
    /// The clean photo's gains before the water (`uwnr_model::water::CleanBalance`).
    balance: CleanBalance,
    /// How far the balance follows each reference's water (0: not at all).
    balance_water_share: f32,
    /// What a dataset stores as a pair's clean side.
    clean_side: CleanSide,
}

impl Network {
    /// The clean balance for a render after `style` (its chromaticity, when the balance
    /// follows the water).
    fn balance_for(&self, style: Option<&ReferenceStyle>) -> CleanBalance {
        match style.and_then(|s| s.chromaticity) {
            Some(chroma) => self.balance.following(self.balance_water_share, chroma),
            None => self.balance,
        }
    }
}

/// The GAN baseline's generator, loaded.
struct Gan {
    /// Cloned once per worker (35,003 parameters).
    generator: uwnr_gan::Generator,
    config: uwnr_gan::GeneratorConfig,
    weights: String,
    fingerprint: String,
}

enum Imp {
    Uwnr(Box<Network>),
    Uwgan(Box<Gan>),
    Baseline(Method),
    Revised(RevisedParams),
    Haze(HazeParams),
}

/// A render method, loaded. Share it between threads; each takes a [`Worker`].
pub struct Renderer {
    spec: MethodSpec,
    imp: Imp,
    /// The baseline a render without a reference uses, for a method whose reference is
    /// optional ([`Renderer::load_keywords`]).
    without_reference: Option<Method>,
}

/// What a render is given of its reference.
#[derive(Clone, Copy, Default)]
pub struct ReferenceInput<'a> {
    /// The decoded reference (what the baselines read).
    pub image: Option<&'a Image>,
    /// Its style: the light field, and the water for the anchored network (what the network
    /// reads).
    pub style: Option<&'a ReferenceStyle>,
}

/// A reference prepared for a renderer: what its method reads of it, computed once.
#[derive(Clone, Default)]
pub struct PreparedReference {
    /// The decoded image, kept for methods that read it (shared, never copied).
    pub image: Option<Arc<Image>>,
    /// The style, computed for the network.
    pub style: Option<ReferenceStyle>,
}

impl PreparedReference {
    /// Bytes it holds: the decoded image (shared with whoever else holds it) and the style's
    /// maps.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        let image = self.image.as_ref().map_or(0, |i| i.data().len());
        let style = self
            .style
            .as_ref()
            .and_then(|s| s.light_field.as_ref())
            .map_or(0, |lf| lf.data().len());
        ((image + style) * std::mem::size_of::<f32>()) as u64
    }

    /// The reference as a render takes it.
    #[must_use]
    pub fn input(&self) -> ReferenceInput<'_> {
        ReferenceInput {
            image: self.image.as_deref(),
            style: self.style.as_ref(),
        }
    }
}

/// A rendered image and the parameters to record with it.
pub struct Rendered {
    /// The underwater image, the clean image's size.
    pub image: Image,
    /// What made it (weights, drawn parameters, depth response).
    pub params: MethodRecord,
}

impl Renderer {
    /// Loads `spec`: reads and checks its weights (the bundled model when it names none).
    pub fn load(spec: MethodSpec) -> Result<Self> {
        spec.validate()?;
        let imp = match &spec {
            MethodSpec::Uwnr(s) => Imp::Uwnr(Box::new(load_network(s)?)),
            MethodSpec::Uwgan(s) => Imp::Uwgan(Box::new(load_gan(s)?)),
            MethodSpec::Haze(p) => Imp::Haze(p.clone()),
            MethodSpec::Revised(p) => Imp::Revised(p.clone()),
            MethodSpec::Jerlov(_)
            | MethodSpec::Uisa(_)
            | MethodSpec::Seathru(_)
            | MethodSpec::Reinhard(_) => Imp::Baseline(spec.baseline().ok_or_else(|| {
                RenderError::Invalid(format!("{} is not a baseline", spec.name()))
            })?),
        };
        Ok(Self {
            spec,
            imp,
            without_reference: None,
        })
    }

    /// Loads method `kind` with `keywords` ([`MethodSpec::from_keywords`]) for renders that
    /// may or may not have a reference, each call deciding: Sea-thru with no coefficients
    /// chosen fits them to the reference of a render that has one, and samples them otherwise.
    pub fn load_keywords(kind: MethodKind, keywords: &Map<String, Value>) -> Result<Self> {
        let with = MethodSpec::from_keywords(kind, keywords, true)?;
        let without = MethodSpec::from_keywords(kind, keywords, false)?;
        let mut renderer = Self::load(with.clone())?;
        if without != with {
            renderer.without_reference = without.baseline();
        }
        Ok(renderer)
    }

    /// The network `generator` as a renderer with `options`; `weights` names the weights'
    /// origin and `weight_bytes` are fingerprinted into the recorded settings.
    #[must_use]
    pub fn network(
        generator: uwnr_model::Network,
        options: RenderOptions,
        weights: String,
        weight_bytes: &[u8],
    ) -> Self {
        let precision = if generator.is_bf16() {
            Precision::Bf16
        } else {
            Precision::F32
        };
        let spec = MethodSpec::Uwnr(UwnrSpec {
            precision,
            max_whole_pixels: options.max_tile_pixels,
            tile: options.tile,
            overlap: options.overlap,
            effects: WaterEffects::NONE,
            balance: CleanBalance::NONE,
            balance_water_share: 0.0,
            ..UwnrSpec::default()
        });
        Self {
            spec,
            imp: Imp::Uwnr(Box::new(Network {
                config: *generator.config(),
                generator,
                options,
                weights,
                fingerprint: fingerprint(weight_bytes),
                precision,
                effects: WaterEffects::NONE,
                balance: CleanBalance::NONE,
                balance_water_share: 0.0,
                clean_side: CleanSide::Photo,
            })),
            without_reference: None,
        }
    }

    /// A baseline of `uwnr_baselines` as a renderer.
    #[must_use]
    pub fn baseline(method: Method) -> Self {
        Self {
            spec: MethodSpec::from_baseline(method.clone()),
            imp: Imp::Baseline(method),
            without_reference: None,
        }
    }

    /// The method and its settings.
    #[must_use]
    pub fn spec(&self) -> &MethodSpec {
        &self.spec
    }

    /// Which method renders.
    #[must_use]
    pub fn kind(&self) -> MethodKind {
        self.spec.kind()
    }

    /// The method's name (`uwnr`, `uwgan`, `jerlov`, ...).
    #[must_use]
    pub fn name(&self) -> &'static str {
        self.spec.name()
    }

    /// What a render does with a reference.
    #[must_use]
    pub fn reference_use(&self) -> ReferenceUse {
        match (self.spec.reference_use(), &self.without_reference) {
            (ReferenceUse::Required, Some(_)) => ReferenceUse::Optional,
            (u, _) => u,
        }
    }

    /// Whether renders must have a reference.
    #[must_use]
    pub fn needs_reference(&self) -> bool {
        self.reference_use() == ReferenceUse::Required
    }

    /// Whether renders use a reference when one is given.
    #[must_use]
    pub fn uses_reference(&self) -> bool {
        self.reference_use() != ReferenceUse::Ignored
    }

    /// The network's config (`None` for the other methods).
    #[must_use]
    pub fn generator_config(&self) -> Option<&GeneratorConfig> {
        match &self.imp {
            Imp::Uwnr(n) => Some(&n.config),
            Imp::Uwgan(_) | Imp::Baseline(_) | Imp::Revised(_) | Imp::Haze(_) => None,
        }
    }

    /// Where the weights came from (a path or the bundled model's name), for the networks.
    #[must_use]
    pub fn weights_source(&self) -> Option<&str> {
        match &self.imp {
            Imp::Uwnr(n) => Some(&n.weights),
            Imp::Uwgan(g) => Some(&g.weights),
            Imp::Baseline(_) | Imp::Revised(_) | Imp::Haze(_) => None,
        }
    }

    /// Whether the clean balance follows each reference's water (the uwnr method with a
    /// `balance_water_share`): its [`ReferenceStyle`] then carries the reference's chromaticity.
    #[must_use]
    pub fn balance_follows_water(&self) -> bool {
        matches!(&self.imp, Imp::Uwnr(n) if n.balance_water_share != 0.0)
    }

    /// `clean` as the method's water starts from it: for the uwnr method at its clean balance
    /// (`uwnr_model::water::CleanBalance`) for the reference of `style` (its
    /// [`Renderer::reference_style`]; the fixed balance without one), against which a calibrated
    /// water's strength is measured; `clean` itself for the others.
    pub fn balanced<'a>(
        &self,
        clean: &'a Image,
        style: Option<&ReferenceStyle>,
    ) -> Result<std::borrow::Cow<'a, Image>> {
        match &self.imp {
            Imp::Uwnr(n) => n
                .balance_for(style)
                .apply(clean)
                .map_err(|e| failed("balancing the clean photo", e)),
            _ => Ok(std::borrow::Cow::Borrowed(clean)),
        }
    }

    /// What a dataset stores as the clean side of a pair made from `clean`, given `balanced`,
    /// that photo at the method's clean balance ([`Renderer::balanced`], which the calibration
    /// measures from, so it is made once a pair): `balanced` when the uwnr method's `clean_side`
    /// says so, lit as the underwater side is when it says `lit`, `clean` itself otherwise.
    pub fn clean_side<'b>(
        &self,
        clean: &'b Image,
        balanced: &'b Image,
    ) -> Result<std::borrow::Cow<'b, Image>> {
        match &self.imp {
            Imp::Uwnr(n) if n.clean_side == CleanSide::Lit && n.effects.has_light() => {
                let mut lit = balanced.clone();
                n.effects
                    .apply_light(&mut lit)
                    .map_err(|e| failed("lighting the clean side", e))?;
                Ok(std::borrow::Cow::Owned(lit))
            }
            // Lit without a light stage is the balanced photo.
            Imp::Uwnr(n) if n.clean_side != CleanSide::Photo => {
                Ok(std::borrow::Cow::Borrowed(balanced))
            }
            _ => Ok(std::borrow::Cow::Borrowed(clean)),
        }
    }

    /// The settings a dataset records and compares on resume: for the networks their weights'
    /// origin and fingerprint, config and precision (bf16 only; f32 is the old form); for the
    /// others their spec.
    pub fn settings_params(&self) -> Result<Value> {
        let value = match &self.imp {
            Imp::Uwnr(n) => serde_json::to_value(NetworkRecord {
                weights: &n.weights,
                fingerprint: &n.fingerprint,
                config: &n.config,
                precision: n.precision,
                effects: &n.effects,
                balance: &n.balance,
                balance_water_share: n.balance_water_share,
                clean_side: match n.clean_side {
                    CleanSide::Photo => None,
                    CleanSide::Balanced => (!n.balance.is_none()).then_some(&n.clean_side),
                    CleanSide::Lit => Some(&n.clean_side),
                },
            }),
            Imp::Uwgan(g) => serde_json::to_value(GanRecord {
                weights: &g.weights,
                fingerprint: &g.fingerprint,
                config: &g.config,
            }),
            Imp::Baseline(m) => serde_json::to_value(m),
            Imp::Revised(_) | Imp::Haze(_) => serde_json::to_value(&self.spec),
        };
        value.map_err(|e| RenderError::Invalid(format!("cannot record the method's settings: {e}")))
    }

    /// The style of reference `img`: for the uwnr method what its config reads (the light field
    /// in the map it names when a network or the Reinhard anchor reads one, and the water for the
    /// anchored variant). `keep_light_field` adds the map when the renders read none (what a
    /// dataset saves with `--save-lightfield`; the released map for the other methods).
    pub fn reference_style(&self, img: &Image, keep_light_field: bool) -> Result<ReferenceStyle> {
        match &self.imp {
            Imp::Uwnr(n) => ReferenceStyle::new(img, &n.config).and_then(|mut style| {
                if self.balance_follows_water() {
                    style.chromaticity = uwnr_model::water::chromaticity(img);
                }
                if keep_light_field && style.light_field.is_none() {
                    style.light_field = Some(uwnr_core::lightfield::light_field_with(
                        img,
                        n.config.light_field,
                    )?);
                }
                Ok(style)
            }),
            _ if keep_light_field => uwnr_core::lightfield::light_field(img)
                .map(ReferenceStyle::from_light_field)
                .map_err(uwnr_model::ModelError::from),
            _ => Ok(ReferenceStyle {
                light_field: None,
                water: None,
                chromaticity: None,
            }),
        }
        .map_err(|e| failed("style of the reference", e))
    }

    /// Whether renders read the decoded reference image (the baselines; the network reads its
    /// style only).
    #[must_use]
    pub fn wants_reference_image(&self) -> bool {
        matches!(self.imp, Imp::Baseline(_) | Imp::Revised(_))
    }

    /// What this method reads of reference `img`, computed once for many renders.
    pub fn prepare_reference(&self, img: Arc<Image>) -> Result<PreparedReference> {
        Ok(match &self.imp {
            Imp::Uwnr(_) => PreparedReference {
                style: Some(self.reference_style(&img, false)?),
                image: None,
            },
            Imp::Baseline(_) | Imp::Revised(_) => PreparedReference {
                image: Some(img),
                style: None,
            },
            Imp::Uwgan(_) | Imp::Haze(_) => PreparedReference::default(),
        })
    }

    /// A per-thread handle (a network is copied so that threads never share one).
    #[must_use]
    pub fn worker(&self) -> Worker<'_> {
        Worker(match &self.imp {
            Imp::Uwnr(n) => WorkerImp::Uwnr {
                generator: Box::new(n.generator.clone()),
                net: n,
            },
            Imp::Uwgan(g) => WorkerImp::Uwgan {
                generator: Box::new(g.generator.clone()),
                gan: g,
            },
            Imp::Baseline(m) => WorkerImp::Baseline {
                method: m,
                without_reference: self.without_reference.as_ref(),
            },
            Imp::Revised(p) => WorkerImp::Revised(p),
            Imp::Haze(p) => WorkerImp::Haze(p),
        })
    }
}

enum WorkerImp<'a> {
    Uwnr {
        generator: Box<uwnr_model::Network>,
        net: &'a Network,
    },
    Uwgan {
        generator: Box<uwnr_gan::Generator>,
        gan: &'a Gan,
    },
    Baseline {
        method: &'a Method,
        without_reference: Option<&'a Method>,
    },
    Revised(&'a RevisedParams),
    Haze(&'a HazeParams),
}

/// A renderer as one thread holds it.
pub struct Worker<'a>(WorkerImp<'a>);

impl Worker<'_> {
    /// Renders `clean` over `depth` (1 channel, its size, larger = farther) after `reference`;
    /// `response` is how the network responds to the depth (what its values stand for, how far
    /// they are trusted), recorded with its renders; the other methods read the map with their
    /// own scales. `seed` draws every random parameter.
    pub fn render(
        &self,
        clean: &Image,
        depth: &Image,
        response: &DepthResponse,
        reference: Option<ReferenceInput<'_>>,
        seed: u64,
    ) -> Result<Rendered> {
        let reference = reference.unwrap_or_default();
        match &self.0 {
            WorkerImp::Uwnr { generator, net } => {
                let style = reference.style.ok_or(RenderError::NeedsReference {
                    method: MethodKind::Uwnr.name(),
                })?;
                let options = RenderOptions {
                    depth: *response,
                    ..net.options
                };
                let balanced = net
                    .balance_for(Some(style))
                    .apply(clean)
                    .map_err(|e| failed("balancing the clean photo", e))?;
                let mut image = generator
                    .render(&balanced, depth, style, &options)
                    .map_err(|e| failed("rendering", e))?;
                if !net.effects.is_none() {
                    // A network without a water (the paper's variant) lights particles and
                    // the medium towards the render's own mean colour.
                    let veil = match style.water.as_ref() {
                        Some(w) => w.veil,
                        None => uwnr_model::water::mean_colour(&image),
                    };
                    net.effects
                        .apply(&mut image, depth, veil, seed)
                        .map_err(|e| failed("the water's effects", e))?;
                }
                let params = MethodRecord::Uwnr(UwnrRecord {
                    weights: net.weights.clone(),
                    depth: depth_record(response),
                    water: style.water.as_ref().and_then(|w| w.affine),
                    strength: None,
                });
                Ok(Rendered { image, params })
            }
            WorkerImp::Uwgan { generator, gan } => {
                let (image, v) = uwnr_gan::render_with_values(generator, clean, depth, seed)
                    .map_err(|e| failed("rendering with uwgan", e))?;
                Ok(Rendered {
                    image,
                    params: MethodRecord::Uwgan(UwganRecord {
                        weights: gan.weights.clone(),
                        z_seed: seed,
                        beta: v.beta,
                        backlight: v.backlight,
                        vignette: v.vignette,
                        gain: v.gain,
                    }),
                })
            }
            WorkerImp::Baseline {
                method,
                without_reference,
            } => {
                let method = match (reference.image, without_reference) {
                    (None, Some(m)) => m,
                    _ => method,
                };
                if method.needs_reference() && reference.image.is_none() {
                    return Err(RenderError::NeedsReference {
                        method: method.name(),
                    });
                }
                let input = RenderInput {
                    clean,
                    depth,
                    reference: reference.image,
                };
                let rendered = uwnr_baselines::render(method, &input, seed)
                    .map_err(|e| failed(&format!("rendering with {}", method.name()), e))?;
                Ok(Rendered {
                    image: rendered.image,
                    params: rendered.params.into(),
                })
            }
            WorkerImp::Revised(p) => {
                if p.baseline().needs_reference() && reference.image.is_none() {
                    return Err(RenderError::NeedsReference {
                        method: MethodKind::Revised.name(),
                    });
                }
                let input = RenderInput {
                    clean,
                    depth,
                    reference: reference.image,
                };
                let (image, params) = revised::render(p, &input, seed)?;
                Ok(Rendered { image, params })
            }
            WorkerImp::Haze(p) => {
                let (image, params) = haze::render(p, clean, depth)?;
                Ok(Rendered { image, params })
            }
        }
    }
}

fn failed(context: &str, e: impl Into<Cause>) -> RenderError {
    RenderError::Failed {
        context: context.into(),
        source: e.into(),
    }
}

/// What runs the network: the engine, at `precision`.
fn backend(device: ComputeDevice, precision: Precision) -> Backend {
    match (device, precision) {
        (ComputeDevice::Engine, Precision::F32) => Backend::Engine,
        (ComputeDevice::Engine, Precision::Bf16) => Backend::EngineBf16,
    }
}

const NO_BUNDLED_MODEL: &str =
    "this build has no bundled model: give weights (safetensors or the authors' checkpoint)";

fn weights_error(source: &str, e: impl Into<Cause>) -> RenderError {
    RenderError::Weights {
        source_name: source.to_string(),
        source: e.into(),
    }
}

fn load_network(s: &UwnrSpec) -> Result<Network> {
    let backend = backend(s.device, s.precision);
    let (network, bytes, weights) = match &s.weights {
        Some(path) => {
            let source = path.display().to_string();
            let (network, _info) =
                uwnr_model::Network::load(path, &backend).map_err(|e| weights_error(&source, e))?;
            let bytes = read(path, &source)?;
            (network, bytes, source)
        }
        None => {
            let source = uwnr_model::BUNDLED_MODEL_NAME.to_string();
            let (bytes, config) = uwnr_model::bundled_model_bytes()
                .zip(uwnr_model::bundled_config())
                .ok_or_else(|| RenderError::Invalid(NO_BUNDLED_MODEL.into()))?;
            let network = config
                .and_then(|c| uwnr_model::Network::uncorrected(&c))
                .map_err(|e| weights_error(&source, e))?;
            (network, bytes.to_vec(), source)
        }
    };
    if !network.runs_network() && s.precision == Precision::Bf16 {
        return Err(RenderError::Invalid(
            "precision bf16 applies to a network, and this model runs none (its correction is \
             none): drop it, or give --weights"
                .into(),
        ));
    }
    Ok(Network {
        config: *network.config(),
        generator: network,
        options: s.render_options(),
        weights,
        fingerprint: fingerprint(&bytes),
        precision: s.precision,
        effects: s.effects,
        balance: s.balance,
        // A balance of none follows nothing (it renders v7's pairs bit for bit).
        balance_water_share: if s.balance.is_none() {
            0.0
        } else {
            s.balance_water_share
        },
        clean_side: s.clean_side,
    })
}

fn read(path: &Path, source: &str) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| weights_error(source, e))
}

fn load_gan(s: &UwganSpec) -> Result<Gan> {
    let (generator, bytes, weights) = uwnr_gan::generator_or_bundled(s.weights.as_deref())
        .map_err(|e| failed("loading the UWGAN generator", e))?;
    Ok(Gan {
        config: generator.config.clone(),
        generator,
        fingerprint: fingerprint(&bytes),
        weights,
    })
}

/// What the settings record of the network.
#[derive(Serialize)]
struct NetworkRecord<'a> {
    weights: &'a str,
    fingerprint: &'a str,
    config: &'a GeneratorConfig,
    /// `bf16` for bf16 products, whose renders differ from f32's by up to one level; absent for
    /// f32 (so datasets made before this field resume unchanged).
    #[serde(skip_serializing_if = "is_f32")]
    precision: Precision,
    /// The stages after the water; absent when none runs.
    #[serde(skip_serializing_if = "WaterEffects::is_none")]
    effects: &'a WaterEffects,
    /// The clean balance; absent when none (as in datasets made before it).
    #[serde(skip_serializing_if = "CleanBalance::is_none")]
    balance: &'a CleanBalance,
    /// How far the balance follows each reference's water; absent when not at all (as in
    /// datasets made before it).
    #[serde(skip_serializing_if = "is_zero")]
    balance_water_share: f32,
    /// What the dataset stores as the clean side; absent when it is the photo as given (also
    /// when there is no balance to store it at).
    #[serde(skip_serializing_if = "Option::is_none")]
    clean_side: Option<&'a CleanSide>,
}

fn is_zero(v: &f32) -> bool {
    *v == 0.0
}

fn is_f32(p: &Precision) -> bool {
    *p == Precision::F32
}

/// What the settings record of the GAN baseline.
#[derive(Serialize)]
struct GanRecord<'a> {
    weights: &'a str,
    fingerprint: &'a str,
    config: &'a uwnr_gan::GeneratorConfig,
}

#[cfg(test)]
mod tests;
