//! What a render method is: [`MethodKind`] names one, [`MethodSpec`] is one with every setting
//! it renders with. A spec is what a dataset records, what `--method-config` files and Python's
//! keywords hold, and what [`crate::Renderer::load`] turns into a renderer.
//!
//! JSON is tagged by `"method"`, e.g. `{"method": "jerlov", "water_type": "3C"}` or
//! `{"method": "uwnr", "precision": "bf16"}`; missing fields take their defaults, and the
//! baselines' JSON is `uwnr_baselines::Method`'s, so their config files read unchanged.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use uwnr_baselines::{
    JerlovParams, Method, ReferenceCoefficients, ReinhardParams, SampledCoefficients,
    SeathruCoefficients, SeathruParams, UisaParams,
};
use uwnr_model::water::CleanBalance;
use uwnr_model::{RenderOptions, WaterEffects};

use crate::error::{RenderError, Result};
use crate::haze::HazeParams;
use crate::revised::RevisedParams;

/// The render methods, by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MethodKind {
    /// uwnr's model: the reference's water on the photo's own colours, the depth stage and the
    /// effects of real water; the bundled model runs no network (its correction is none), while
    /// weights given add the UWNR generator's correction from the reference's light field.
    Uwnr,
    /// The UWGAN-style GAN baseline: water parameters predicted from the clean image, its depth
    /// and a code drawn from the seed.
    Uwgan,
    /// UWCNN's synthesis with the ten Jerlov water types.
    Jerlov,
    /// The reference-based physical model in the manner of Hou et al. 2020 (SUID).
    Uisa,
    /// The revised (Sea-thru) image formation model.
    Seathru,
    /// Reinhard et al. 2001 colour transfer from the reference.
    Reinhard,
    /// The revised model with forward scattering and an inhomogeneous medium: Sea-thru's
    /// render, then the two stages ([`crate::revised`]).
    Revised,
    /// Plain haze `I = J t + B (1 - t)` with a given veil and attenuation: a control.
    Haze,
}

impl MethodKind {
    /// Every method, in the order the docs list them.
    pub const ALL: [Self; 8] = [
        Self::Uwnr,
        Self::Uwgan,
        Self::Jerlov,
        Self::Uisa,
        Self::Seathru,
        Self::Revised,
        Self::Reinhard,
        Self::Haze,
    ];

    /// The method's name (`--method`, the `"method"` tag, Python's `method=`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Uwnr => "uwnr",
            Self::Uwgan => "uwgan",
            Self::Jerlov => "jerlov",
            Self::Uisa => "uisa",
            Self::Seathru => "seathru",
            Self::Reinhard => "reinhard",
            Self::Revised => "revised",
            Self::Haze => "haze",
        }
    }

    /// One line on what the method does, for `--help`.
    #[must_use]
    pub const fn summary(self) -> &'static str {
        match self {
            Self::Uwnr => {
                "uwnr's model: the reference's water on the photo's own colours, depth (farther \
                 is hazier) and the effects of real water; the bundled model runs no network, \
                 --weights adds the UWNR generator's correction from the reference's light field"
            }
            Self::Uwgan => {
                "The UWGAN-style GAN baseline (`uwnr gan train`): water parameters predicted from \
                 the clean image, its depth and a code drawn from --seed; no reference needed. \
                 Bundled model unless --weights names a trained generator"
            }
            Self::Jerlov => {
                "UWCNN's synthesis with the ten Jerlov water types (no reference needed)"
            }
            Self::Uisa => "Reference-based physical model in the manner of Hou et al. 2020 (SUID)",
            Self::Seathru => "The revised (Sea-thru) image formation model",
            Self::Reinhard => "Reinhard et al. 2001 colour transfer from the reference",
            Self::Revised => {
                "The revised model with forward scattering (a point spread widening with \
                 distance) and an inhomogeneous medium: Sea-thru, then the two stages \
                 (--method-config sets their strengths)"
            }
            Self::Haze => {
                "Plain haze I = J t + B (1 - t) with a given veil B and attenuation beta \
                 (--method-config; no reference needed): a control"
            }
        }
    }

    /// Whether the method runs trained weights (`--weights`, a device, a bundled model).
    #[must_use]
    pub const fn loads_weights(self) -> bool {
        matches!(self, Self::Uwnr | Self::Uwgan)
    }

    /// The names of all methods, comma-separated.
    #[must_use]
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }
}

