//! What turns a clean image into its underwater twin in a dataset run: the UWNR network, the
//! UWGAN-style GAN baseline of `uwnr-gan`, or one of the physical / statistical baselines of
//! `uwnr-baselines`.

use std::sync::Mutex;

use serde_json::json;
use uwnr_baselines::{Method, RenderInput, SeathruCoefficients};
use uwnr_core::Image;
use uwnr_model::{
    DepthResponse, GeneratorConfig, Network as Generator, ReferenceStyle, RenderOptions,
};

use crate::error::{DatasetError, Result};

/// The UWNR generator with what it runs on.
pub struct Network {
    /// Cloned once per worker thread (the engine's weights are shared, burn's module copied).
    generator: Mutex<Generator>,
    config: GeneratorConfig,
    options: RenderOptions,
    /// Where the weights came from (a path, or "bundled model").
    weights: String,
    /// A fingerprint of the weight bytes, so a resumed run cannot switch models silently.
    fingerprint: String,
    /// Whether the network runs with bf16 products (recorded, so a resume cannot mix them).
    bf16: bool,
}

/// The GAN baseline's generator (it needs no reference: the water comes from a code drawn from
/// each pair's seed).
pub struct Gan {
    /// Cloned once per worker thread.
    generator: Mutex<uwnr_gan::Generator>,
    config: uwnr_gan::GeneratorConfig,
    device: uwnr_model::Device,
    /// Where the weights came from (a path, or the bundled model).
    weights: String,
    /// A fingerprint of the weight bytes, so a resumed run cannot switch models silently.
    fingerprint: String,
}

/// The rendering method of a dataset.
pub enum Renderer {
    /// The UWNR network (needs references).
    Network(Box<Network>),
    /// The UWGAN-style GAN baseline (uses no reference).
    Gan(Box<Gan>),
    /// A baseline; its random parameters are drawn from each pair's seed.
    Baseline(Method),
}

impl Renderer {
    /// The network renderer. `weights` names the weights' origin; `weight_bytes` is hashed
    /// into the fingerprint recorded in the dataset settings.
    #[must_use]
    pub fn network(
        generator: Generator,
        options: RenderOptions,
        weights: String,
        weight_bytes: &[u8],
    ) -> Self {
        Self::Network(Box::new(Network {
            config: *generator.config(),
            bf16: generator.is_bf16(),
            generator: Mutex::new(generator),
            options,
            weights,
            fingerprint: format!("fnv1a64:{:016x}", fnv1a64(weight_bytes)),
        }))
    }

    /// The GAN baseline's renderer, running on `device`. `weights` names the weights' origin;
    /// `weight_bytes` is hashed into the fingerprint recorded in the dataset settings.
    #[must_use]
    pub fn gan(
        generator: uwnr_gan::Generator,
        device: uwnr_model::Device,
        weights: String,
        weight_bytes: &[u8],
    ) -> Self {
        Self::Gan(Box::new(Gan {
            config: generator.config.clone(),
            generator: Mutex::new(generator),
            device,
            weights,
            fingerprint: format!("fnv1a64:{:016x}", fnv1a64(weight_bytes)),
        }))
    }

    /// The method's name (`uwnr`, `uwgan`, `jerlov`, ...).
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Network(_) => "uwnr",
            Self::Gan(_) => "uwgan",
            Self::Baseline(m) => m.name(),
        }
    }

    /// The configuration recorded in the dataset settings (compared on resume, so a value that
    /// cannot be serialised is an error rather than a `null` that would match another).
    pub fn settings_params(&self) -> Result<serde_json::Value> {
        let value = match self {
            Self::Network(n) => serde_json::to_value(NetworkParams {
                weights: &n.weights,
                fingerprint: &n.fingerprint,
                config: &n.config,
                precision: n.bf16.then_some("bf16"),
            }),
            Self::Gan(g) => serde_json::to_value(GanParams {
                weights: &g.weights,
                fingerprint: &g.fingerprint,
                config: &g.config,
            }),
            Self::Baseline(m) => serde_json::to_value(m),
        };
        value
            .map_err(|e| DatasetError::Invalid(format!("cannot record the method's settings: {e}")))
    }

    /// What a render takes of the decoded reference `img`: for the network its style (light
    /// field in the map its config names, and the water for the anchored variant); the
    /// baselines do not read a light field, so the released map is kept for them (saved with
    /// `--save-lightfield`).
    pub fn reference_style(&self, img: &Image) -> std::result::Result<ReferenceStyle, String> {
        match self {
            Self::Network(n) => ReferenceStyle::new(img, &n.config).map_err(|e| e.to_string()),
            Self::Gan(_) | Self::Baseline(_) => uwnr_core::lightfield::light_field(img)
                .map(ReferenceStyle::from_light_field)
                .map_err(|e| e.to_string()),
        }
    }

    /// Whether renders must have a reference.
    #[must_use]
    pub fn needs_reference(&self) -> bool {
        match self {
            Self::Network(_) => true,
            Self::Gan(_) => false,
            Self::Baseline(m) => m.needs_reference(),
        }
    }

    /// Whether renders use a reference when references are given (Sea-thru fitted from the
    /// reference does; Jerlov never does).
    #[must_use]
    pub fn uses_reference(&self) -> bool {
        match self {
            Self::Network(_) => true,
            Self::Gan(_) => false,
            Self::Baseline(Method::Seathru(p)) => {
                matches!(p.coefficients, SeathruCoefficients::FromReference(_))
            }
            Self::Baseline(m) => m.needs_reference(),
        }
    }

    /// A per-thread handle (the network is cloned so threads never share it).
    pub fn worker(&self) -> Result<Worker<'_>> {
        Ok(match self {
            Self::Network(n) => {
                let generator = n
                    .generator
                    .lock()
                    .map_err(|_| DatasetError::Invalid("the network's lock is poisoned".into()))?
                    .clone();
                Worker::Network {
                    generator: Box::new(generator),
                    net: n,
                }
            }
            Self::Gan(g) => Worker::Gan {
                generator: Box::new(
                    g.generator
                        .lock()
                        .map_err(|_| {
                            DatasetError::Invalid("the generator's lock is poisoned".into())
                        })?
                        .clone(),
                ),
                gan: g,
            },
            Self::Baseline(m) => Worker::Baseline(m),
        })
    }
}

