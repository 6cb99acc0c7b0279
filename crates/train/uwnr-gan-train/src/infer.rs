//! Rendering a clean image with burn's generator, as `uwnr_gan::infer` does without burn: the
//! water code `z` comes from `seed`, so a given (weights, image, depth, seed) always gives the
//! same render. Training's validation sheets use it; the tests compare the two.

use burn::tensor::{Device, Tensor, TensorData};
use uwnr_core::Image;

use crate::error::{Result, to_vec};
use crate::imaging::{RGB, WaterParams};
use crate::model::{Generator, sample_z};

pub use uwnr_gan::WaterValues;

/// The first row of `params`.
fn first(params: WaterParams) -> Result<WaterValues> {
    let three = |t: Tensor<2>| -> Result<[f32; 3]> {
        let v = to_vec(t)?;
        Ok([v[0], v[1], v[2]])
    };
    Ok(WaterValues {
        beta: three(params.beta)?,
        backlight: three(params.backlight)?,
        vignette: three(params.vignette)?,
        gain: to_vec(params.gain)?[0],
        blur: to_vec(params.blur)?[0],
    })
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
    uwnr_gan::imaging::check_inputs(clean, depth)?;
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
    Ok((Image::from_planar(w, h, RGB, data)?, first(params)?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{GeneratorConfig, GeneratorInit};

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

    /// The render wing's generator (`uwnr_gan`, plain Rust) reads the weights this crate saves
    /// and renders what burn's module renders: the same parameters to float rounding, the same
    /// image within a hundredth of an 8-bit level, at sizes the encoder's pooling does not divide
    /// evenly, with the blur on, and with the bundled generator when this build has one.
    #[test]
    fn the_render_wing_renders_what_burn_renders() {
        let d = Device::flex();
        d.seed(11);
        let cfg = GeneratorConfig {
            z_dim: 16,
            widths: vec![8, 16, 16],
            hidden: 16,
            encoder_size: 16,
            imaging: crate::ImagingConfig {
                blur: true,
                range_m: 6.0,
            },
        };
        let g = cfg.init(&d).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(crate::GENERATOR_FILE);
        crate::save_generator(&g, &path, &std::collections::BTreeMap::new()).unwrap();
        let plain = uwnr_gan::load_generator(&path).unwrap();
        let mut generators = vec![(g, plain)];
        if let Some(bytes) = crate::bundled_gan_weights() {
            let name = std::path::Path::new("bundled");
            generators.push((
                crate::load_generator_from_bytes(bytes.to_vec(), name, &d).unwrap(),
                uwnr_gan::load_generator_from_bytes(bytes, name).unwrap(),
            ));
        }
        for (burn, plain) in &generators {
            for (w, h) in [(37, 23), (64, 48), (13, 71)] {
                let clean = Image::from_planar(
                    w,
                    h,
                    3,
                    (0..3 * w * h)
                        .map(|i| ((i * 37 % 101) as f32 / 100.0).clamp(0.0, 1.0))
                        .collect(),
                )
                .unwrap();
                let depth = Image::from_planar(
                    w,
                    h,
                    1,
                    (0..w * h).map(|i| (i % w) as f32 / w as f32).collect(),
                )
                .unwrap();
                for seed in [0, 5] {
                    let (a, va) = render_with_values(burn, &clean, &depth, seed, &d).unwrap();
                    let (b, vb) =
                        uwnr_gan::render_with_values(plain, &clean, &depth, seed).unwrap();
                    let close = |x: &[f32], y: &[f32]| {
                        x.iter()
                            .zip(y)
                            .all(|(p, q)| (p - q).abs() <= 1e-5 * (1.0 + p.abs()))
                    };
                    assert!(close(&va.beta, &vb.beta), "{va:?} {vb:?}");
                    assert!(close(&va.backlight, &vb.backlight), "{va:?} {vb:?}");
                    assert!(close(&va.vignette, &vb.vignette), "{va:?} {vb:?}");
                    assert!(
                        close(&[va.gain, va.blur], &[vb.gain, vb.blur]),
                        "{va:?} {vb:?}"
                    );
                    let diff = a
                        .data()
                        .iter()
                        .zip(b.data())
                        .map(|(p, q)| (p - q).abs())
                        .fold(0.0f32, f32::max);
                    assert!(diff < 0.01 / 255.0, "{w}x{h} seed {seed}: {diff}");
                }
            }
        }
    }
}
