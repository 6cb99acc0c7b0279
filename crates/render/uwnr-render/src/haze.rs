//! Plain haze, `I = J·t + B·(1 − t)` with `t_c = exp(−β_c · d · s)`: the single-scattering
//! model with a veil `B` and attenuation `β` the user gives and no randomness, a control beside
//! the methods that imitate a real water (Koschmieder's law, as in Schechner & Karpel 2005).
//!
//! `d` is uwnr's relative depth in [0, 1] (larger = farther) and `s` the metres it spans, so a
//! pixel at depth `d` sits `d·s` metres away.

use crate::record::{HazeRecord, MethodRecord, PhysicalRecord};
use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::error::{RenderError, Result};

/// Attenuation per metre of Jerlov's coastal type 3C in RGB, `−ln N_c` of UWCNN's table
/// (`uwnr_baselines::JERLOV_TYPES`), rounded.
pub const DEFAULT_BETA_PER_M: [f64; 3] = [0.34, 0.2, 0.22];
/// Type 3C's UWCNN background at 4 m, `1.5·N_c^4`, rounded: a green-blue veil.
pub const DEFAULT_VEIL: [f64; 3] = [0.38, 0.68, 0.61];
/// Metres that depth 1 stands for.
pub const DEFAULT_DEPTH_SCALE_M: f64 = 5.0;
/// Largest accepted attenuation per metre (the murkiest Jerlov type is below 1.3).
const MAX_BETA_PER_M: f64 = 10.0;

/// The veil, attenuation and distance of the haze.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HazeParams {
    /// Veiling light `B`, RGB in [0, 1].
    pub veil: [f64; 3],
    /// Attenuation `β` per metre, RGB, in [0, 10].
    pub beta: [f64; 3],
    /// Metres that depth 1 stands for (> 0).
    pub depth_scale_m: f64,
}

impl Default for HazeParams {
    fn default() -> Self {
        Self {
            veil: DEFAULT_VEIL,
            beta: DEFAULT_BETA_PER_M,
            depth_scale_m: DEFAULT_DEPTH_SCALE_M,
        }
    }
}

impl HazeParams {
    /// Checks the ranges above.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f64, range: &str| {
            Err(RenderError::Invalid(format!(
                "haze {what} {v} is outside {range}"
            )))
        };
        for v in self.veil {
            if !(0.0..=1.0).contains(&v) {
                return bad("veil", v, "[0, 1]");
            }
        }
        for b in self.beta {
            if !(0.0..=MAX_BETA_PER_M).contains(&b) {
                return bad("beta", b, "[0, 10] per metre");
            }
        }
        if !(self.depth_scale_m.is_finite() && self.depth_scale_m > 0.0) {
            return bad("depth_scale_m", self.depth_scale_m, "(0, inf) metres");
        }
        Ok(())
    }
}

/// Renders `clean` (RGB) hazed over `depth` (1 channel, its size); returns the image and the
/// parameters to record.
pub fn render(params: &HazeParams, clean: &Image, depth: &Image) -> Result<(Image, MethodRecord)> {
    params.validate()?;
    if clean.channels() != 3 || depth.channels() != 1 || depth.size() != clean.size() {
        return Err(RenderError::Invalid(format!(
            "haze needs an RGB image and a 1-channel depth of its size, got {}x{}x{} and {}x{}x{}",
            clean.width(),
            clean.height(),
            clean.channels(),
            depth.width(),
            depth.height(),
            depth.channels()
        )));
    }
    let (w, h) = clean.size();
    let d = depth.plane(0);
    if let Some(v) = d.iter().find(|v| !v.is_finite()) {
        return Err(RenderError::Invalid(format!("depth holds {v}")));
    }
    let mut out = Image::filled(w, h, 3, 0.0);
    for c in 0..3 {
        let (b, beta) = (params.veil[c] as f32, params.beta[c] as f32);
        let k = beta * params.depth_scale_m as f32;
        for ((o, &j), &z) in out.plane_mut(c).iter_mut().zip(clean.plane(c)).zip(d) {
            let t = (-k * z.clamp(0.0, 1.0)).exp();
            *o = (j * t + b * (1.0 - t)).clamp(0.0, 1.0);
        }
    }
    let record = MethodRecord::Physical(PhysicalRecord::Haze(HazeRecord {
        veil: params.veil,
        beta: params.beta,
        depth_scale_m: params.depth_scale_m,
    }));
    Ok((out, record))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_camera_sees_the_scene_and_far_away_sees_the_veil() {
        let clean = Image::filled(4, 2, 3, 0.5);
        let p = HazeParams::default();
        let (near, record) = render(&p, &clean, &Image::filled(4, 2, 1, 0.0)).unwrap();
        assert!(near.data().iter().all(|&v| (v - 0.5).abs() < 1e-6));
        assert_eq!(record.to_value()["method"], "haze");
        // At depth 1 (5 m), red keeps exp(-0.34 * 5) = 0.1827 of the scene.
        let (far, _) = render(&p, &clean, &Image::filled(4, 2, 1, 1.0)).unwrap();
        let t = (-0.34f32 * 5.0).exp();
        assert!((far.plane(0)[0] - (0.5 * t + 0.38 * (1.0 - t))).abs() < 1e-6);
        let murky = HazeParams {
            beta: [10.0; 3],
            depth_scale_m: 100.0,
            ..p
        };
        let (veiled, _) = render(&murky, &clean, &Image::filled(4, 2, 1, 1.0)).unwrap();
        for (c, b) in DEFAULT_VEIL.iter().enumerate() {
            assert!((veiled.plane(c)[0] - *b as f32).abs() < 1e-6);
        }
    }

    #[test]
    fn out_of_range_settings_and_mismatched_depth_are_refused() {
        let clean = Image::filled(4, 2, 3, 0.5);
        let depth = Image::filled(4, 2, 1, 0.5);
        for bad in [
            HazeParams {
                veil: [1.5, 0.0, 0.0],
                ..HazeParams::default()
            },
            HazeParams {
                beta: [-1.0, 0.0, 0.0],
                ..HazeParams::default()
            },
            HazeParams {
                depth_scale_m: 0.0,
                ..HazeParams::default()
            },
        ] {
            assert!(render(&bad, &clean, &depth).is_err(), "{bad:?}");
        }
        let small = Image::filled(2, 2, 1, 0.5);
        assert!(render(&HazeParams::default(), &clean, &small).is_err());
    }
}
