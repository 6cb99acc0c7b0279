//! Rendering a clean image with a trained generator: the water code `z` comes from `seed`, so a
//! given (weights, image, depth, seed) always gives the same render.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use uwnr_core::Image;

use crate::config::draw_z;
use crate::error::Result;
use crate::generator::Generator;
use crate::imaging::WaterValues;

/// The water code of `seed`: `z_dim` values uniform in [−1, 1] from a ChaCha8 generator seeded
/// with it (the first row of the training wing's `sample_z` for the same seed).
#[must_use]
pub fn water_code(seed: u64, z_dim: usize) -> Vec<f32> {
    draw_z(&mut ChaCha8Rng::seed_from_u64(seed), z_dim)
}

/// Renders `clean` (RGB in [0, 1]) with its `depth` (1 channel, [0, 1], larger = farther, the
/// same size) under the water the generator predicts for code `seed`.
pub fn render(generator: &Generator, clean: &Image, depth: &Image, seed: u64) -> Result<Image> {
    Ok(render_with_values(generator, clean, depth, seed)?.0)
}

/// [`render`], also returning the parameters used.
pub fn render_with_values(
    generator: &Generator,
    clean: &Image,
    depth: &Image,
    seed: u64,
) -> Result<(Image, WaterValues)> {
    generator.forward(clean, depth, &water_code(seed, generator.config.z_dim))
}
