//! What a network takes from its reference, and the `anchored` variant's physical output stage.
//!
//! The paper's generator (variant [`Variant::Paper`]) reads the reference only through its
//! light-field map and outputs the underwater image directly. Trained here, that network learnt
//! a tint: it scored below a Reinhard colour transfer on unseen pairs and ignored depth
//! (`MODEL_CARD.md`; the calibration runs in the training notes show why). The `anchored`
//! variant keeps the same network body but changes what goes in and what comes out:
//!
//! ```text
//! T      = Reinhard transfer of the clean image to the reference's lαβ statistics
//! A      = T · 10^((LF_ref - LF_T) · R) per channel, clamped to RETENTION_GAIN      (anchor)
//!          light-field retention: T takes the reference's coarse light (absolute maps)
//! A      = blur(A) + k (A - blur(A)) per channel, k = D_ref / D_A, clamped to DETAIL_GAIN,
//!          then rescaled to A's overall std: detail retention (config `detail_retention`),
//!          D = mean local std / overall std
//! x      = concat[clean, light field, A]                                 9 input planes
//! g, o   = G(x)                                   6 output planes, tanh, zero at initialisation
//! g', o' = Gaussian blur of g and o, sigma SMOOTH_SIGMA px    (a smooth local correction)
//! N      = A (1 + g') + o'                       the reference's look at the reference's depth
//! z      = s · d, the depth in metres: s = the metres 1 stands for (DepthScale)
//! z̄      = mean of z over the image; z_ref = the reference's distance: REFERENCE_DISTANCE_M
//!          for metric and absolute maps, z̄ itself for a relative map
//! out    = B + (N - B) · min(exp(-beta_m (k (z - z̄) + (z̄ - z_ref))), MAX_GAIN)
//!          per channel, beta_m per metre, k = the trust in the map's differences
//!          (DepthResponse: 1 for a map or model the user gives, PRIOR_TRUST for the prior)
//! ```
//!
//! - Light-field retention is the paper's idea (keep the reference's light field) done
//!   explicitly: the absolute map is the mean of three blurred log10 channels, so the factor is
//!   the ratio of the reference's and the transfer's blurred light. Untrained, it lifts the
//!   transfer from 29.45 to 30.40 dB on `uieb-val` and from 29.75 to 30.62 dB on `lsui-test`
//!   (self-reconstruction, `examples/depth_strength.rs`).
//! - Detail retention (models whose config has `detail_retention`) gives each channel of the
//!   anchor the reference's share of fine detail: `D_c`, the mean standard deviation over
//!   SSIM's 7x7 windows divided by the channel's overall standard deviation, measured on the
//!   reference and on the anchor at their own resolutions. The colour transfer matches each
//!   lαβ channel's overall spread, but water (and the camera behind it) changes fine and coarse
//!   contrast differently per channel: a red channel the water darkens keeps its noise and
//!   grain while losing its large-scale contrast (`D` above the clean image's), forward
//!   scattering softens detail (`D` below). The detail is what `DETAIL_SIGMA` separates from
//!   the coarse image. A ratio of shares, not of spreads, so a reference of another scene
//!   passes on its water's character rather than its content's amount of texture. Untrained,
//!   after light-field retention, it lifts `uieb-val` from 30.40 dB / 0.939 to 30.64 / 0.946
//!   and `lsui-test` from 30.62 / 0.941 to 30.95 / 0.952 (`examples/depth_strength.rs`).
//! - The network starts exactly at the anchor (the last convolution is zero), and can
//!   only move it by a smooth per-pixel gain and offset: it corrects where the reference's water
//!   is brighter, darker, hazier or more tinted than a global transfer puts it (the light field
//!   shows where), but it cannot paint texture, so what it learns on one dataset's pairs cannot
//!   turn into artefacts on another's.
//! - Depth acts outside the network, through the image-formation model
//!   `I = J t + B (1 - t)`, `t = exp(-beta z)`: the anchored render `N` stands for the scene as
//!   the reference's water shows it at the reference's typical distance (`REFERENCE_DEPTH` of
//!   the normalised depth map), so `J = B + (N - B) / t(z_ref)` and
//!   `I(z) = B + (N - B) t(z) / t(z_ref)`. Farther than the reference the image moves towards the
//!   veiling light `B` and loses contrast; nearer it regains contrast, up to `MAX_GAIN`. The
//!   image's mean depth acts when the map says how far the scene is: a metric map (metres, the
//!   reference's subject taken to be [`REFERENCE_DISTANCE_M`] away) or an absolute one (uwnr's
//!   [0, 1], [`REFERENCE_DEPTH`] standing for the reference's distance; a constant map at 1 is
//!   a scene far away). A relative map (normalised per image, as the built-in prior and
//!   monocular networks give) says nothing about how far the scene is, so its mean is taken to
//!   be the reference's and only differences within the image act, its [0, 1] spanning a scene
//!   scale `s` in metres ([`DEFAULT_SCENE_SCALE_M`] unless given; datasets sample it per pair).
//! - How much the differences within the image act is the trust `k` of [`crate::finish::DepthResponse`]: a
//!   map the user measured or a model the user chose is trusted (`k = 1`: the water acts over
//!   the map's distances as it does over the reference's); the built-in prior is a guess (a
//!   ground-plane ramp), wrong about where the haze of a real target lies, so rendering trusts
//!   it [`PRIOR_TRUST`]. Measured on `paired/uieb-val` (and the held-out `lsui-test`) with the
//!   prior, the default scene scale and the network's correction at zero
//!   (`examples/depth_strength.rs`), prior trusts 0, 0.075, 0.15, 0.375, 0.75, 1 and 1.5 score
//!   30.40 (30.62), 30.23 (30.58), 29.84 (30.36), 28.24 (29.04), 25.46 (26.40), 23.89 (24.92)
//!   and 21.60 (22.89) dB before detail retention, and with it, as shipped, 0.075 scores 30.45
//!   (30.76) and 1 scores 23.97 (24.97) (Reinhard lαβ: 29.45 and 29.75).
//!   The statistics anchor cannot cancel
//!   the response and the network never sees depth, so it is monotonic by construction,
//!   whatever the weights (the training notes found that a network fed depth learns to ignore
//!   it, since in self-reconstruction the light field already shows the target's haze). In
//!   training the reference is the target, the same scene, so the reference's mean depth is the
//!   crop's own and only the within-image part acts (`uwnr-train`'s tensor form of [`crate::finish::finish`]).
//! - The water's parameters come from the reference ([`estimate_water`]): `B` by the quadtree
//!   search of Hou et al. (the UISA baseline's), `beta` per channel from how much contrast the
//!   reference keeps: `t_c(d_ref) = clamp(std_c / AIR_CONTRAST, MIN_TRANSMISSION, 1)`, where
//!   `AIR_CONTRAST` is the typical per-channel spread of an in-air photo. A channel the water
//!   flattens (red in blue water) attenuates fast; a hazy reference gives a strong response, a
//!   clear one a weak one. This is a one-image heuristic, not a fit; it is what makes the depth
//!   response follow the reference.

