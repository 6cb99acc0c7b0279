//! What a baseline records of a render ([`Rendered::params`](crate::Rendered)): the parameters it
//! used, the drawn ones included, one typed record per method with a `"method"` tag, the same
//! JSON a dataset's manifest has always held for each pair (its keys written in sorted order, as a
//! `serde_json::Value` writes them).
//!
//! Numbers are rounded where the record is made (6 decimals), so that a manifest read and written
//! again is unchanged.

use serde::{Deserialize, Serialize};

use crate::{AttenuationRatio, BackgroundPick, ColourSpace, WaterType};

/// The parameters a baseline rendered with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum BaselineRecord {
    Jerlov(JerlovRecord),
    Uisa(UisaRecord),
    Seathru(SeathruRecord),
    Reinhard(ReinhardRecord),
}

impl BaselineRecord {
    /// The method's name, as its tag is written.
    #[must_use]
    pub fn method(&self) -> &'static str {
        match self {
            Self::Jerlov(_) => "jerlov",
            Self::Uisa(_) => "uisa",
            Self::Seathru(_) => "seathru",
            Self::Reinhard(_) => "reinhard",
        }
    }
}

/// [`crate::jerlov`]: the water type and distances drawn.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JerlovRecord {
    pub water_type: WaterType,
    /// The type's transmittance per metre `N_c`, RGB.
    pub transmittance_per_m_rgb: [f64; 3],
    pub depth_scale_m: f64,
    pub background_depth_m: f64,
    pub background_gain: f64,
    pub background_rgb: [f64; 3],
    pub illuminate_scene: bool,
    pub seed: u64,
}

/// [`crate::uisa`]: the water measured on the reference.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UisaRecord {
    pub background_rgb: [f64; 3],
    pub background_pick: BackgroundPick,
    /// The reference's size as measured (after fitting it within the working size).
    pub reference_size: [usize; 2],
    pub reference_median_transmission: f64,
    /// The clean image's typical relative depth.
    pub clean_typical_depth: f64,
    pub attenuation_ratio: AttenuationRatio,
    pub beta_over_beta_red_rgb: [f64; 3],
    pub beta_per_unit_depth_rgb: [f64; 3],
    pub window: usize,
    pub transmission_floor: f64,
}

/// [`crate::seathru`]: the coefficients and where they came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeathruRecord {
    pub coefficients: CoefficientsRecord,
    pub beta_d_per_m_rgb: [f64; 3],
    pub beta_b_per_m_rgb: [f64; 3],
    pub b_inf_rgb: [f64; 3],
    pub depth_scale_m: f64,
    pub seed: u64,
}

/// Where Sea-thru's coefficients came from, tagged by `"mode"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum CoefficientsRecord {
    /// Given by the user.
    Given,
    /// Drawn along the Jerlov manifold.
    Sampled(SampledRecord),
    /// Fitted to the reference's background.
    FromReference(FittedRecord),
}

/// Coefficients drawn along the Jerlov manifold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampledRecord {
    /// Position on the manifold (0 = type I, 9 = type 9C).
    pub jerlov_position: f64,
    pub nearest_water_type: WaterType,
    pub backscatter_ratio_rgb: [f64; 3],
    pub background_depth_m: f64,
    pub background_gain: f64,
}

/// Coefficients fitted to the reference's background light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FittedRecord {
    pub jerlov_position: f64,
    pub nearest_water_type: WaterType,
    pub fitted_background_depth_m: f64,
    /// How far the fitted water's hue is from the background's.
    pub hue_residual: f64,
    pub backscatter_ratio_rgb: [f64; 3],
    pub background_pick: BackgroundPick,
}

/// [`crate::reinhard`]: the reference's statistics the clean image was moved to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReinhardRecord {
    pub space: ColourSpace,
    pub match_std: bool,
    pub reference_mean: [f64; 3],
    pub reference_std: [f64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::JERLOV_TYPES;

    #[test]
    fn water_types_are_written_by_their_names() {
        for (t, (name, _)) in WaterType::ALL.iter().zip(JERLOV_TYPES) {
            assert_eq!(serde_json::to_value(t).unwrap(), *name);
            assert_eq!(t.name(), name);
        }
    }

    #[test]
    fn a_record_is_tagged_by_its_method_and_refuses_unknown_fields() {
        let r = BaselineRecord::Reinhard(ReinhardRecord {
            space: ColourSpace::Lab,
            match_std: true,
            reference_mean: [0.1, 0.2, 0.3],
            reference_std: [0.01, 0.02, 0.03],
        });
        let v = serde_json::to_value(&r).unwrap();
        assert_eq!(v["method"], "reinhard");
        assert_eq!(
            serde_json::from_value::<BaselineRecord>(v.clone()).unwrap(),
            r
        );
        let mut extra = v;
        extra["colour"] = "red".into();
        assert!(serde_json::from_value::<BaselineRecord>(extra).is_err());
        let given = serde_json::json!({"mode": "given"});
        assert_eq!(
            serde_json::from_value::<CoefficientsRecord>(given).unwrap(),
            CoefficientsRecord::Given
        );
    }
}
