//! What real underwater photos have that a water applied to a clean photo lacks, as stages of
//! the uwnr method after its depth stage, each a number of [`WaterEffects`] (0 turns it off),
//! every random draw seeded by the render's seed:
//!
//! - **particles**: marine snow, small soft spots lit towards the veil's colour, a Poisson-like
//!   count per 256 x 256 px;
//! - **light from above**: the surface lights the top of the frame, the bottom is darker
//!   (brightness `1 + a (1/2 - y / h)`);
//! - **vignette**: light falling off from the centre (`1 - v r^2`, `r` 1 at the corners);
//! - **absorb**: colours the water removes: the chroma opposite the veil's hue (a red flower or a
//!   blue sky under green water) is cut by `absorb`, half of it near and all of it at the
//!   farthest point, while the chroma towards the veil's hue and across it stays;
//! - **forward scattering**: light scattered at small angles on its way from the subject, a
//!   point spread that widens with distance (Ismiroglou et al., "Sea-ing Through Scattered Rays",
//!   the revised image formation model with forward scattering): each pixel mixes with its blur,
//!   sigma from 1 px near to 3 px at the farthest (at a 256 px side, scaled with the image), the
//!   scattered share `forward_scatter x` relative distance;
//! - **medium**: a medium that varies over the frame: a smooth random field (a 5 x 5 grid of
//!   normal draws, interpolated smoothly, standard deviation `medium`) moves each pixel towards
//!   the veil where the water is thicker and away from it where it is thinner.
//!
//! Distances are the depth map's, relative within the image (0 nearest, 1 farthest); a constant
//! map is all near. The realism table in `docs/RESULTS.md` measures each stage alone.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::blur::blur_plane;
use crate::error::{ModelError, Result};

/// Side, in pixels, that the pixel sizes of the stages refer to (scaled with the shorter side).
const UNIT_SIDE: f32 = 256.0;
/// Sigma of a particle's spot, px at [`UNIT_SIDE`].
const PARTICLE_SIGMA: f32 = 0.8;
/// A particle's colour: the veil lifted by this much (light scattered by the particle).
const PARTICLE_LIFT: f32 = 0.35;
/// A particle's peak opacity is drawn in this range.
const PARTICLE_OPACITY: (f32, f32) = (0.3, 1.0);
/// Forward scattering's sigma near and at the farthest point, px at [`UNIT_SIDE`].
const SCATTER_SIGMA: (f32, f32) = (1.0, 3.0);
/// Nodes per side of the medium's random grid.
const MEDIUM_GRID: usize = 5;
/// Largest share of the way to the veil (or away from it) the medium moves a pixel.
const MEDIUM_LIMIT: f32 = 0.9;
/// Mixed into the render's seed for the effects' draws (a stream of their own).
const EFFECTS_STREAM: u64 = 0x5EA5_A077;

/// The stages and their strengths (module doc); all 0 is no stage at all.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WaterEffects {
    /// Particles per 256 x 256 px, on average.
    pub particles: f32,
    /// Brightness difference between the top and the bottom of the frame.
    pub light_from_above: f32,
    /// Light lost at the corners.
    pub vignette: f32,
    /// Share of the chroma across the veil's hue removed at the farthest point.
    pub absorb: f32,
    /// Share of the direct light scattered forward at the farthest point.
    pub forward_scatter: f32,
    /// Standard deviation of the medium's field.
    pub medium: f32,
}

impl WaterEffects {
    /// No stage.
    pub const NONE: Self = Self {
        particles: 0.0,
        light_from_above: 0.0,
        vignette: 0.0,
        absorb: 0.0,
        forward_scatter: 0.0,
        medium: 0.0,
    };

    /// uwnr's default (`docs/RESULTS.md`, "Realism"): particles, which alone took FID from 217.6
    /// to 210.3 on the realism protocol, with light from above and absorbed colours, which water
    /// has and which moved it by about a point either way, and forward scattering (no change
    /// alone, 217.2), which makes distance act within an image as water does (the depth effect
    /// 0.72 without it, 0.64 with it) and costs about 7 ms per pair since the blur vectorises.
    /// The medium and the vignette made realism worse and are off.
    pub const DEFAULT: Self = Self {
        particles: 80.0,
        light_from_above: 0.6,
        vignette: 0.0,
        absorb: 0.5,
        forward_scatter: 0.3,
        medium: 0.0,
    };

