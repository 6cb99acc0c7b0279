//! A loaded UWNR generator ready to render, on the implementation chosen at the edge: the
//! dedicated engine (`uwnr-engine`, in f32 or with bf16 products), or any other
//! [`Implementation`] of the forward pass (the training wing's burn module, for validation
//! renders and parity checks). Every implementation renders through the same padding and
//! tiling code ([`crate::infer`]); burn's and the engine's outputs agree within 1e-4.

use std::path::Path;
use std::sync::Arc;

use uwnr_core::Image;
use uwnr_engine::{EngineOptions, Precision};

use crate::config::GeneratorConfig;
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

/// Name of the engine backend, the one backend renders run on (bf16 products are
/// [`Backend::EngineBf16`], chosen by precision rather than by name).
pub const ENGINE_NAME: &str = "engine";

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
    /// No network: the config's correction is none ([`crate::config::Correction::None`]).
    Uncorrected,
}

/// A model with its config, ready to render: a generator (on the engine or another
/// implementation), or, when the config's correction is none, no network at all. Cloning is
/// cheap for the engine (shared, immutable weights) and copies another implementation's module.
#[derive(Clone, Debug)]
pub struct Network {
    config: GeneratorConfig,
    imp: Imp,
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
        if !config.runs_network() {
            return Err(ModelError::InvalidOptions(
                "the weights' config says its correction is none: such a model has no network \
                 to load (Network::uncorrected)"
                    .into(),
            ));
        }
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
        }
    }

    /// The model of an anchored `config` whose correction is none: the water, the depth stage,
    /// no network (nothing to load).
    pub fn uncorrected(config: &GeneratorConfig) -> Result<Self> {
        config.validate()?;
        if config.runs_network() {
            return Err(ModelError::InvalidOptions(
                "this config's correction is a network: load its weights".into(),
            ));
        }
        Ok(Self {
            config: *config,
            imp: Imp::Uncorrected,
        })
    }

    /// Whether a network runs in each render (false when the correction is none).
    #[must_use]
    pub fn runs_network(&self) -> bool {
        !matches!(self.imp, Imp::Uncorrected)
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
            Imp::Uncorrected => "none (no network runs)".to_string(),
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
        match &self.imp {
            Imp::Engine(engine) => render_with(engine.as_ref(), variant, clean, depth, style, opts),
            Imp::Other(imp) => render_with(imp.as_ref(), variant, clean, depth, style, opts),
            Imp::Uncorrected => crate::infer::render_uncorrected(clean, depth, style, opts),
        }
    }

    /// The style of the underwater image `reference` for this model ([`ReferenceStyle::new`]).
    pub fn style(&self, reference: &Image) -> Result<ReferenceStyle> {
        ReferenceStyle::new(reference, &self.config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{AnchorKind, Correction};
    use crate::infer::RenderOptions;

    fn water_model(correction: Correction) -> GeneratorConfig {
        GeneratorConfig {
            anchor: AnchorKind::Water,
            detail_retention: true,
            correction,
            ..GeneratorConfig::anchored(8)
        }
    }

    fn textured(w: usize, h: usize, tint: [f32; 3]) -> Image {
        let mut img = Image::filled(w, h, 3, 0.0);
        for (c, t) in tint.iter().enumerate() {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                *v = t * (0.5 + 0.4 * ((i % w) as f32 * 0.3 + (i / w) as f32 * 0.2).sin());
            }
        }
        img
    }

    #[test]
    fn without_a_correction_no_network_is_loaded_and_no_light_field_computed() {
        let none = water_model(Correction::None);
        let net = Network::uncorrected(&none).unwrap();
        assert!(!net.runs_network() && !none.runs_network() && !none.reads_light_field());
        let reference = textured(48, 40, [0.2, 0.7, 0.6]);
        let style = net.style(&reference).unwrap();
        assert!(style.light_field.is_none() && style.water.is_some());
        let clean = textured(40, 32, [0.9, 0.8, 0.7]);
        let depth = Image::filled(40, 32, 1, 0.5);
        let out = net
            .render(&clean, &depth, &style, &RenderOptions::default())
            .unwrap();
        assert_eq!(out.size(), clean.size());
        assert_ne!(out, clean);
        // A network config needs its weights; weights cannot come with no network.
        let with = water_model(Correction::Network);
        assert!(with.runs_network() && with.reads_light_field());
        assert!(Network::uncorrected(&with).is_err());
        let e = Network::from_tensors(&none, TensorMap::new(), &Backend::Engine).unwrap_err();
        assert!(e.to_string().contains("correction is none"), "{e}");
        // The paper's variant always runs its network.
        let paper = GeneratorConfig {
            correction: Correction::None,
            ..GeneratorConfig::with_base_width(8)
        };
        assert!(paper.validate().is_err());
        // Old configs (no field) read as a network; `none` round-trips.
        let old: GeneratorConfig = serde_json::from_str(
            r#"{"in_channels":9,"out_channels":6,"base_width":8,"light_field":"absolute","variant":"anchored","anchor":"water"}"#,
        )
        .unwrap();
        assert_eq!(old.correction, Correction::Network);
        assert!(!serde_json::to_string(&old).unwrap().contains("correction"));
        let text = serde_json::to_string(&none).unwrap();
        assert!(text.contains(r#""correction":"none""#), "{text}");
        assert_eq!(
            serde_json::from_str::<GeneratorConfig>(&text).unwrap(),
            none
        );
    }
}