use serde::{Deserialize, Serialize};
use uwnr_baselines::reinhard::{ChannelStats, reference_stats, transfer_to_stats};
use uwnr_baselines::{BackgroundPick, ColourSpace, quadtree_background};
use uwnr_core::Image;
use uwnr_core::lightfield::light_field_with;

pub use crate::blur::BLUR_TRUNCATE_SIGMAS;
use crate::config::{AnchorKind, GeneratorConfig};
use crate::error::{ModelError, Result};
use crate::water::{Affine, bundled_bank};

pub use crate::variant::{ANCHORED_IN_CHANNELS, ANCHORED_OUT_CHANNELS, Variant};

mod detail;

pub use detail::{
    DETAIL_FLAT_STD, DETAIL_GAIN, DETAIL_NOISE_FLOOR, DETAIL_SIDE, DETAIL_SIGMA, DETAIL_WINDOW,
    detail_share, detail_share_with, retain_detail, retain_detail_with,
};

/// The colour space of the anchor's statistics transfer.
pub const ANCHOR_SPACE: ColourSpace = ColourSpace::LAlphaBeta;
/// Blur of the gain and offset planes, in pixels.
pub const SMOOTH_SIGMA: f64 = 12.0;
/// The normalised depth the anchored render stands for.
pub const REFERENCE_DEPTH: f32 = 0.5;
/// Typical per-channel standard deviation of an in-air photo (RGB in [0, 1]).
pub const AIR_CONTRAST: f64 = 0.25;
/// Floor of the transmission read off a reference's contrast.
pub const MIN_TRANSMISSION: f64 = 0.15;
/// Largest and smallest per-channel gain of the light-field retention step.
pub const RETENTION_GAIN: (f32, f32) = (0.5, 2.0);
/// Strength of the depth response within one image in training, in units of the normalised
/// map, relative to the response to the image's mean depth: the built-in prior at
/// [`PRIOR_TRUST`] over [`DEFAULT_SCENE_SCALE_M`] (the bundled model was trained with it).
pub const LOCAL_DEPTH_STRENGTH: f32 = 0.05;
/// The distance in metres at which the reference shows its subject: its contrast gives the
/// water's transmission at this distance, so `beta` per metre is `-ln t / REFERENCE_DISTANCE_M`.
/// Underwater photographs are taken close, since visibility is short: 1-5 m in UIEB's and
/// LSUI's scenes of divers, fish and reefs.
pub const REFERENCE_DISTANCE_M: f32 = 3.0;
/// The metres a relative depth map's [0, 1] spans when nothing says otherwise (near to far of an
/// indoor room or a reef scene; NYU-v2's measured maps span 3.5-6 m, Redwood's about 1.7 m).
pub const DEFAULT_SCENE_SCALE_M: f32 = 4.0;
/// How much rendering trusts the built-in prior's depth differences (1 = as a measured map):
/// the measured choice of the module doc, which keeps self-reconstruction above Reinhard's.
/// Equal to [`LOCAL_DEPTH_STRENGTH`] at [`DEFAULT_SCENE_SCALE_M`].
pub const PRIOR_TRUST: f32 = 0.075;
/// Largest contrast gain towards depth 0.
pub const MAX_GAIN: f32 = 2.0;
/// Stopping size of the veiling-light quadtree search (fraction of the pixels).
pub const VEIL_MIN_FRACTION: f64 = 0.01;