    /// Whether no stage runs.
    #[must_use]
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    fn fields(&self) -> [(&'static str, f32, f32); 6] {
        [
            ("particles", self.particles, 10_000.0),
            ("light_from_above", self.light_from_above, 1.0),
            ("vignette", self.vignette, 1.0),
            ("absorb", self.absorb, 1.0),
            ("forward_scatter", self.forward_scatter, 1.0),
            ("medium", self.medium, 1.0),
        ]
    }

    /// Checks that every strength is finite and within its range.
    pub fn validate(&self) -> Result<()> {
        for (name, v, max) in self.fields() {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(ModelError::InvalidOptions(format!(
                    "effects.{name} = {v} must be within [0, {max}]"
                )));
            }
        }
        Ok(())
    }

    /// Whether a light stage (light from above, the vignette) runs.
    #[must_use]
    pub fn has_light(&self) -> bool {
        self.light_from_above > 0.0 || self.vignette > 0.0
    }

    /// Only the light's stages (light from above and the vignette) on `img` (RGB in [0, 1]):
    /// what a pair's clean side shares with its underwater side when the scene's light is kept
    /// on both, as real pairs' clean sides keep it. Nothing when both are 0.
    pub fn apply_light(&self, img: &mut Image) -> Result<()> {
        self.validate()?;
        if self.has_light() {
            light(img, self.light_from_above, self.vignette);
            img.clamp01();
        }
        Ok(())
    }

    /// Applies the stages to `img` (RGB in [0, 1]) over `depth` (1 plane, its size, larger is
    /// farther) in a water whose veil is `veil`; `seed` draws the particles and the medium.
    pub fn apply(&self, img: &mut Image, depth: &Image, veil: [f32; 3], seed: u64) -> Result<()> {
        let frame = img.width().min(img.height()) as f32;
        self.apply_in_frame(img, depth, veil, seed, frame)
    }

    /// [`Self::apply`] on a crop of a larger frame: spots and point spreads sized for a frame
    /// whose shorter side is `frame` px (`apply` takes the image's own), particles as many per
    /// pixel as in the frame.
    pub fn apply_in_frame(
        &self,
        img: &mut Image,
        depth: &Image,
        veil: [f32; 3],
        seed: u64,
        frame: f32,
    ) -> Result<()> {
        self.validate()?;
        if !(frame.is_finite() && frame > 0.0) {
            return Err(ModelError::InvalidOptions(format!(
                "effects frame side {frame} must be finite and > 0"
            )));
        }
        let unit = frame / UNIT_SIDE;
        if self.is_none() {
            return Ok(());
        }
        let (w, h) = img.size();
        if img.channels() != 3 || depth.size() != (w, h) || depth.channels() != 1 {
            return Err(ModelError::InvalidOptions(format!(
                "effects need an RGB image and a 1-plane depth map of its size, got {}x{}x{} and \
                 {}x{}x{}",
                w,
                h,
                img.channels(),
                depth.width(),
                depth.height(),
                depth.channels()
            )));
        }
        let d = relative(depth.plane(0));
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ EFFECTS_STREAM);
        if self.absorb > 0.0 {
            absorb(img, &d, veil, self.absorb);
        }
        if self.forward_scatter > 0.0 {
            forward_scatter(img, &d, self.forward_scatter, unit);
        }
        // The medium's nodes are drawn whether or not it runs, so the particles do not move with
        // it; the field is spread over the frame only when it runs.
        let nodes = medium_nodes(&mut rng);
        if self.medium > 0.0 {
            let field = smooth_field(&nodes, w, h);
            for (c, &b) in veil.iter().enumerate() {
                for (v, f) in img.plane_mut(c).iter_mut().zip(&field) {
                    let share = (self.medium * f).clamp(-MEDIUM_LIMIT, MEDIUM_LIMIT);
                    *v += share * (b - *v);
                }
            }
        }
        if self.has_light() {
            light(img, self.light_from_above, self.vignette);
        }
        if self.particles > 0.0 {
            particles(img, veil, self.particles, unit, &mut rng);
        }
        img.clamp01();
        Ok(())
    }
}

/// A depth plane as 0 (nearest) to 1 (farthest); all 0 when it is flat or not finite.
fn relative(d: &[f32]) -> Vec<f32> {
    let (lo, hi) = d
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return vec![0.0; d.len()];
    }
    d.iter()
        .map(|&v| {
            if v.is_finite() {
                (v - lo) / (hi - lo)
            } else {
                0.0
            }
        })
        .collect()
}

