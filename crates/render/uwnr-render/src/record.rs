//! What a render method records: the settings a dataset compares on every resume, and what each
//! pair records of its depth response.

use serde::Serialize;
use serde_json::json;
use uwnr_model::{DepthResponse, DepthScale, GeneratorConfig, WaterEffects};

use crate::method::Precision;

/// What the settings record of the network.
#[derive(Serialize)]
pub(crate) struct NetworkRecord<'a> {
    pub weights: &'a str,
    pub fingerprint: &'a str,
    pub config: &'a GeneratorConfig,
    /// `bf16` for bf16 products, whose renders differ from f32's by up to one level; absent for
    /// f32 (so datasets made before this field resume unchanged).
    #[serde(skip_serializing_if = "is_f32")]
    pub precision: Precision,
    /// The stages after the water; absent when none runs.
    #[serde(skip_serializing_if = "WaterEffects::is_none")]
    pub effects: &'a WaterEffects,
}

fn is_f32(p: &Precision) -> bool {
    *p == Precision::F32
}

/// What the settings record of the GAN baseline.
#[derive(Serialize)]
pub(crate) struct GanRecord<'a> {
    pub weights: &'a str,
    pub fingerprint: &'a str,
    pub config: &'a uwnr_gan::GeneratorConfig,
}

/// The fingerprint of weight bytes recorded with a dataset, so a resumed run cannot switch
/// models silently.
#[must_use]
pub fn fingerprint(bytes: &[u8]) -> String {
    format!("fnv1a64:{:016x}", fnv1a64(bytes))
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
        DepthScale::Relative { scene_m } => {
            json!({ "scale": "relative", "scene_m": round(scene_m), "trust": trust })
        }
        DepthScale::Metric { max_m } => {
            json!({ "scale": "metric", "max_m": round(max_m), "trust": trust })
        }
        DepthScale::Absolute => json!({ "scale": "absolute", "trust": trust }),
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