/// The water of a reference, as the anchored variant uses it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Water {
    /// The reference's lαβ statistics (the anchor's target).
    pub stats: ChannelStats,
    /// Veiling light `B`, RGB in [0, 1].
    pub veil: [f32; 3],
    /// Attenuation per unit of normalised depth, RGB ([`REFERENCE_DEPTH`] is the reference's
    /// distance; [`Water::beta_per_metre`] for metres).
    pub beta: [f32; 3],
    /// The reference's share of fine detail per channel ([`detail_share`]) when the model
    /// retains it (`detail_retention` in its config); `None` leaves the anchor's detail alone.
    #[serde(default)]
    pub detail: Option<[f32; 3]>,
    /// The reference's water as a per-channel gain and offset ([`crate::water`]) for a model
    /// whose anchor is the water (`"anchor": "water"`): the anchor is then this water on the
    /// clean image's own colours, not a transfer of `stats`; `None` for the Reinhard anchor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub affine: Option<Affine>,
}

impl Water {
    /// Attenuation per metre, RGB: the reference's subject taken to be [`REFERENCE_DISTANCE_M`]
    /// away.
    #[must_use]
    pub fn beta_per_metre(&self) -> [f32; 3] {
        self.beta
            .map(|b| b * REFERENCE_DEPTH / REFERENCE_DISTANCE_M)
    }
}

/// Estimates the water of the underwater image `reference` (module doc), without its detail.
pub fn estimate_water(reference: &Image) -> Result<Water> {
    estimate_water_with(reference, false)
}

