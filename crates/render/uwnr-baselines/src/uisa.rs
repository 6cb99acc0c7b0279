//! Reference-based physical synthesis in the manner of UISA, the underwater image synthesis
//! algorithm of Hou et al. 2020 (SUID, "Benchmarking underwater image enhancement and
//! restoration, and beyond", IEEE Access 8): the water of a real underwater image (the
//! reference) is measured and re-applied to a clean image with `I_c = J_c·t_c + B_c·(1 − t_c)`.
//!
//! 1. **Background light** `B` of the reference by quadtree search ([`crate::background`]).
//! 2. **Red transmission of the reference** by the red channel prior (Galdran et al. 2015,
//!    "Automatic red-channel underwater image restoration", JVCIR 26):
//!    `t_ref(x) = 1 − min_{y∈Ω(x)} min((1 − I_R)/(1 − B_R), I_G/B_G, I_B/B_B)`, clamped to
//!    `[t_0, 1]` with He et al.'s `t_0 = 0.1`, over a 15×15 window `Ω`. Its median `t̃` is the
//!    statistic carried over.
//! 3. **Red transmission of the clean image** from its depth `d`: `t_R(x) = exp(−β_R·d(x))` with
//!    `β_R` chosen so that the clean image's median transmission equals the reference's. As
//!    `exp(−β·d)` is decreasing in `d`, its median is `exp(−β·median(d))`, so
//!    `β_R = −ln(t̃) / median(d)` and `t_R(x) = t̃^(d(x) / median(d))`: the reference fixes how
//!    much water lies in front of the typical pixel, the depth map fixes how it varies across
//!    the image. The metric scale of the depth cancels out, so none is needed (the manifest
//!    reports `β_R` per unit of relative depth; divide by the depth scale for m⁻¹). When the
//!    median depth is 0 the mean depth is used; when that is 0 too, `t = 1`.
//! 4. **Green and blue** from red by the scattering relation `b(λ) = −0.00113·λ + 1.62517`
//!    (Gould, Arnone, Martinolich 1999, Applied Optics 38) at 620, 540, 450 nm:
//!    `t_c = t_R^(β_c/β_R)` with, by default, `β_c/β_R = (b(λ_c)·B_R) / (b(λ_R)·B_c)` — the
//!    relation as Zhao et al. 2015 derive it from `B_c ∝ b_c/β_c` and as Li et al. 2016 (TIP
//!    25(12)) and the public SUID re-implementation `vismiroglou/SUID_data_generation` use it —
//!    or the background-free `β_c/β_R = b(λ_c)/b(λ_R)` ([`AttenuationRatio`]).
//!
//! The reference is downscaled (never upscaled) to at most 512 px on its longer side first, so
//! the 15-pixel window spans a similar part of the scene whatever the reference's resolution.
//! Nothing is random: the seed is unused.

use crate::record::{BaselineRecord, UisaRecord};
use serde::{Deserialize, Serialize};
use uwnr_core::Image;
use uwnr_core::dark_channel::dark_channel;
use uwnr_core::resize::fit_within;

use crate::background::{BackgroundPick, SUID_MIN_REGION_FRACTION, quadtree_background};
use crate::common::{check_image, check_in, checked_depth, form_image, median, round6, round6_3};
use crate::error::{BaselineError, Result};
use crate::{RenderInput, Rendered};

/// Wavelengths (nm) taken for the R, G, B channels (Li et al. 2016, Zhao et al. 2015).
pub const CHANNEL_WAVELENGTHS_NM: [f64; 3] = [620.0, 540.0, 450.0];
/// Slope of Gould et al.'s scattering relation `b(λ) = m·λ + i` (per nm).
pub const SCATTERING_SLOPE: f64 = -0.00113;
/// Intercept of Gould et al.'s scattering relation.
pub const SCATTERING_INTERCEPT: f64 = 1.62517;
/// He et al. 2009's lower bound `t_0` on the transmission of the reference.
pub const TRANSMISSION_FLOOR: f64 = 0.1;
/// Side of the square minimum-filter window of the red channel prior (He et al. 2009's 15×15).
pub const PRIOR_WINDOW: usize = 15;
/// Longest side the reference is downscaled to before it is analysed.
pub const REFERENCE_MAX_SIDE: usize = 512;
/// Smallest background-light component (and largest is 1 minus it): keeps the prior's
/// normalisations `I_c/B_c`, `(1 − I_R)/(1 − B_R)` and the ratio `B_R/B_c` finite.
const BACKGROUND_MARGIN: f64 = 1e-3;

