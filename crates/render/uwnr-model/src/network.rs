//! A loaded UWNR generator ready to render, on the implementation chosen at the edge: the
//! dedicated engine (`uwnr-engine`, in f32 or with bf16 products), or any other
//! [`Implementation`] of the forward pass (the training wing's burn module, for validation
//! renders and parity checks). Every implementation renders through the same padding and
//! tiling code ([`crate::infer`]); burn's and the engine's outputs agree within 1e-4.

use std::path::Path;
use std::sync::Arc;

use uwnr_core::Image;
use uwnr_engine::{EngineOptions, Precision};

use crate::config::{GeneratorConfig, Variant};
use crate::error::{ModelError, Result};
use crate::infer::{Forward, RenderOptions, render_with};
use crate::style::ReferenceStyle;
pub use crate::weights::engine_weights;
use crate::weights::{
    LoadedWeights, TensorMap, WeightsInfo, read_weights, read_weights_from_bytes,
};

/// Which implementation runs the generator.
#[derive(Clone, Debug)]
pub enum Backend {
    /// The dedicated CPU engine (fastest exact path; inference only).
    Engine,
    /// The engine with the Winograd products in bf16 with f32 sums: faster on CPUs with
    /// AVX512_BF16 (emulated, so no faster, elsewhere), outputs a little off `Engine`'s (see
    /// the bf16 figures in `docs/speed.md`).
    EngineBf16,
}

/// Names [`backend_from_name`] accepts, the default first.
#[must_use]
pub fn backend_names() -> Vec<&'static str> {
    vec![ENGINE_NAME]
}

/// Name of the engine backend.
pub const ENGINE_NAME: &str = "engine";

/// The backend called `name`: `"engine"` (bf16 products are [`Backend::EngineBf16`], chosen by
/// precision rather than by name).
pub fn backend_from_name(name: &str) -> Result<Backend> {
    if name == ENGINE_NAME {
        return Ok(Backend::Engine);
    }
    Err(ModelError::UnknownDevice {
        name: name.to_string(),
        available: backend_names().join(", "),
    })
}

/// A forward pass of the generator other than the engine's, handed to a [`Network`] with
/// [`Network::from_implementation`] (the training wing's burn module is one).
pub trait Implementation: Forward + Send + Sync + std::fmt::Debug {
    /// Its name in reports (e.g. the burn device).
    fn name(&self) -> String;
    /// A copy for another worker.
    fn clone_box(&self) -> Box<dyn Implementation>;
}

impl Clone for Box<dyn Implementation> {
    fn clone(&self) -> Self {
        self.clone_box()
    }
}

#[derive(Clone, Debug)]
enum Imp {
    Engine(Arc<uwnr_engine::Generator>),
    Other(Box<dyn Implementation>),
}

/// A generator with its config, ready to render. Cloning is cheap for the engine (shared,
/// immutable weights) and copies another implementation's module.
#[derive(Clone, Debug)]
pub struct Network {
    config: GeneratorConfig,
    imp: Imp,
    /// The anchored network's output convolution is all zeros (weights and biases), so its
    /// correction is zero whatever the input: rendering skips the network (the bundled v5 model
    /// ships so; `MODEL_CARD.md` says why).
    zero_output: bool,
}

/// Whether the output convolution (`out.0`) of a state dict is all zeros.
fn output_is_zero(tensors: &TensorMap) -> bool {
    ["out.0.weight", "out.0.bias"].iter().all(|k| {
        tensors
            .get(*k)
            .is_some_and(|t| t.data.iter().all(|&v| v == 0.0))
    })
}

impl Network {
    /// Builds the network from weights read into memory.
    pub fn from_weights(loaded: LoadedWeights, backend: &Backend) -> Result<(Self, WeightsInfo)> {
        let LoadedWeights {
            config,
            tensors,
            mut info,
        } = loaded;
        let (net, ignored) = Self::from_tensors(&config, tensors, backend)?;
        info.ignored_keys = ignored;
        Ok((net, info))
    }