/// [`estimate_water`], with the reference's share of detail when `detail_retention` is set.
pub fn estimate_water_with(reference: &Image, detail_retention: bool) -> Result<Water> {
    let baseline = |e: uwnr_baselines::BaselineError| ModelError::InvalidOptions(e.to_string());
    let stats = reference_stats(reference, ANCHOR_SPACE).map_err(baseline)?;
    let veil = quadtree_background(reference, VEIL_MIN_FRACTION, BackgroundPick::Mean)
        .map_err(baseline)?;
    let beta = std::array::from_fn(|c| {
        let (_, sd) = mean_std(reference.plane(c));
        let t = (sd / AIR_CONTRAST).clamp(MIN_TRANSMISSION, 1.0);
        (-t.ln() / f64::from(REFERENCE_DEPTH)) as f32
    });
    Ok(Water {
        stats,
        veil: veil.map(|v| v as f32),
        beta,
        detail: detail_retention.then(|| detail_share(reference)),
        affine: None,
    })
}

/// The water of `reference` for an anchor of kind `anchor`: [`estimate_water_with`] for the
/// Reinhard anchor; for the water anchor, the water the bundled bank predicts from the
/// reference's statistics ([`water_for_affine`]).
pub fn estimate_water_for(
    reference: &Image,
    anchor: AnchorKind,
    detail_retention: bool,
) -> Result<Water> {
    match anchor {
        AnchorKind::Reinhard => estimate_water_with(reference, detail_retention),
        AnchorKind::Water => {
            let affine = bundled_bank()?.predict(reference)?;
            water_for_affine(reference, affine, detail_retention)
        }
    }
}

/// The water of `reference` whose anchor is the per-channel water `affine` (predicted from the
/// reference, or drawn from a calibration target's bank): the depth stage follows the same
/// water, `t_c = a_c` at the reference's distance (clamped to [`MIN_TRANSMISSION`], 1) and
/// `B_c = b_c / (1 - a_c)` ([`Affine::veil`], the quadtree veil where a channel is not
/// attenuated), so that farther than the reference a scene moves on along the line the water
/// drew it on.
pub fn water_for_affine(
    reference: &Image,
    affine: Affine,
    detail_retention: bool,
) -> Result<Water> {
    let mut water = estimate_water_with(reference, false)?;
    water.detail = detail_retention.then(|| detail_share_with(reference, DETAIL_NOISE_FLOOR));
    set_affine(&mut water, affine);
    Ok(water)
}

/// Puts `affine` into `water`, with the veil and attenuation it implies ([`water_for_affine`]).
/// The gain is the transmission times the camera's gain, which is at least 1 underwater
/// (exposure makes up for the light the water takes), so `-ln a` is a lower bound of the
/// attenuation: `water`'s own (from the contrast the reference keeps) is kept where it is larger.
/// With the bound alone, the far quarter of photos with measured depth kept 0.72 (median) of its
/// contrast; with both, see `MODEL_CARD.md`.
pub fn set_affine(water: &mut Water, affine: Affine) {
    let affine = affine.clamped();
    water.veil = affine.veil(water.veil);
    for (beta, a) in water.beta.iter_mut().zip(affine.gain) {
        let t = f64::from(a).clamp(MIN_TRANSMISSION, 1.0);
        *beta = beta.max((-t.ln() / f64::from(REFERENCE_DEPTH)) as f32);
    }
    water.affine = Some(affine);
}

/// `water` (a reference's, as estimated) with the water `base` taken `s` of the way
/// ([`Affine::scaled`]): the attenuation the reference's contrast implies is scaled by `s` as
/// well (a path `s` times as long through the same water), then [`set_affine`] puts the scaled
/// water in. Without the scaling, the reference's contrast set a floor under the haze that a
/// weaker water could not go below, and datasets calibrated to a strength came out stronger than
/// their target (`MODEL_CARD.md`, "Strength corrected on the render").
pub fn set_scaled_water(water: &mut Water, base: Affine, s: f32) {
    let s = s.max(0.0);
    for beta in &mut water.beta {
        *beta *= s;
    }
    set_affine(water, base.scaled(s));
}