/// How the green and blue attenuation follow from the red one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttenuationRatio {
    /// `β_c/β_R = b(λ_c)/b(λ_R)`: scattering only. Blue then always attenuates more than red
    /// (1.21×), the opposite of what light does in sea water.
    Wavelength,
    /// `β_c/β_R = (b(λ_c)·B_R)/(b(λ_R)·B_c)` (default): the background light's colour sets the
    /// balance, so a blue reference attenuates red the most.
    #[default]
    WavelengthAndBackground,
}

/// Parameters of the UISA-style synthesis. `Default` is the setting described in the module docs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct UisaParams {
    /// How the background light is read off the quadtree's final region.
    pub background_pick: BackgroundPick,
    /// Quadtree stopping size as a fraction of the reference's pixels (SUID: 0.01).
    pub min_region_fraction: f64,
    /// Side of the red-channel-prior window in pixels of the (downscaled) reference.
    pub window: usize,
    /// Lower bound on the reference's transmission.
    pub transmission_floor: f64,
    /// Green/blue attenuation relative to red.
    pub attenuation_ratio: AttenuationRatio,
    /// Longest side of the reference after downscaling.
    pub reference_max_side: usize,
}

impl Default for UisaParams {
    fn default() -> Self {
        Self {
            background_pick: BackgroundPick::Mean,
            min_region_fraction: SUID_MIN_REGION_FRACTION,
            window: PRIOR_WINDOW,
            transmission_floor: TRANSMISSION_FLOOR,
            attenuation_ratio: AttenuationRatio::WavelengthAndBackground,
            reference_max_side: REFERENCE_MAX_SIDE,
        }
    }
}

impl UisaParams {
    /// Checks the numeric parameters.
    pub fn validate(&self) -> Result<()> {
        check_in(
            "uisa.min_region_fraction",
            self.min_region_fraction,
            f64::MIN_POSITIVE,
            1.0,
            "must be in (0, 1]",
        )?;
        check_in(
            "uisa.transmission_floor",
            self.transmission_floor,
            f64::MIN_POSITIVE,
            1.0,
            "must be in (0, 1]",
        )?;
        if self.window == 0 {
            return Err(BaselineError::InvalidParam {
                name: "uisa.window",
                value: "0".into(),
                reason: "must be at least 1",
            });
        }
        if self.reference_max_side < 2 {
            return Err(BaselineError::InvalidParam {
                name: "uisa.reference_max_side",
                value: self.reference_max_side.to_string(),
                reason: "must be at least 2",
            });
        }
        Ok(())
    }
}

/// Gould et al.'s scattering coefficient relation `b(λ) = −0.00113·λ + 1.62517` (λ in nm).
#[must_use]
pub fn scattering(lambda_nm: f64) -> f64 {
    SCATTERING_SLOPE * lambda_nm + SCATTERING_INTERCEPT
}

/// `β_c/β_R` for c = R, G, B under `ratio`, given the background light `b_light` (RGB).
#[must_use]
pub fn attenuation_ratios(ratio: AttenuationRatio, b_light: [f64; 3]) -> [f64; 3] {
    let b = CHANNEL_WAVELENGTHS_NM.map(scattering);
    std::array::from_fn(|c| match ratio {
        AttenuationRatio::Wavelength => b[c] / b[0],
        AttenuationRatio::WavelengthAndBackground => (b[c] * b_light[0]) / (b[0] * b_light[c]),
    })
}

/// The reference's red-channel-prior transmission `t_ref` (1 channel), clamped to `[floor, 1]`.
pub fn red_channel_transmission(
    reference: &Image,
    background: [f64; 3],
    window: usize,
    floor: f64,
) -> Result<Image> {
    check_image(reference, "reference", 3)?;
    let (w, h) = reference.size();
    let n = w * h;
    let mut norm = vec![0.0f32; 3 * n];
    let scale = [
        1.0 / (1.0 - background[0]) as f32,
        1.0 / background[1] as f32,
        1.0 / background[2] as f32,
    ];
    for (c, out) in norm.chunks_exact_mut(n).enumerate() {
        for (o, &v) in out.iter_mut().zip(reference.plane(c)) {
            let v = if c == 0 { 1.0 - v } else { v };
            *o = v * scale[c];
        }
    }
    let norm = Image::from_planar(w, h, 3, norm)?;
    let mut t = dark_channel(&norm, &[0, 1, 2], window)?;
    let floor = floor as f32;
    for v in t.data_mut() {
        *v = (1.0 - *v).clamp(floor, 1.0);
    }
    Ok(t)
}