impl fmt::Display for MethodKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for MethodKind {
    type Err = RenderError;

    fn from_str(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| RenderError::UnknownMethod {
                name: s.to_string(),
                known: Self::names(),
            })
    }
}

/// Arithmetic of the network's heavy products.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// f32 throughout.
    #[default]
    F32,
    /// bf16 operands with f32 sums (the engine only): faster on CPUs with AVX512_BF16, outputs
    /// up to one 8-bit level off the f32 ones.
    Bf16,
}

/// What runs a network. Renders run on uwnr's CPU inference engine (the UWNR generator on
/// `uwnr-engine`, the GAN's small generator in plain Rust); the training framework's devices
/// (`flex`, `tch`) are the training wing's. The field stays in specs and dataset records, which
/// name it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ComputeDevice {
    /// uwnr's CPU inference engine.
    #[default]
    Engine,
}

impl ComputeDevice {
    /// The device's name (`engine`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Engine => uwnr_model::ENGINE_NAME,
        }
    }
}

/// The UWNR network's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UwnrSpec {
    /// Weights (safetensors with the authors' keys, or their checkpoint); `None`: the bundled
    /// model.
    pub weights: Option<PathBuf>,
    /// What runs the network.
    pub device: ComputeDevice,
    /// Arithmetic of the convolutions (bf16 on the engine only).
    pub precision: Precision,
    /// Images with more pixels than this are rendered in overlapping tiles.
    pub max_whole_pixels: usize,
    /// Tile edge in pixels (a multiple of 16).
    pub tile: usize,
    /// Overlap of tiles in pixels (a multiple of 16).
    pub overlap: usize,
    /// What real photos have that the water alone lacks (particles, light from above, colours
    /// the water removes, forward scattering, an uneven medium), drawn from each render's seed;
    /// `uwnr_model::WaterEffects::DEFAULT` unless set.
    pub effects: WaterEffects,
    /// Per-channel gains on the clean photo before the water, bringing it to the white point
    /// of the real pairs' clean sides the waters were fitted from
    /// (`uwnr_model::water::CleanBalance`); `[1, 1, 1]` for none. The bank's unless set.
    pub balance: CleanBalance,
    /// The share of its water's cast a real clean side keeps: the balance follows each
    /// reference's chromaticity by this much (`uwnr_model::water::CleanBalance::following`);
    /// 0 for the fixed balance (v8), the default; the bank's fitted share is
    /// `uwnr_model::water::BANK_WATER_SHARE` (0.325).
    pub balance_water_share: f32,
    /// What a dataset stores as a pair's clean side: the photo as given, the photo at the
    /// clean balance (the white point real pairs' clean sides have), or that photo under the
    /// underwater side's light (the default), so that a pair is made as a real pair is: the
    /// underwater side and a clean side at that white point and in the same light, at the
    /// strength drawn from real pairs.
    pub clean_side: CleanSide,
}

/// What `uwnr dataset` stores as the clean side of the uwnr method's pairs ([`UwnrSpec`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CleanSide {
    /// The photo as given.
    Photo,
    /// The photo at the method's clean balance (v8's clean side).
    Balanced,
    /// The photo at the clean balance, lit as the underwater side is (the effects' light from
    /// above and vignette): the scene's light, which real pairs' clean sides keep, is then on
    /// both sides, and a pair differs by the water alone (the default).
    #[default]
    Lit,
}

impl CleanSide {
    /// Whether this is the photo as given (the form datasets had before the choice existed).
    #[must_use]
    pub fn is_photo(&self) -> bool {
        *self == Self::Photo
    }
}

impl Default for UwnrSpec {
    fn default() -> Self {
        let o = RenderOptions::default();
        Self {
            weights: None,
            device: ComputeDevice::default(),
            precision: Precision::default(),
            max_whole_pixels: o.max_tile_pixels,
            tile: o.tile,
            overlap: o.overlap,
            effects: WaterEffects::DEFAULT,
            balance: CleanBalance::BANK,
            balance_water_share: 0.0,
            clean_side: CleanSide::Lit,
        }
    }
}