/// Mean and standard deviation of a plane.
pub(crate) fn mean_std(p: &[f32]) -> (f64, f64) {
    let n = p.len().max(1) as f64;
    let mean = p.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let var = p
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / n;
    (mean, var.sqrt())
}

/// What rendering needs of one reference, computed once and reused for any clean image.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceStyle {
    /// The light-field map (any size: it is resized to each clean image); `None` when the
    /// renders read none ([`GeneratorConfig::reads_light_field`]).
    pub light_field: Option<Image>,
    /// The water, for the anchored variant.
    pub water: Option<Water>,
    /// The reference's chromaticity ([`crate::water::chromaticity`]), for a clean balance that
    /// follows the water ([`crate::water::CleanBalance::following`]); `None` when the renders
    /// read none.
    pub chromaticity: Option<[f32; 3]>,
}

impl ReferenceStyle {
    /// The style of `reference` for a model with `config`: its light-field map (256x256, the
    /// map the config names) when its renders read one, and, for the anchored variant, its
    /// water.
    pub fn new(reference: &Image, config: &GeneratorConfig) -> Result<Self> {
        let light_field = if config.reads_light_field() {
            Some(light_field_with(reference, config.light_field)?)
        } else {
            None
        };
        let water = match config.variant {
            Variant::Paper => None,
            Variant::Anchored => Some(estimate_water_for(
                reference,
                config.anchor,
                config.detail_retention,
            )?),
        };
        Ok(Self {
            light_field,
            water,
            chromaticity: None,
        })
    }

    /// A style given by a light-field map alone (enough for the paper's variant).
    #[must_use]
    pub fn from_light_field(light_field: Image) -> Self {
        Self {
            light_field: Some(light_field),
            water: None,
            chromaticity: None,
        }
    }
}

/// The colour transfer of `clean` to the reference's lαβ statistics (the first half of
/// [`anchor`]).
pub fn colour_transfer(clean: &Image, water: &Water) -> Result<Image> {
    if let Some(affine) = &water.affine {
        return affine.apply(clean);
    }
    transfer_to_stats(clean, water.stats, ANCHOR_SPACE)
        .map_err(|e| ModelError::InvalidOptions(e.to_string()))
}

/// Light-field retention: `transfer` scaled per channel so that its light field matches the
/// reference's, `x_c * 10^((LF_ref,c - LF_x,c) * R)` (`R` = [`uwnr_core::lightfield::absolute_log10_range`]) clamped to
/// [`RETENTION_GAIN`]. The absolute map is the mean over its three blurs of
/// `log10(blur) / ABSOLUTE_RANGE`, so the factor is the geometric mean of the ratios of the
/// reference's and the transfer's blurred channels: the transfer keeps its own detail and takes
/// the reference's coarse distribution of light and colour (brighter above, darker at the
/// bottom, bluer on one side). Both maps must come from the same geometry (at render time the
/// 256x256 map resized to the image; in training the crop's own).
/// `transfer` is taken and changed in place.
pub fn retain_light_field(
    transfer: Image,
    transfer_lf: &Image,
    reference_lf: &Image,
) -> Result<Image> {
    for (what, im) in [
        ("transfer light field", transfer_lf),
        ("reference light field", reference_lf),
    ] {
        if im.size() != transfer.size() || im.channels() != 3 {
            return Err(ModelError::ImageSize {
                what,
                expected: transfer.size(),
                got: im.size(),
            });
        }
    }
    let range = uwnr_core::lightfield::absolute_log10_range() as f32;
    let mut out = transfer;
    for c in 0..3 {
        let (t, r) = (transfer_lf.plane(c), reference_lf.plane(c));
        for (i, v) in out.plane_mut(c).iter_mut().enumerate() {
            let gain = 10f32
                .powf((r[i] - t[i]) * range)
                .clamp(RETENTION_GAIN.0, RETENTION_GAIN.1);
            *v = (*v * gain).clamp(0.0, 1.0);
        }
    }
    Ok(out)
}

