//! uwnr-baselines: physically-based and statistical ways of rendering a clean in-air image into an
//! underwater image, the baselines UWNR is compared with.
//!
//! | method | module | needs a reference | random |
//! |---|---|---|---|
//! | UWCNN's Jerlov water types, `I = J·t + B·(1 − t)` | [`jerlov`] | no | water type, distances |
//! | UISA / SUID, water measured on a real image | [`uisa`] | yes | nothing |
//! | Akkaynak & Treibitz's revised model | [`seathru`] | only in `from_reference` mode | coefficients, distance |
//! | Reinhard et al. colour transfer | [`reinhard`] | yes | nothing |
//!
//! Depth convention (all of uwnr): a 1-channel [`Image`] in [0, 1] of the clean image's size,
//! larger = farther, relative (from any depth source). A metric range is `d·s` with a distance
//! scale `s` in metres, a parameter of each method that needs one.
//!
//! Every method is deterministic for a given seed: the same inputs, parameters and seed give the
//! same image on every machine. [`Rendered::params`] records the parameters actually used,
//! including the sampled ones, for a dataset manifest.
//!
//! ```
//! use uwnr_baselines::{Method, JerlovParams, RenderInput, render};
//! use uwnr_core::Image;
//!
//! let clean = Image::filled(32, 24, 3, 0.5);
//! let depth = Image::filled(32, 24, 1, 0.3);
//! let out = render(
//!     &Method::Jerlov(JerlovParams::default()),
//!     &RenderInput { clean: &clean, depth: &depth, reference: None },
//!     7,
//! )
//! .unwrap();
//! assert_eq!(out.image.size(), (32, 24));
//! assert_eq!(out.params.method(), "jerlov");
//! ```

pub mod background;
mod common;
pub mod error;
pub mod jerlov;
pub mod record;
pub mod reinhard;
pub mod seathru;
pub mod uisa;

use serde::{Deserialize, Serialize};
use uwnr_core::Image;

pub use background::{BackgroundPick, quadtree_background};
pub use common::Range;
pub use error::{BaselineError, Result};
pub use jerlov::{JERLOV_TYPES, JerlovParams, WaterType};
pub use record::BaselineRecord;
pub use reinhard::{ColourSpace, ReinhardParams};
pub use seathru::{
    GivenCoefficients, ReferenceCoefficients, SampledCoefficients, SeathruCoefficients,
    SeathruParams,
};
pub use uisa::{AttenuationRatio, UisaParams};

/// A baseline and its parameters. Serialised with a `"method"` tag, e.g.
/// `{"method": "jerlov", "water_type": "3C"}` (missing fields take their defaults).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum Method {
    /// UWCNN's Jerlov water-type synthesis ([`jerlov`]).
    Jerlov(JerlovParams),
    /// UISA-style synthesis from a reference underwater image ([`uisa`]).
    Uisa(UisaParams),
    /// Akkaynak & Treibitz's revised image formation model ([`seathru`]).
    Seathru(SeathruParams),
    /// Reinhard et al.'s colour transfer from a reference ([`reinhard`]).
    Reinhard(ReinhardParams),
}

impl Method {
    /// The method's name as it appears in the `"method"` tag.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Jerlov(_) => "jerlov",
            Self::Uisa(_) => "uisa",
            Self::Seathru(_) => "seathru",
            Self::Reinhard(_) => "reinhard",
        }
    }

    /// Whether [`render`] will fail without [`RenderInput::reference`].
    #[must_use]
    pub fn needs_reference(&self) -> bool {
        match self {
            Self::Jerlov(_) => false,
            Self::Uisa(_) | Self::Reinhard(_) => true,
            Self::Seathru(p) => matches!(p.coefficients, SeathruCoefficients::FromReference(_)),
        }
    }
}

/// What a baseline renders from.
#[derive(Clone, Copy, Debug)]
pub struct RenderInput<'a> {
    /// The clean in-air image, RGB in [0, 1].
    pub clean: &'a Image,
    /// Its relative depth, 1 channel in [0, 1], same size, larger = farther (values outside
    /// [0, 1] are clamped; NaN is an error). Unused by [`Method::Reinhard`].
    pub depth: &'a Image,
    /// A real underwater image whose water is imitated (any size), for the methods that need one.
    pub reference: Option<&'a Image>,
}

/// A rendered underwater image and the parameters that produced it.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// The underwater image, RGB in [0, 1], the clean image's size.
    pub image: Image,
    /// The parameters actually used, including the sampled ones, for the dataset manifest.
    pub params: BaselineRecord,
}

/// Renders `input` with `method`; `seed` fixes every random draw.
pub fn render(method: &Method, input: &RenderInput, seed: u64) -> Result<Rendered> {
    match method {
        Method::Jerlov(p) => jerlov::render(p, input, seed),
        Method::Uisa(p) => uisa::render(p, input),
        Method::Seathru(p) => seathru::render(p, input, seed),
        Method::Reinhard(p) => reinhard::render(p, input),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_json_uses_the_method_tag_and_defaults() {
        let m: Method = serde_json::from_str(r#"{"method":"jerlov","water_type":"3C"}"#).unwrap();
        match &m {
            Method::Jerlov(p) => {
                assert_eq!(p.water_type, Some(WaterType::C3));
                assert_eq!(p.background_gain, 1.5);
            }
            other => panic!("{other:?}"),
        }
        let s = serde_json::to_string(&Method::Reinhard(ReinhardParams::default())).unwrap();
        assert_eq!(
            s,
            r#"{"method":"reinhard","space":"lalphabeta","match_std":true}"#
        );
        let rgb: Method = serde_json::from_str(r#"{"method":"reinhard","space":"rgb"}"#).unwrap();
        assert_eq!(
            rgb,
            Method::Reinhard(ReinhardParams {
                space: ColourSpace::Rgb,
                match_std: true
            })
        );
        assert!(serde_json::from_str::<Method>(r#"{"method":"jerlow"}"#).is_err());
        assert!(!m.needs_reference());
        assert!(Method::Uisa(UisaParams::default()).needs_reference());
    }
}