impl UwnrSpec {
    /// The tiling as the network's render options (the depth response is set per render).
    #[must_use]
    pub fn render_options(&self) -> RenderOptions {
        RenderOptions {
            max_tile_pixels: self.max_whole_pixels,
            tile: self.tile,
            overlap: self.overlap,
            ..RenderOptions::default()
        }
    }
}

/// The GAN baseline's settings.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UwganSpec {
    /// A generator (`generator.safetensors` of `uwnr gan train`); `None`: the bundled one.
    pub weights: Option<PathBuf>,
    /// What runs it.
    pub device: ComputeDevice,
}

/// A render method with all its settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum MethodSpec {
    /// The UWNR network.
    Uwnr(UwnrSpec),
    /// The UWGAN-style GAN baseline.
    Uwgan(UwganSpec),
    /// UWCNN's Jerlov water types.
    Jerlov(JerlovParams),
    /// UISA-style synthesis from a reference.
    Uisa(UisaParams),
    /// The revised (Sea-thru) model.
    Seathru(SeathruParams),
    /// Reinhard colour transfer.
    Reinhard(ReinhardParams),
    /// The revised model with forward scattering and an inhomogeneous medium.
    Revised(RevisedParams),
    /// Plain haze, a control.
    Haze(HazeParams),
}

/// Sea-thru's defaults: coefficients fitted to the reference when renders have one, else sampled
/// on the Jerlov manifold.
fn seathru_defaults(have_reference: bool) -> SeathruParams {
    SeathruParams {
        coefficients: if have_reference {
            SeathruCoefficients::FromReference(ReferenceCoefficients::default())
        } else {
            SeathruCoefficients::Sampled(SampledCoefficients::default())
        },
        ..SeathruParams::default()
    }
}

/// Whether a method reads the reference image of a render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceUse {
    /// Never (its water comes from its own parameters).
    Ignored,
    /// When one is given; it renders without one too.
    Optional,
    /// Always: a render without one fails.
    Required,
}

impl MethodSpec {
    /// Which method this is.
    #[must_use]
    pub const fn kind(&self) -> MethodKind {
        match self {
            Self::Uwnr(_) => MethodKind::Uwnr,
            Self::Uwgan(_) => MethodKind::Uwgan,
            Self::Jerlov(_) => MethodKind::Jerlov,
            Self::Uisa(_) => MethodKind::Uisa,
            Self::Seathru(_) => MethodKind::Seathru,
            Self::Reinhard(_) => MethodKind::Reinhard,
            Self::Revised(_) => MethodKind::Revised,
            Self::Haze(_) => MethodKind::Haze,
        }
    }

    /// The method's name.
    #[must_use]
    pub const fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// The method with its default settings, for renders that have references
    /// (`have_reference`) or not. This is where a reference decides where Sea-thru's
    /// coefficients come from: fitted to the reference when there is one, else sampled on the
    /// Jerlov manifold.
    #[must_use]
    pub fn defaults(kind: MethodKind, have_reference: bool) -> Self {
        match kind {
            MethodKind::Uwnr => Self::Uwnr(UwnrSpec::default()),
            MethodKind::Uwgan => Self::Uwgan(UwganSpec::default()),
            MethodKind::Jerlov => Self::Jerlov(JerlovParams::default()),
            MethodKind::Uisa => Self::Uisa(UisaParams::default()),
            MethodKind::Seathru => Self::Seathru(seathru_defaults(have_reference)),
            MethodKind::Revised => Self::Revised(RevisedParams {
                seathru: seathru_defaults(have_reference),
                ..RevisedParams::default()
            }),
            MethodKind::Reinhard => Self::Reinhard(ReinhardParams::default()),
            MethodKind::Haze => Self::Haze(HazeParams::default()),
        }
    }

