//! What a render records of itself ([`MethodRecord`], a pair's `params` in a dataset's
//! manifest), and the fingerprint of the weights a dataset records with its settings.

use serde::{Deserialize, Serialize, Serializer};
use uwnr_baselines::BaselineRecord;
use uwnr_baselines::record::{CoefficientsRecord, SeathruRecord};
use uwnr_model::water::Affine;
use uwnr_model::{DepthResponse, DepthScale};

/// The parameters one render used, drawn values included: one typed record per method.
///
/// On disk (a manifest's `params`) it is the JSON uwnr has always written: the baselines' records
/// carry a `"method"` tag, the networks' records are told apart by their fields (the manifest line
/// names the method too), and keys are written in sorted order, as a `serde_json::Value` writes
/// them, so that a folder merged or resumed stays byte for byte the same.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum MethodRecord {
    Uwnr(UwnrRecord),
    Uwgan(UwganRecord),
    Baseline(BaselineRecord),
    Physical(PhysicalRecord),
    /// A record of a shape this version does not write (a folder made by an earlier version),
    /// kept as read so that it writes out unchanged.
    Earlier(serde_json::Value),
}

impl Serialize for MethodRecord {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let value = match self {
            Self::Uwnr(r) => serde_json::to_value(r),
            Self::Uwgan(r) => serde_json::to_value(r),
            Self::Baseline(r) => serde_json::to_value(r),
            Self::Physical(r) => serde_json::to_value(r),
            // Already a value (its keys sorted as read): written as it is, not copied.
            Self::Earlier(v) => return v.serialize(serializer),
        };
        value
            .map_err(|e| serde::ser::Error::custom(e.to_string()))?
            .serialize(serializer)
    }
}

impl MethodRecord {
    /// The record as JSON (what a manifest line holds).
    #[must_use]
    pub fn to_value(&self) -> serde_json::Value {
        // Every record is strings, numbers and arrays of them: it always converts.
        serde_json::to_value(self).unwrap_or_default()
    }
}

impl From<BaselineRecord> for MethodRecord {
    fn from(r: BaselineRecord) -> Self {
        Self::Baseline(r)
    }
}

/// A render by the UWNR model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UwnrRecord {
    /// Where the model came from (a path, or the bundled model's name).
    pub weights: String,
    /// The depth response the render used.
    pub depth: DepthRecord,
    /// The reference's water on the clean image's colours (absent for the paper's variant,
    /// which renders the reference's light field alone).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub water: Option<Affine>,
    /// The pair's drawn strength and the renders it took, when a dataset calibrates it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strength: Option<StrengthRecord>,
}

/// A pair's strength as a dataset calibrated it: the target item drawn, its PSNR(underwater,
/// clean) in dB, the water's scale that reached it and how many renders that took.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StrengthRecord {
    pub target: String,
    pub target_db: f32,
    pub scale: f32,
    pub renders: usize,
}

/// A render by the UWGAN-style generator: the code's seed and the water it drew.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UwganRecord {
    pub weights: String,
    pub z_seed: u64,
    pub beta: [f32; 3],
    pub backlight: [f32; 3],
    pub vignette: [f32; 3],
    pub gain: f32,
}

/// The methods of this crate with a `"method"` tag: the haze control and the revised model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case")]
pub enum PhysicalRecord {
    Haze(HazeRecord),
    Revised(RevisedRecord),
}

/// The haze control's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HazeRecord {
    pub veil: [f64; 3],
    pub beta: [f64; 3],
    pub depth_scale_m: f64,
}

/// The revised model: Sea-thru's record with the strengths of its two stages after it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RevisedRecord {
    pub coefficients: CoefficientsRecord,
    pub beta_d_per_m_rgb: [f64; 3],
    pub beta_b_per_m_rgb: [f64; 3],
    pub b_inf_rgb: [f64; 3],
    pub depth_scale_m: f64,
    pub seed: u64,
    pub forward_scatter: f64,
    pub medium: f64,
}

impl RevisedRecord {
    /// Sea-thru's record with the stages' strengths.
    #[must_use]
    pub fn new(seathru: SeathruRecord, forward_scatter: f64, medium: f64) -> Self {
        let SeathruRecord {
            coefficients,
            beta_d_per_m_rgb,
            beta_b_per_m_rgb,
            b_inf_rgb,
            depth_scale_m,
            seed,
        } = seathru;
        Self {
            coefficients,
            beta_d_per_m_rgb,
            beta_b_per_m_rgb,
            b_inf_rgb,
            depth_scale_m,
            seed,
            forward_scatter,
            medium,
        }
    }
}

/// What a pair records of its depth response, tagged by `"scale"`; numbers rounded to 4
/// decimals (an f32 widened to f64 prints 17 digits, which a JSON reader need not return exactly).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scale", rename_all = "snake_case", deny_unknown_fields)]
pub enum DepthRecord {
    /// Relative depth, `scene_m` metres at depth 1.
    Relative { scene_m: f64, trust: f64 },
    /// Metric depth up to `max_m` metres.
    Metric { max_m: f64, trust: f64 },
    /// Depth in metres as given.
    Absolute { trust: f64 },
}

/// The fingerprint of weight bytes recorded with a dataset, so a resumed run cannot switch
/// models silently.
#[must_use]
pub fn fingerprint(bytes: &[u8]) -> String {
    format!("fnv1a64:{:016x}", fnv1a64(bytes))
}

/// What a pair records of its depth response ([`DepthRecord`]).
#[must_use]
pub fn depth_record(response: &DepthResponse) -> DepthRecord {
    let round = |v: f32| (f64::from(v) * 1e4).round() / 1e4;
    let trust = round(response.trust);
    match response.scale {
        DepthScale::Relative { scene_m } => DepthRecord::Relative {
            scene_m: round(scene_m),
            trust,
        },
        DepthScale::Metric { max_m } => DepthRecord::Metric {
            max_m: round(max_m),
            trust,
        },
        DepthScale::Absolute => DepthRecord::Absolute { trust },
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
}