/// Renders `input.clean` with the water measured on `input.reference` (required).
pub(crate) fn render(params: &UisaParams, input: &RenderInput) -> Result<Rendered> {
    params.validate()?;
    let depth = checked_depth(input.clean, input.depth)?;
    let reference = input
        .reference
        .ok_or(BaselineError::MissingReference { method: "uisa" })?;
    check_image(reference, "reference", 3)?;
    let work = fit_within(reference, params.reference_max_side)?;

    let background =
        quadtree_background(&work, params.min_region_fraction, params.background_pick)?
            .map(|v| v.clamp(BACKGROUND_MARGIN, 1.0 - BACKGROUND_MARGIN));
    let t_ref =
        red_channel_transmission(&work, background, params.window, params.transmission_floor)?;
    let t_median = f64::from(median(t_ref.data()).unwrap_or(1.0));

    let depth_median = f64::from(median(&depth).unwrap_or(0.0));
    let depth_typical = if depth_median > 0.0 {
        depth_median
    } else {
        depth.iter().map(|&v| f64::from(v)).sum::<f64>() / depth.len() as f64
    };
    // β_R per unit of relative depth; 0 when the scene has no depth at all (then t = 1).
    let beta_red = if depth_typical > 0.0 {
        -t_median.ln() / depth_typical
    } else {
        0.0
    };
    let ratios = attenuation_ratios(params.attenuation_ratio, background);
    let att = ratios.map(|r| r * beta_red);
    let image = form_image(input.clean, &depth, [1.0; 3], att, att, background)?;

    let params = BaselineRecord::Uisa(UisaRecord {
        background_rgb: round6_3(background),
        background_pick: params.background_pick,
        reference_size: [work.width(), work.height()],
        reference_median_transmission: round6(t_median),
        clean_typical_depth: round6(depth_typical),
        attenuation_ratio: params.attenuation_ratio,
        beta_over_beta_red_rgb: round6_3(ratios),
        beta_per_unit_depth_rgb: round6_3(att),
        window: params.window,
        transmission_floor: params.transmission_floor,
    });
    Ok(Rendered { image, params })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scattering_relation_at_the_three_wavelengths() {
        assert!((scattering(620.0) - 0.92457).abs() < 1e-9);
        assert!((scattering(540.0) - 1.01497).abs() < 1e-9);
        assert!((scattering(450.0) - 1.11667).abs() < 1e-9);
        let r = attenuation_ratios(AttenuationRatio::Wavelength, [0.5; 3]);
        assert!((r[0] - 1.0).abs() < 1e-12);
        assert!((r[2] - 1.11667 / 0.92457).abs() < 1e-9);
        // A blue background (B_R small) makes blue attenuate less than red.
        let r = attenuation_ratios(AttenuationRatio::WavelengthAndBackground, [0.1, 0.5, 0.8]);
        assert!(r[2] < 1.0 && r[1] < 1.0, "{r:?}");
        assert!((r[2] - 1.11667 * 0.1 / (0.92457 * 0.8)).abs() < 1e-9);
    }

    #[test]
    fn red_channel_prior_by_hand() {
        // Uniform reference equal to the background light: every normalised channel is 1, t = 0
        // -> clamped to the floor. Half the background: G/B_G = 0.5 is the minimum, t = 0.5.
        let b = [0.2, 0.6, 0.8];
        let flat = |k: f32| {
            let data: Vec<f32> = (0..3).flat_map(|c| vec![b[c] as f32 * k; 16]).collect();
            Image::from_planar(4, 4, 3, data).unwrap()
        };
        let t = red_channel_transmission(&flat(1.0), b, 3, 0.1).unwrap();
        assert!(
            t.data().iter().all(|&v| (v - 0.1).abs() < 1e-6),
            "{:?}",
            t.data()
        );
        let t = red_channel_transmission(&flat(0.5), b, 3, 0.1).unwrap();
        // (1 − 0.1)/(1 − 0.2) = 1.125 for red, 0.5 for green and blue: t = 1 − 0.5.
        assert!(
            t.data().iter().all(|&v| (v - 0.5).abs() < 1e-6),
            "{:?}",
            t.data()
        );
    }
}