/// The anchor of `clean`: the colour transfer to the reference's statistics, with the
/// reference's light field retained ([`retain_light_field`]) and, when the water carries the
/// reference's share of detail, its detail too ([`retain_detail`]). `reference_lf` is the reference's
/// absolute light field at the clean image's size; `light_field` computes a map of the same
/// geometry from an image of that size.
pub fn anchor(
    clean: &Image,
    water: &Water,
    reference_lf: &Image,
    light_field: impl Fn(&Image) -> Result<Image>,
) -> Result<Image> {
    if water.affine.is_some() {
        return water_anchor(clean, water);
    }
    let transfer = colour_transfer(clean, water)?;
    let transfer_lf = light_field(&transfer)?;
    let retained = retain_light_field(transfer, &transfer_lf, reference_lf)?;
    Ok(match water.detail {
        Some(detail) => retain_detail(retained, detail)?,
        None => retained,
    })
}

/// The anchor of a water with a gain and offset ([`Water::affine`]): that water on the clean
/// image's own colours, then its detail retained above [`DETAIL_NOISE_FLOOR`]. It reads no
/// light field: a real pair's two sides differ by a global gain and offset per channel
/// (`crate::water`), and the reference's light field is a picture of its own scene.
pub fn water_anchor(clean: &Image, water: &Water) -> Result<Image> {
    let transfer = colour_transfer(clean, water)?;
    Ok(match water.detail {
        Some(detail) => retain_detail_with(transfer, detail, DETAIL_NOISE_FLOOR)?,
        None => transfer,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contrast_sets_the_attenuation() {
        // A flat red channel attenuates fastest; a full-contrast channel not at all.
        let (w, h) = (32, 32);
        let mut data = Vec::new();
        for c in 0..3 {
            for i in 0..w * h {
                let checker = if (i / w + i % w) % 2 == 0 { 1.0 } else { 0.0 };
                let amp = [0.02, 0.3, 0.6][c];
                data.push(0.5 - amp / 2.0 + amp * checker);
            }
        }
        let img = Image::from_planar(w, h, 3, data).unwrap();
        let water = estimate_water(&img).unwrap();
        let t_min_beta = (-MIN_TRANSMISSION.ln() / f64::from(REFERENCE_DEPTH)) as f32;
        assert!(
            (water.beta[0] - t_min_beta).abs() < 1e-5,
            "{:?}",
            water.beta
        );
        assert!(water.beta[1] > 0.0 && water.beta[1] < water.beta[0]);
        assert_eq!(water.beta[2], 0.0);
    }

    #[test]
    fn a_scaled_water_scales_the_reference_attenuation() {
        let water = Water {
            stats: ChannelStats {
                mean: [0.0; 3],
                std: [1.0; 3],
            },
            veil: [0.1, 0.4, 0.5],
            beta: [2.0, 1.0, 0.5],
            detail: None,
            affine: None,
        };
        // A mild water: its own attenuation (-ln a / depth) is below the reference's.
        let base = Affine {
            gain: [0.8, 0.9, 0.9],
            offset: [0.0, 0.05, 0.06],
        };
        let at = |s: f32| {
            let mut w = water;
            set_scaled_water(&mut w, base, s);
            w
        };
        // At scale 1 the reference's contrast sets it, as set_affine does.
        let mut full = water;
        set_affine(&mut full, base);
        assert_eq!(at(1.0).beta, full.beta);
        assert_eq!(at(1.0).beta, [2.0, 1.0, 0.5]);
        // At half the path, half the attenuation (the water's own bound is lower still).
        let half = at(0.5);
        for c in 0..3 {
            assert!(
                (half.beta[c] - water.beta[c] * 0.5).abs() < 1e-6,
                "{:?}",
                half.beta
            );
        }
        assert_eq!(half.affine, Some(base.scaled(0.5)));
        // No water, no attenuation.
        assert_eq!(at(0.0).beta, [0.0; 3]);
        // Stronger than the reference: more of it.
        assert!(at(1.5).beta.iter().zip(full.beta).all(|(a, b)| *a > b));
    }
}