    /// The method `kind` with `keywords` set over [`MethodSpec::defaults`] (JSON values by
    /// option name, as in the method's JSON). An option the method does not have is an error
    /// naming the options it has, never ignored.
    pub fn from_keywords(
        kind: MethodKind,
        keywords: &Map<String, Value>,
        have_reference: bool,
    ) -> Result<Self> {
        let defaults = Self::defaults(kind, have_reference);
        let Value::Object(mut fields) =
            serde_json::to_value(&defaults).map_err(|e| RenderError::Invalid(e.to_string()))?
        else {
            return Err(RenderError::Invalid(format!(
                "the settings of method {kind} are not a JSON object"
            )));
        };
        let mut known: Vec<String> = fields.keys().filter(|k| *k != "method").cloned().collect();
        known.sort();
        for (key, v) in keywords {
            if key == "method" || !fields.contains_key(key) {
                return Err(RenderError::UnknownOption {
                    method: kind.name(),
                    option: key.clone(),
                    known: known.join(", "),
                });
            }
            fields.insert(key.clone(), v.clone());
        }
        serde_json::from_value(Value::Object(fields)).map_err(|e| RenderError::BadOptions {
            method: kind.name(),
            reason: e.to_string(),
        })
    }

    /// A method read from JSON (a `--method-config` file), which must be `kind` when one is
    /// asked for.
    pub fn from_json(text: &str, kind: Option<MethodKind>) -> Result<Self> {
        let spec: Self =
            serde_json::from_str(text).map_err(|e| RenderError::Invalid(e.to_string()))?;
        match kind {
            Some(k) if k != spec.kind() => Err(RenderError::Invalid(format!(
                "the config is for {}, not {k}",
                spec.name()
            ))),
            _ => Ok(spec),
        }
    }

    /// The baseline of `uwnr_baselines` this spec is, if it is one.
    #[must_use]
    pub fn baseline(&self) -> Option<Method> {
        match self {
            Self::Jerlov(p) => Some(Method::Jerlov(p.clone())),
            Self::Uisa(p) => Some(Method::Uisa(p.clone())),
            Self::Seathru(p) => Some(Method::Seathru(p.clone())),
            Self::Reinhard(p) => Some(Method::Reinhard(p.clone())),
            Self::Uwnr(_) | Self::Uwgan(_) | Self::Revised(_) | Self::Haze(_) => None,
        }
    }

    /// The spec of a `uwnr_baselines` method.
    #[must_use]
    pub fn from_baseline(method: Method) -> Self {
        match method {
            Method::Jerlov(p) => Self::Jerlov(p),
            Method::Uisa(p) => Self::Uisa(p),
            Method::Seathru(p) => Self::Seathru(p),
            Method::Reinhard(p) => Self::Reinhard(p),
        }
    }

    /// What a render of this method does with a reference.
    #[must_use]
    pub fn reference_use(&self) -> ReferenceUse {
        let needs = match self {
            Self::Uwnr(_) => true,
            Self::Uwgan(_) | Self::Haze(_) => false,
            Self::Jerlov(_) | Self::Uisa(_) | Self::Seathru(_) | Self::Reinhard(_) => {
                self.baseline().is_some_and(|m| m.needs_reference())
            }
            Self::Revised(p) => p.baseline().needs_reference(),
        };
        if needs {
            ReferenceUse::Required
        } else {
            ReferenceUse::Ignored
        }
    }