    /// Builds the network for `config` from a state dict under the authors' keys; returns it
    /// with the keys present but unused (the `.norm.` keys).
    pub fn from_tensors(
        config: &GeneratorConfig,
        tensors: TensorMap,
        backend: &Backend,
    ) -> Result<(Self, Vec<String>)> {
        let zero_output = config.variant == Variant::Anchored && output_is_zero(&tensors);
        let (weights, ignored) = engine_weights(config, tensors)?;
        let precision = match backend {
            Backend::Engine => Precision::F32,
            Backend::EngineBf16 => Precision::Bf16,
        };
        let opts = EngineOptions {
            precision,
            ..EngineOptions::default()
        };
        let engine = uwnr_engine::Generator::with_options(&weights, opts)?;
        let imp = Imp::Engine(Arc::new(engine));
        Ok((
            Self {
                config: *config,
                imp,
                zero_output,
            },
            ignored,
        ))
    }

    /// Loads a weights file (safetensors or PyTorch checkpoint).
    pub fn load(path: &Path, backend: &Backend) -> Result<(Self, WeightsInfo)> {
        Self::from_weights(read_weights(path)?, backend)
    }

    /// [`Network::load`] for weights held in memory.
    pub fn load_from_bytes(bytes: &[u8], backend: &Backend) -> Result<(Self, WeightsInfo)> {
        Self::from_weights(read_weights_from_bytes(bytes)?, backend)
    }

    /// The network of another implementation of the forward pass (e.g. burn's module being
    /// trained) with its config.
    #[must_use]
    pub fn from_implementation(config: &GeneratorConfig, imp: Box<dyn Implementation>) -> Self {
        Self {
            config: *config,
            imp: Imp::Other(imp),
            zero_output: false,
        }
    }

    /// Whether the network's correction is zero whatever its input, so renders skip it.
    #[must_use]
    pub fn skips_network(&self) -> bool {
        self.zero_output
    }

    /// The generator's config.
    #[must_use]
    pub fn config(&self) -> &GeneratorConfig {
        &self.config
    }

    /// Whether the network runs the engine with bf16 products (outputs a little off the f32
    /// paths', see [`Backend::EngineBf16`]).
    #[must_use]
    pub fn is_bf16(&self) -> bool {
        matches!(&self.imp, Imp::Engine(e) if e.options().precision == Precision::Bf16)
    }

    /// The backend's name (`engine`, `engine (bf16)`, or another implementation's).
    #[must_use]
    pub fn backend_name(&self) -> String {
        match &self.imp {
            Imp::Engine(e) if e.options().precision == Precision::Bf16 => {
                format!("{ENGINE_NAME} (bf16)")
            }
            Imp::Engine(_) => ENGINE_NAME.to_string(),
            Imp::Other(imp) => imp.name(),
        }
    }

    /// Renders `clean` (3 channels) in the style of a reference (its light field resized to
    /// the clean image, and for the anchored variant its water), using `depth` (1 channel, the
    /// clean image's size). The output has that size too, values in [0, 1].
    pub fn render(
        &self,
        clean: &Image,
        depth: &Image,
        style: &ReferenceStyle,
        opts: &RenderOptions,
    ) -> Result<Image> {
        let variant = self.config.variant;
        if self.zero_output {
            return crate::infer::render_anchor_only(clean, depth, style, opts);
        }
        match &self.imp {
            Imp::Engine(engine) => render_with(engine.as_ref(), variant, clean, depth, style, opts),
            Imp::Other(imp) => render_with(imp.as_ref(), variant, clean, depth, style, opts),
        }
    }

    /// The style of the underwater image `reference` for this network ([`ReferenceStyle::new`]).
    pub fn style(&self, reference: &Image) -> Result<ReferenceStyle> {
        ReferenceStyle::new(reference, &self.config)
    }
}