/// The chroma opposite the veil's hue cut by `a (1 + d) / 2`.
fn absorb(img: &mut Image, d: &[f32], veil: [f32; 3], a: f32) {
    let vm = (veil[0] + veil[1] + veil[2]) / 3.0;
    let mut u = veil.map(|v| v - vm);
    let norm = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    if norm > 1e-6 {
        u = u.map(|v| v / norm);
    } else {
        u = [0.0; 3];
    }
    let n = d.len();
    let data = img.data_mut();
    for (i, &di) in d.iter().enumerate() {
        let px = [data[i], data[n + i], data[2 * n + i]];
        let y = (px[0] + px[1] + px[2]) / 3.0;
        let along = (px[0] - y) * u[0] + (px[1] - y) * u[1] + (px[2] - y) * u[2];
        let keep = 1.0 - a * 0.5 * (1.0 + di);
        // Towards the veil's hue and across it stays; opposite it goes.
        let cut = (1.0 - keep) * along.min(0.0);
        for c in 0..3 {
            data[c * n + i] = px[c] - cut * u[c];
        }
    }
}

/// Each pixel mixed with its blur, sigma and share growing with distance.
fn forward_scatter(img: &mut Image, d: &[f32], strength: f32, unit: f32) {
    let (w, h) = img.size();
    for c in 0..3 {
        let plane = img.plane_mut(c);
        let mut near = plane.to_vec();
        let mut far = plane.to_vec();
        blur_plane(&mut near, w, h, f64::from(SCATTER_SIGMA.0 * unit));
        blur_plane(&mut far, w, h, f64::from(SCATTER_SIGMA.1 * unit));
        for (i, v) in plane.iter_mut().enumerate() {
            let spread = near[i] + (far[i] - near[i]) * d[i];
            let share = (strength * d[i]).min(1.0);
            *v += share * (spread - *v);
        }
    }
}

/// The medium's grid of normal draws.
fn medium_nodes(rng: &mut ChaCha8Rng) -> Vec<f32> {
    (0..MEDIUM_GRID * MEDIUM_GRID)
        .map(|_| normal(rng))
        .collect()
}

/// A smooth field over the frame with standard deviation 1: the grid's `nodes` interpolated
/// with smoothstep weights.
fn smooth_field(nodes: &[f32], w: usize, h: usize) -> Vec<f32> {
    let last = (MEDIUM_GRID - 1) as f32;
    let axis = |i: usize, n: usize| {
        let t = if n > 1 {
            i as f32 / (n - 1) as f32 * last
        } else {
            0.0
        };
        let k = (t.floor() as usize).min(MEDIUM_GRID - 2);
        let f = t - k as f32;
        (k, f * f * (3.0 - 2.0 * f))
    };
    let mut field = Vec::with_capacity(w * h);
    for y in 0..h {
        let (ky, fy) = axis(y, h);
        for x in 0..w {
            let (kx, fx) = axis(x, w);
            let at = |j: usize, i: usize| nodes[j * MEDIUM_GRID + i];
            let top = at(ky, kx) + (at(ky, kx + 1) - at(ky, kx)) * fx;
            let bottom = at(ky + 1, kx) + (at(ky + 1, kx + 1) - at(ky + 1, kx)) * fx;
            field.push(top + (bottom - top) * fy);
        }
    }
    let (mean, std) = crate::style::mean_std(&field);
    let scale = if std > 1e-6 { 1.0 / std } else { 0.0 };
    field
        .iter_mut()
        .for_each(|v| *v = ((f64::from(*v) - mean) * scale) as f32);
    field
}

