//! Rendering a clean image with a trained generator: the water code `z` comes from `seed`, so a
//! given (weights, image, depth, seed) always gives the same render.

use burn::tensor::{Device, Tensor, TensorData};
use uwnr_core::Image;

use crate::error::{GanError, Result, to_vec};
use crate::imaging::{RGB, WaterParams};
use crate::model::{Generator, sample_z};

/// The image-formation parameters of one render, as numbers (for reports).
#[derive(Clone, Debug, PartialEq)]
pub struct WaterValues {
    /// Attenuation per metre, R, G, B.
    pub beta: [f32; 3],
    /// Veiling light, R, G, B.
    pub backlight: [f32; 3],
    /// Vignetting coefficients of `r², r⁴, r⁶`.
    pub vignette: [f32; 3],
    /// Camera gain.
    pub gain: f32,
    /// Blur weight (used only when the generator's imaging config has the blur on).
    pub blur: f32,
}

impl WaterValues {
    /// The first row of `params`.
    fn first(params: WaterParams) -> Result<Self> {
        let three = |t: Tensor<2>| -> Result<[f32; 3]> {
            let v = to_vec(t)?;
            Ok([v[0], v[1], v[2]])
        };
        Ok(Self {
            beta: three(params.beta)?,
            backlight: three(params.backlight)?,
            vignette: three(params.vignette)?,
            gain: to_vec(params.gain)?[0],
            blur: to_vec(params.blur)?[0],
        })
    }
}

/// Renders `clean` (RGB in [0, 1]) with its `depth` (1 channel, [0, 1], larger = farther, the
/// same size) under the water the generator predicts for code `seed`.
pub fn render(
    generator: &Generator,
    clean: &Image,
    depth: &Image,
    seed: u64,
    device: &Device,
) -> Result<Image> {
    Ok(render_with_values(generator, clean, depth, seed, device)?.0)
}

/// [`render`], also returning the parameters used.
pub fn render_with_values(
    generator: &Generator,
    clean: &Image,
    depth: &Image,
    seed: u64,
    device: &Device,
) -> Result<(Image, WaterValues)> {
    if clean.channels() != RGB {
        return Err(GanError::ShapeMismatch {
            what: "clean image channels",
            expected: vec![RGB],
            got: vec![clean.channels()],
        });
    }
    if depth.channels() != 1 || depth.size() != clean.size() {
        return Err(GanError::ShapeMismatch {
            what: "depth map (channels, width, height)",
            expected: vec![1, clean.width(), clean.height()],
            got: vec![depth.channels(), depth.width(), depth.height()],
        });
    }
    let (w, h) = clean.size();
    let x = Tensor::<4>::from_data(
        TensorData::new(clean.data().to_vec(), [1, RGB, h, w]),
        device,
    );
    let d = Tensor::<4>::from_data(TensorData::new(depth.data().to_vec(), [1, 1, h, w]), device);
    let z = sample_z(seed, 1, generator.config.z_dim, device);
    let (out, params) = generator.forward(x, d, z)?;
    // The render is in [0, 1] by construction; the clamp only removes rounding excursions.
    let data = to_vec(out.clamp(0.0, 1.0))?;
    Ok((
        Image::from_planar(w, h, RGB, data)?,
        WaterValues::first(params)?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::GeneratorConfig;

    #[test]
    fn the_same_seed_renders_the_same_image_and_another_seed_another() {
        let d = Device::flex();
        let g = GeneratorConfig {
            z_dim: 8,
            widths: vec![4, 8],
            hidden: 8,
            encoder_size: 8,
            ..GeneratorConfig::default()
        }
        .init(&d)
        .unwrap();
        let clean =
            Image::from_planar(4, 3, 3, (0..36).map(|i| i as f32 / 36.0).collect()).unwrap();
        let depth =
            Image::from_planar(4, 3, 1, (0..12).map(|i| i as f32 / 12.0).collect()).unwrap();
        let (a, va) = render_with_values(&g, &clean, &depth, 7, &d).unwrap();
        let (b, vb) = render_with_values(&g, &clean, &depth, 7, &d).unwrap();
        assert_eq!(a, b);
        assert_eq!(va, vb);
        let (c, vc) = render_with_values(&g, &clean, &depth, 8, &d).unwrap();
        assert_ne!(va, vc);
        assert_ne!(a, c);
        assert_eq!(a.size(), (4, 3));
        assert!(a.data().iter().all(|v| (0.0..=1.0).contains(v)));
        let bad = Image::filled(5, 3, 1, 0.5);
        assert!(render(&g, &clean, &bad, 7, &d).is_err());
    }
}