/// What the settings record of the GAN baseline.
#[derive(serde::Serialize)]
struct GanParams<'a> {
    weights: &'a str,
    fingerprint: &'a str,
    config: &'a uwnr_gan::GeneratorConfig,
}

/// What the settings record of the network.
#[derive(serde::Serialize)]
struct NetworkParams<'a> {
    weights: &'a str,
    fingerprint: &'a str,
    config: &'a GeneratorConfig,
    /// `bf16` for bf16 products, whose renders differ from f32's by up to one level; absent
    /// for f32 (so datasets made before this field resume unchanged).
    #[serde(skip_serializing_if = "Option::is_none")]
    precision: Option<&'static str>,
}

/// A renderer as one worker thread holds it.
pub enum Worker<'a> {
    Network {
        generator: Box<Generator>,
        net: &'a Network,
    },
    Gan {
        generator: Box<uwnr_gan::Generator>,
        gan: &'a Gan,
    },
    Baseline(&'a Method),
}

/// What a render gets of its reference.
pub struct ReferenceInput<'a> {
    /// The decoded reference (baselines).
    pub image: Option<&'a Image>,
    /// The reference's style (its 256x256 light-field map, and its water).
    pub style: &'a ReferenceStyle,
}

impl Worker<'_> {
    /// Whether this worker needs the decoded reference image (the network needs only its
    /// light field).
    #[must_use]
    pub fn wants_reference_image(&self) -> bool {
        matches!(self, Self::Baseline(_))
    }

    /// Renders one pair; returns the underwater image and the parameters to record. `response`
    /// is how the network responds to `depth` (what its values stand for, how far they are
    /// trusted), recorded with its pairs; the baselines read the map with their own scales.
    pub fn render(
        &self,
        clean: &Image,
        depth: &Image,
        response: &DepthResponse,
        reference: Option<ReferenceInput<'_>>,
        seed: u64,
    ) -> std::result::Result<(Image, serde_json::Value), String> {
        match self {
            Self::Network { generator, net } => {
                let reference = reference.ok_or("the network needs a reference")?;
                let out = generator
                    .render(
                        clean,
                        depth,
                        reference.style,
                        &RenderOptions {
                            depth: *response,
                            ..net.options
                        },
                    )
                    .map_err(|e| format!("rendering: {e}"))?;
                Ok((
                    out,
                    json!({ "weights": net.weights, "depth": depth_record(response) }),
                ))
            }
            Self::Gan { generator, gan } => {
                let (out, v) =
                    uwnr_gan::render_with_values(generator, clean, depth, seed, &gan.device)
                        .map_err(|e| format!("rendering with uwgan: {e}"))?;
                Ok((
                    out,
                    json!({
                        "weights": gan.weights,
                        "z_seed": seed,
                        "beta": v.beta,
                        "backlight": v.backlight,
                        "vignette": v.vignette,
                        "gain": v.gain,
                    }),
                ))
            }
            Self::Baseline(method) => {
                let input = RenderInput {
                    clean,
                    depth,
                    reference: reference.and_then(|r| r.image),
                };
                let rendered = uwnr_baselines::render(method, &input, seed)
                    .map_err(|e| format!("rendering with {}: {e}", method.name()))?;
                Ok((rendered.image, rendered.params))
            }
        }
    }
}