/// A standard normal draw (Box-Muller), for the effects and the dataset's camera noise.
pub fn normal(rng: &mut ChaCha8Rng) -> f32 {
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random();
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

/// Brightness from above and from the centre.
fn light(img: &mut Image, above: f32, vignette: f32) {
    let (w, h) = img.size();
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let r2_max = (cx * cx + cy * cy).max(1.0);
    let gain: Vec<f32> = (0..h)
        .flat_map(|y| {
            (0..w).map(move |x| {
                let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
                let r2 = (dx * dx + dy * dy) / r2_max;
                (1.0 - vignette * r2) * (1.0 + above * (0.5 - (y as f32 + 0.5) / h as f32))
            })
        })
        .collect();
    for c in 0..3 {
        for (v, g) in img.plane_mut(c).iter_mut().zip(&gain) {
            *v *= g;
        }
    }
}

/// Soft spots lit towards the veil's colour.
fn particles(img: &mut Image, veil: [f32; 3], density: f32, unit: f32, rng: &mut ChaCha8Rng) {
    let (w, h) = img.size();
    let expected = density * (w * h) as f32 / (UNIT_SIDE * UNIT_SIDE);
    let count = (expected + rng.random::<f32>()).floor() as usize;
    let colour = veil.map(|v| (v + PARTICLE_LIFT).min(1.0));
    let sigma = (PARTICLE_SIGMA * unit).max(0.3);
    let radius = (3.0 * sigma).ceil() as i64;
    let n = w * h;
    for _ in 0..count {
        let px = rng.random_range(0..w) as i64;
        let py = rng.random_range(0..h) as i64;
        let opacity = rng.random_range(PARTICLE_OPACITY.0..PARTICLE_OPACITY.1);
        let data = img.data_mut();
        for y in (py - radius).max(0)..=(py + radius).min(h as i64 - 1) {
            for x in (px - radius).max(0)..=(px + radius).min(w as i64 - 1) {
                let r2 = ((x - px) * (x - px) + (y - py) * (y - py)) as f32;
                let a = opacity * (-r2 / (2.0 * sigma * sigma)).exp();
                let i = y as usize * w + x as usize;
                for (c, &pc) in colour.iter().enumerate() {
                    let v = &mut data[c * n + i];
                    *v += a * (pc - *v);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stripes(w: usize, h: usize) -> Image {
        let mut img = Image::filled(w, h, 3, 0.0);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                *v = if (i % w / 2).is_multiple_of(2) {
                    0.8
                } else {
                    0.2
                };
            }
        }
        img
    }

    /// Depth growing left to right (the left edge nearest).
    fn ramp(w: usize, h: usize) -> Image {
        let mut d = Image::filled(w, h, 1, 0.0);
        for (i, v) in d.plane_mut(0).iter_mut().enumerate() {
            *v = (i % w) as f32 / (w - 1) as f32;
        }
        d
    }

    fn contrast(img: &Image, x0: usize, x1: usize) -> f32 {
        let (w, h) = img.size();
        let p = img.plane(1);
        let vals: Vec<f32> = (0..h)
            .flat_map(|y| (x0..x1).map(move |x| p[y * w + x]))
            .collect();
        let m = vals.iter().sum::<f32>() / vals.len() as f32;
        (vals.iter().map(|v| (v - m) * (v - m)).sum::<f32>() / vals.len() as f32).sqrt()
    }

    #[test]
    fn a_crop_takes_its_frames_scale() {
        // `apply` is `apply_in_frame` at the image's own side; a larger frame spreads the far
        // parts more.
        let (w, h) = (64, 64);
        let fx = WaterEffects::DEFAULT;
        let (mut own, mut same, mut framed) = (stripes(w, h), stripes(w, h), stripes(w, h));
        fx.apply(&mut own, &ramp(w, h), [0.1, 0.5, 0.4], 3).unwrap();
        fx.apply_in_frame(&mut same, &ramp(w, h), [0.1, 0.5, 0.4], 3, 64.0)
            .unwrap();
        fx.apply_in_frame(&mut framed, &ramp(w, h), [0.1, 0.5, 0.4], 3, 256.0)
            .unwrap();
        assert_eq!(own.data(), same.data());
        assert!(contrast(&framed, 48, 64) < contrast(&own, 48, 64));
        assert!(
            fx.apply_in_frame(&mut framed, &ramp(w, h), [0.1, 0.5, 0.4], 3, f32::NAN)
                .is_err()
        );
    }

    #[test]
    fn forward_scattering_blurs_far_more_than_near() {
        let (w, h) = (256, 256);
        let mut img = stripes(w, h);
        let before = (contrast(&img, 0, 16), contrast(&img, 224, 256));
        let fx = WaterEffects {
            forward_scatter: 1.0,
            ..WaterEffects::NONE
        };
        fx.apply(&mut img, &ramp(w, h), [0.1, 0.5, 0.4], 0).unwrap();
        let after = (contrast(&img, 0, 16), contrast(&img, 224, 256));
        assert!((before.0 - before.1).abs() < 1e-4);
        // Near: little lost; far: most of the stripes' contrast gone.
        assert!(after.0 > 0.9 * before.0, "{before:?} {after:?}");
        assert!(after.1 < 0.3 * before.1, "{before:?} {after:?}");
    }

    #[test]
    fn the_medium_field_is_fixed_by_the_seed_and_moves_with_it() {
        let (w, h) = (96, 64);
        let fx = WaterEffects {
            medium: 0.3,
            particles: 40.0,
            ..WaterEffects::NONE
        };
        let run = |seed| {
            let mut img = Image::filled(w, h, 3, 0.5);
            fx.apply(&mut img, &ramp(w, h), [0.1, 0.6, 0.5], seed)
                .unwrap();
            img
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
        let field = smooth_field(&medium_nodes(&mut ChaCha8Rng::seed_from_u64(1)), w, h);
        let mean = field.iter().sum::<f32>() / field.len() as f32;
        let var = field.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / field.len() as f32;
        assert!(
            mean.abs() < 1e-4 && (var - 1.0).abs() < 1e-3,
            "{mean} {var}"
        );
        // Smooth: neighbours along a row differ by a small fraction of the spread.
        let step = field
            .chunks(w)
            .flat_map(|row| row.windows(2).map(|p| (p[1] - p[0]).abs()))
            .fold(0.0, f32::max);
        assert!(step < 0.35, "{step}");
    }

    #[test]
    fn absorb_removes_colours_across_the_water_and_keeps_the_waters_own() {
        let (w, h) = (8, 8);
        let veil = [0.1, 0.6, 0.5];
        let fx = WaterEffects {
            absorb: 1.0,
            ..WaterEffects::NONE
        };
        let far = Image::filled(w, h, 1, 1.0);
        let mut red = Image::filled(w, h, 3, 0.1);
        red.plane_mut(0).fill(0.9);
        // A constant map is all near: half the chroma that is not the water's goes.
        fx.apply(&mut red, &far, veil, 0).unwrap();
        let spread = |img: &Image| {
            let px: Vec<f32> = (0..3).map(|c| img.plane(c)[0]).collect();
            px.iter().cloned().fold(0.0, f32::max) - px.iter().cloned().fold(1.0, f32::min)
        };
        assert!(spread(&red) < 0.6, "{}", spread(&red));
        let mut water = Image::filled(w, h, 3, 0.0);
        for (c, v) in veil.iter().enumerate() {
            water.plane_mut(c).fill(*v);
        }
        let before = water.clone();
        fx.apply(&mut water, &far, veil, 0).unwrap();
        for (a, b) in water.data().iter().zip(before.data()) {
            assert!((a - b).abs() < 1e-5);
        }
    }

    #[test]
    fn the_light_alone_is_the_light_of_the_whole_stage() {
        let (w, h) = (40, 30);
        let depth = Image::filled(w, h, 1, 0.3);
        let fx = WaterEffects {
            light_from_above: 0.6,
            vignette: 0.2,
            ..WaterEffects::NONE
        };
        let mut whole = stripes(w, h);
        fx.apply(&mut whole, &depth, [0.1, 0.5, 0.4], 3).unwrap();
        let mut light_only = stripes(w, h);
        fx.apply_light(&mut light_only).unwrap();
        assert_eq!(whole, light_only);
        assert_ne!(light_only, stripes(w, h));
        // The other stages are not the scene's light: nothing of them.
        let mut unlit = stripes(w, h);
        WaterEffects {
            light_from_above: 0.0,
            ..WaterEffects::DEFAULT
        }
        .apply_light(&mut unlit)
        .unwrap();
        assert_eq!(unlit, stripes(w, h));
        let bad = WaterEffects {
            light_from_above: 2.0,
            ..WaterEffects::NONE
        };
        assert!(bad.apply_light(&mut unlit).is_err());
    }

    #[test]
    fn light_falls_from_above_and_particles_lighten() {
        let (w, h) = (64, 64);
        let flat = Image::filled(w, h, 1, 0.0);
        let mut img = Image::filled(w, h, 3, 0.5);
        WaterEffects {
            light_from_above: 0.4,
            ..WaterEffects::NONE
        }
        .apply(&mut img, &flat, [0.1, 0.5, 0.4], 0)
        .unwrap();
        assert!(img.get(1, 0, 32) > 0.59 && img.get(1, h - 1, 32) < 0.41);
        let mut img = Image::filled(w, h, 3, 0.2);
        WaterEffects {
            particles: 200.0,
            ..WaterEffects::NONE
        }
        .apply(&mut img, &flat, [0.1, 0.5, 0.4], 0)
        .unwrap();
        let lit = img.plane(1).iter().filter(|&&v| v > 0.3).count();
        assert!(lit > 10, "{lit}");
        assert!(
            WaterEffects {
                medium: f32::NAN,
                ..WaterEffects::NONE
            }
            .validate()
            .is_err()
        );
    }
}