    /// Checks the settings that can be checked before anything is loaded.
    pub fn validate(&self) -> Result<()> {
        match self {
            Self::Uwnr(s) => {
                s.render_options()
                    .validate()
                    .and_then(|()| s.effects.validate())
                    .and_then(|()| s.balance.validate())
                    .map_err(|e| RenderError::Invalid(e.to_string()))?;
                if !(0.0..=1.0).contains(&s.balance_water_share) {
                    return Err(RenderError::Invalid(format!(
                        "balance_water_share {} must be within [0, 1]",
                        s.balance_water_share
                    )));
                }
                Ok(())
            }
            Self::Haze(p) => p.validate(),
            Self::Revised(p) => p.validate(),
            Self::Uwgan(_)
            | Self::Jerlov(_)
            | Self::Uisa(_)
            | Self::Seathru(_)
            | Self::Reinhard(_) => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_an_unknown_name_lists_the_methods() {
        for k in MethodKind::ALL {
            assert_eq!(k.name().parse::<MethodKind>().unwrap(), k);
            assert_eq!(MethodSpec::defaults(k, true).kind(), k);
            let json = serde_json::to_value(MethodSpec::defaults(k, false)).unwrap();
            assert_eq!(json["method"], k.name());
        }
        let e = "jerlow".parse::<MethodKind>().unwrap_err().to_string();
        assert!(e.contains("jerlow") && e.contains("reinhard, haze"), "{e}");
        let MethodSpec::Revised(p) = MethodSpec::from_json(
            r#"{"method":"revised","medium":0.2,"seathru":{"coefficients":{"mode":"sampled"}}}"#,
            Some(MethodKind::Revised),
        )
        .unwrap() else {
            panic!()
        };
        assert_eq!((p.medium, p.forward_scatter), (0.2, 0.3));
    }

    #[test]
    fn baseline_json_is_the_baselines_json() {
        for text in [
            r#"{"method":"jerlov","water_type":"3C"}"#,
            r#"{"method":"reinhard","space":"rgb","match_std":false}"#,
            r#"{"method":"seathru","coefficients":{"mode":"given","beta_d":[0.4,0.1,0.1],"beta_b":[0.3,0.1,0.1],"b_inf":[0.1,0.4,0.5]}}"#,
            r#"{"method":"uisa"}"#,
        ] {
            let method: Method = serde_json::from_str(text).unwrap();
            let spec = MethodSpec::from_json(text, None).unwrap();
            assert_eq!(spec.baseline().unwrap(), method);
            assert_eq!(
                serde_json::to_value(&spec).unwrap(),
                serde_json::to_value(&method).unwrap()
            );
            assert_eq!(MethodSpec::from_baseline(method), spec);
        }
        let e = MethodSpec::from_json(r#"{"method":"uisa"}"#, Some(MethodKind::Jerlov))
            .unwrap_err()
            .to_string();
        assert!(e.contains("uisa, not jerlov"), "{e}");
    }

    #[test]
    fn a_reference_decides_seathrus_coefficients_unless_chosen() {
        let coefficients = |spec: MethodSpec| match spec {
            MethodSpec::Seathru(p) => p.coefficients,
            other => panic!("{other:?}"),
        };
        assert!(matches!(
            coefficients(MethodSpec::defaults(MethodKind::Seathru, true)),
            SeathruCoefficients::FromReference(_)
        ));
        assert!(matches!(
            coefficients(MethodSpec::defaults(MethodKind::Seathru, false)),
            SeathruCoefficients::Sampled(_)
        ));
        let given: Map<String, Value> =
            serde_json::from_str(r#"{"coefficients":{"mode":"given","beta_d":[0.4,0.1,0.1],"beta_b":[0.3,0.1,0.1],"b_inf":[0.1,0.4,0.5]}}"#).unwrap();
        let spec = MethodSpec::from_keywords(MethodKind::Seathru, &given, true).unwrap();
        assert!(matches!(
            coefficients(spec.clone()),
            SeathruCoefficients::Given(_)
        ));
        assert_eq!(spec.reference_use(), ReferenceUse::Ignored);
        assert_eq!(
            MethodSpec::defaults(MethodKind::Seathru, true).reference_use(),
            ReferenceUse::Required
        );
    }

    #[test]
    fn keywords_set_fields_and_unknown_ones_are_refused() {
        let kw: Map<String, Value> =
            serde_json::from_str(r#"{"precision":"bf16","tile":512}"#).unwrap();
        let MethodSpec::Uwnr(s) = MethodSpec::from_keywords(MethodKind::Uwnr, &kw, true).unwrap()
        else {
            panic!()
        };
        assert_eq!(
            (s.precision, s.tile, s.overlap),
            (Precision::Bf16, 512, 192)
        );
        let bad: Map<String, Value> = serde_json::from_str(r#"{"water_typ":"3C"}"#).unwrap();
        let e = MethodSpec::from_keywords(MethodKind::Jerlov, &bad, false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("\"water_typ\"") && e.contains("water_type"),
            "{e}"
        );
        let wrong: Map<String, Value> = serde_json::from_str(r#"{"water_type":"12Z"}"#).unwrap();
        let e = MethodSpec::from_keywords(MethodKind::Jerlov, &wrong, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("12Z"), "{e}");
        let e = MethodSpec::from_keywords(MethodKind::Uwgan, &kw, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not apply to method uwgan"), "{e}");
    }

    #[test]
    fn bad_tiling_is_refused() {
        let spec = MethodSpec::Uwnr(UwnrSpec {
            tile: 100,
            ..UwnrSpec::default()
        });
        assert!(spec.validate().is_err());
        assert!(
            MethodSpec::defaults(MethodKind::Uwnr, true)
                .validate()
                .is_ok()
        );
    }
}
