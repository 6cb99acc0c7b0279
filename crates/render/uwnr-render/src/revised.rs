//! `revised`: the revised image formation model (Sea-thru's, `uwnr_baselines`'s `seathru`) with
//! forward scattering and an inhomogeneous medium, physics alone beside uwnr's model: the
//! Sea-thru render, then the forward scattering of Ismiroglou et al. ("Sea-ing Through Scattered
//! Rays", the revised model with forward scattering: a point spread that widens with distance)
//! and a medium that varies smoothly over the frame, moving pixels towards or away from the
//! water's veil `B^inf` (`uwnr_model::effects`, the same stages uwnr's model has, with Sea-thru's
//! `B^inf` as the veil). Every draw comes from the render's seed, and a pair records Sea-thru's
//! parameters with the two strengths.

use serde::{Deserialize, Serialize};
use uwnr_baselines::BaselineRecord;
use uwnr_baselines::{Method, RenderInput, SeathruParams};
use uwnr_core::error::Cause;
use uwnr_model::WaterEffects;

use crate::error::{RenderError, Result};
use crate::record::{MethodRecord, PhysicalRecord, RevisedRecord};

/// The revised model's settings: Sea-thru's, and the two stages' strengths.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RevisedParams {
    /// The Sea-thru model under it (coefficients from the reference when one is given).
    pub seathru: SeathruParams,
    /// Share of the direct light scattered forward at the farthest point (0 to 1).
    pub forward_scatter: f32,
    /// Standard deviation of the medium's field over the frame (0 to 1).
    pub medium: f32,
}

impl Default for RevisedParams {
    /// Sea-thru's defaults, forward scattering 0.3 and a medium of 0.1 (the strengths measured
    /// on uwnr's model in `docs/RESULTS.md`).
    fn default() -> Self {
        Self {
            seathru: SeathruParams::default(),
            forward_scatter: 0.3,
            medium: 0.1,
        }
    }
}

impl RevisedParams {
    /// The two stages as `uwnr_model::WaterEffects`.
    fn effects(&self) -> WaterEffects {
        WaterEffects {
            forward_scatter: self.forward_scatter,
            medium: self.medium,
            ..WaterEffects::NONE
        }
    }

    /// Checks Sea-thru's settings and the two strengths.
    pub fn validate(&self) -> Result<()> {
        self.seathru
            .validate()
            .map_err(|e| RenderError::Invalid(format!("revised: {e}")))?;
        self.effects()
            .validate()
            .map_err(|e| RenderError::Invalid(format!("revised: {e}")))
    }

    /// Sea-thru's method under it.
    #[must_use]
    pub fn baseline(&self) -> Method {
        Method::Seathru(self.seathru.clone())
    }
}

/// Renders `input` with the revised model; returns the image and the parameters to record.
pub fn render(
    params: &RevisedParams,
    input: &RenderInput<'_>,
    seed: u64,
) -> Result<(uwnr_core::Image, MethodRecord)> {
    params.validate()?;
    let failed = |e: Cause| RenderError::Failed {
        context: "rendering with revised".into(),
        source: e,
    };
    let rendered =
        uwnr_baselines::render(&params.baseline(), input, seed).map_err(|e| failed(e.into()))?;
    let BaselineRecord::Seathru(seathru) = rendered.params else {
        return Err(failed("Sea-thru's render recorded another method".into()));
    };
    let veil = seathru.b_inf_rgb.map(|v| v as f32);
    let mut image = rendered.image;
    params
        .effects()
        .apply(&mut image, input.depth, veil, seed)
        .map_err(|e| failed(e.into()))?;
    let recorded = RevisedRecord::new(
        seathru,
        f64::from(params.forward_scatter),
        f64::from(params.medium),
    );
    Ok((
        image,
        MethodRecord::Physical(PhysicalRecord::Revised(recorded)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use uwnr_core::Image;

    #[test]
    fn revised_is_seathru_with_its_stages_and_records_them() {
        let mut clean = Image::filled(64, 48, 3, 0.0);
        for (i, v) in clean.data_mut().iter_mut().enumerate() {
            *v = ((i * 37) % 101) as f32 / 100.0;
        }
        let mut depth = Image::filled(64, 48, 1, 0.0);
        for (i, v) in depth.plane_mut(0).iter_mut().enumerate() {
            *v = (i % 64) as f32 / 63.0;
        }
        let mut params = RevisedParams::default();
        params.seathru.coefficients =
            uwnr_baselines::SeathruCoefficients::Sampled(Default::default());
        let input = RenderInput {
            clean: &clean,
            depth: &depth,
            reference: None,
        };
        let (image, recorded) = render(&params, &input, 5).unwrap();
        let seathru = uwnr_baselines::render(&params.baseline(), &input, 5).unwrap();
        assert_ne!(image, seathru.image);
        let MethodRecord::Physical(PhysicalRecord::Revised(r)) = &recorded else {
            panic!("{recorded:?}")
        };
        let BaselineRecord::Seathru(s) = &seathru.params else {
            panic!()
        };
        assert_eq!(r.b_inf_rgb, s.b_inf_rgb);
        assert!((r.medium - 0.1).abs() < 1e-6);
        let line = recorded.to_value();
        assert_eq!(line["method"], "revised");
        // A manifest reads it back as the same typed record.
        assert_eq!(
            serde_json::from_value::<MethodRecord>(line).unwrap(),
            recorded
        );
        assert_eq!(render(&params, &input, 5).unwrap().0, image);
        let off = RevisedParams {
            forward_scatter: 0.0,
            medium: 0.0,
            ..params.clone()
        };
        assert_eq!(render(&off, &input, 5).unwrap().0, seathru.image);
        let bad = RevisedParams {
            medium: 2.0,
            ..params
        };
        assert!(render(&bad, &input, 5).is_err());
    }
}