/// What a pair records of its depth response: `scale` (`relative` with `scene_m`, `metric` with
/// `max_m`, or `absolute`) and `trust`, rounded to 4 decimals so that the manifest's numbers read
/// back and write out unchanged (an f32 widened to f64 prints 17 digits, which a JSON reader
/// need not return exactly).
#[must_use]
pub fn depth_record(response: &DepthResponse) -> serde_json::Value {
    let round = |v: f32| (f64::from(v) * 1e4).round() / 1e4;
    let trust = round(response.trust);
    match response.scale {
        uwnr_model::DepthScale::Relative { scene_m } => {
            json!({ "scale": "relative", "scene_m": round(scene_m), "trust": trust })
        }
        uwnr_model::DepthScale::Metric { max_m } => {
            json!({ "scale": "metric", "max_m": round(max_m), "trust": trust })
        }
        uwnr_model::DepthScale::Absolute => json!({ "scale": "absolute", "trust": trust }),
    }
}

/// FNV-1a, 64 bit: a fingerprint of the weights (identity, not security).
#[must_use]
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    bytes
        .iter()
        .fold(OFFSET, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_published_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn bf16_products_are_recorded_and_f32_settings_keep_their_old_form() {
        let config = GeneratorConfig::with_base_width(8);
        let generator = config.init(&uwnr_model::Device::flex()).unwrap();
        let params = |backend: &uwnr_model::Backend| {
            let network =
                uwnr_model::Network::from_generator(&generator, &config, backend).unwrap();
            Renderer::network(network, RenderOptions::default(), "w".into(), b"x")
                .settings_params()
                .unwrap()
        };
        let f32 = params(&uwnr_model::Backend::Engine);
        let bf16 = params(&uwnr_model::Backend::EngineBf16);
        assert!(f32.get("precision").is_none(), "{f32}");
        assert_eq!(bf16["precision"], "bf16");
        assert_ne!(f32, bf16, "a resume with the other precision is refused");
        let mut without = bf16.clone();
        without.as_object_mut().unwrap().remove("precision");
        assert_eq!(without, f32, "nothing else differs");
    }

    #[test]
    fn a_run_whose_workers_cannot_start_is_incomplete_and_verify_agrees() {
        let tmp = tempfile::tempdir().unwrap();
        let (clean, refs) = (tmp.path().join("clean"), tmp.path().join("refs"));
        std::fs::create_dir_all(&clean).unwrap();
        std::fs::create_dir_all(&refs).unwrap();
        for k in 0..2 {
            let img = Image::filled(24, 20, 3, 0.2 + 0.3 * k as f32);
            uwnr_core::io::save_rgb(&clean.join(format!("c{k}.png")), &img).unwrap();
            uwnr_core::io::save_rgb(&refs.join(format!("r{k}.png")), &img).unwrap();
        }
        let config = GeneratorConfig::with_base_width(8);
        let device = uwnr_model::Device::flex();
        let generator = config.init(&device).unwrap();
        let network =
            uwnr_model::Network::from_generator(&generator, &config, &uwnr_model::Backend::Engine)
                .unwrap();
        let renderer = Renderer::network(network, RenderOptions::default(), "test".into(), b"");
        // A worker takes its copy of the network under the lock: a poisoned lock stops every
        // worker from starting.
        let Renderer::Network(n) = &renderer else {
            unreachable!()
        };
        let _ = std::thread::scope(|s| {
            s.spawn(|| {
                let _held = n.generator.lock();
                panic!("poisoning the network's lock");
            })
            .join()
        });
        let spec = crate::Spec {
            clean: vec![clean],
            references: vec![refs],
            per_image: 1,
            seed: 1,
            size: crate::Size::Native,
            save_depth: false,
            save_lightfield: false,
            depth: uwnr_depth::DepthSource::Builtin,
            depth_policy: crate::DepthPolicy::default(),
        };
        let opts = crate::RunOptions {
            shard: None,
            jobs: 2,
            limits: uwnr_core::io::DecodeLimits::default(),
            gallery: true,
        };
        let out = tmp.path().join("out");
        let stop = std::sync::atomic::AtomicBool::new(false);
        let summary = crate::generate(&out, &spec, &renderer, &opts, &stop, &mut |_| {}).unwrap();
        assert_eq!(summary.rendered, 0);
        assert!(summary.failures.is_empty() && !summary.interrupted);
        assert!(!summary.complete && !summary.ok());
        assert_eq!(
            summary.worker_errors.len(),
            2,
            "{:?}",
            summary.worker_errors
        );
        let report = crate::verify(&out, &|_, _| {}).unwrap();
        assert!(!report.ok());
        assert!(
            report.problems.iter().any(|p| p.contains("missing")),
            "{:?}",
            report.problems
        );
    }
}
