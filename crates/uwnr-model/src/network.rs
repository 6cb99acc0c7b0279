//! A loaded UWNR generator ready to render, on the implementation chosen at the edge: the
//! dedicated engine (`uwnr-engine`, the default) or burn's module on a burn device (`flex`,
//! or `tch` with that feature), kept for comparison and for training. Both render through the
//! same padding and tiling code ([`crate::infer`]) and agree within 1e-4 on the output.

use std::path::Path;
use std::sync::Arc;

use uwnr_core::Image;
use uwnr_engine::{EngineOptions, Precision};

use crate::config::{GeneratorConfig, Variant};
use crate::error::{ModelError, Result};
use crate::generator::Generator;
use crate::infer::{BurnForward, RenderOptions, render_with};
use crate::style::ReferenceStyle;
pub use crate::weights::engine_weights;
use crate::weights::{
    LoadedWeights, TensorMap, WeightsInfo, generator_from_tensors, generator_to_tensors,
    read_weights, read_weights_from_bytes,
};

/// Which implementation runs the generator.
#[derive(Clone, Debug)]
pub enum Backend {
    /// The dedicated CPU engine (fastest exact path; inference only).
    Engine,
    /// The engine with the Winograd products in bf16 with f32 sums: faster on CPUs with
    /// AVX512_BF16 (emulated, so no faster, elsewhere), outputs a little off `Engine`'s (see
    /// the README's bf16 figures).
    EngineBf16,
    /// burn's module on this device (`flex`, `tch`).
    Burn(burn::tensor::Device),
}

/// Names [`backend_from_name`] accepts in this build, the default first.
#[must_use]
pub fn backend_names() -> Vec<&'static str> {
    let mut names = vec![ENGINE_NAME];
    names.extend_from_slice(crate::device_names());
    names
}

/// Name of the engine backend.
pub const ENGINE_NAME: &str = "engine";

/// The backend called `name`: `"engine"`, or a burn device name ([`crate::device_from_name`]).
pub fn backend_from_name(name: &str) -> Result<Backend> {
    if name == ENGINE_NAME {
        return Ok(Backend::Engine);
    }
    crate::device_from_name(name)
        .map(Backend::Burn)
        .map_err(|_| ModelError::UnknownDevice {
            name: name.to_string(),
            available: backend_names().join(", "),
        })
}

#[derive(Clone, Debug)]
enum Imp {
    Engine(Arc<uwnr_engine::Generator>),
    Burn {
        generator: Box<Generator>,
        device: burn::tensor::Device,
    },
}

/// A generator with its config, ready to render. Cloning is cheap for the engine (shared,
/// immutable weights) and clones burn's module otherwise.
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
        let (imp, ignored) = match backend {
            Backend::Engine | Backend::EngineBf16 => {
                let (weights, ignored) = engine_weights(config, tensors)?;
                let precision = if matches!(backend, Backend::EngineBf16) {
                    Precision::Bf16
                } else {
                    Precision::F32
                };
                let opts = EngineOptions {
                    precision,
                    ..EngineOptions::default()
                };
                let engine = uwnr_engine::Generator::with_options(&weights, opts)?;
                (Imp::Engine(Arc::new(engine)), ignored)
            }
            Backend::Burn(device) => {
                let (generator, ignored) = generator_from_tensors(config, tensors, device)?;
                (
                    Imp::Burn {
                        generator: Box::new(generator),
                        device: device.clone(),
                    },
                    ignored,
                )
            }
        };
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

    /// The network of a burn module (e.g. the one being trained) on `backend`.
    pub fn from_generator(
        generator: &Generator,
        config: &GeneratorConfig,
        backend: &Backend,
    ) -> Result<Self> {
        match backend {
            Backend::Burn(device) => Ok(Self {
                config: *config,
                imp: Imp::Burn {
                    generator: Box::new(generator.clone()),
                    device: device.clone(),
                },
                zero_output: false,
            }),
            Backend::Engine | Backend::EngineBf16 => {
                let tensors = generator_to_tensors(generator, config)?;
                Ok(Self::from_tensors(config, tensors, backend)?.0)
            }
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

    /// The backend's name (`engine`, `engine (bf16)`, `flex`, `tch`).
    #[must_use]
    pub fn backend_name(&self) -> String {
        match &self.imp {
            Imp::Engine(e) if e.options().precision == Precision::Bf16 => {
                format!("{ENGINE_NAME} (bf16)")
            }
            Imp::Engine(_) => ENGINE_NAME.to_string(),
            Imp::Burn { device, .. } => format!("{device:?}"),
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
            Imp::Burn { generator, device } => render_with(
                &BurnForward { generator, device },
                variant,
                clean,
                depth,
                style,
                opts,
            ),
        }
    }

    /// The style of the underwater image `reference` for this network ([`ReferenceStyle::new`]).
    pub fn style(&self, reference: &Image) -> Result<ReferenceStyle> {
        ReferenceStyle::new(reference, &self.config)
    }
}
