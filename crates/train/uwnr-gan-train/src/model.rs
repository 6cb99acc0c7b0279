//! The networks of the GAN baseline: a small parameter generator and a PatchGAN discriminator.
//!
//! **Generator** (ours, in the manner of WaterGAN/UWGAN, whose generators are the physical
//! stages themselves with global learnt parameters, see [`crate::imaging`]): the clean image
//! and its depth are area-averaged to `encoder_size²` (so the prediction does not depend on
//! the resolution rendered), encoded by stride-2 conv3x3 + LeakyReLU(0.2) layers and pooled
//! globally; the feature is concatenated with the water code `z` (uniform in [−1, 1]^z_dim, as
//! both papers draw it) and mapped by a hidden layer and a linear head to the
//! [`RAW_PARAMS`] raw values of [`WaterParams::from_raw`], which the imaging layer renders at
//! full resolution. The head's bias starts at the parameters' initial values
//! ([`crate::imaging::initial_raw`]), its weights at N(0, 0.02), so an untrained generator
//! renders UWGAN's initial water.
//!
//! **Discriminator**: pix2pix's `NLayerDiscriminator` (Isola et al. 2017; the 70x70 PatchGAN
//! for 3 layers): conv4x4 stride 2 `3 → w` + LeakyReLU(0.2); `layers − 1` conv4x4 stride 2
//! doubling the width (at most 8w) + InstanceNorm + LeakyReLU; one conv4x4 stride 1 + norm +
//! LeakyReLU; a conv4x4 stride 1 to one logit per patch. All with padding 1 and bias; weights
//! N(0, 0.02). pix2pix uses BatchNorm by default and CycleGAN InstanceNorm; we take the
//! instance norm (no running statistics to carry through checkpoints). UWGAN and WaterGAN use
//! a DCGAN discriminator with one logit per image instead.

use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{
    Initializer, InstanceNorm, InstanceNormConfig, Linear, LinearConfig, PaddingConfig2d,
};
use burn::tensor::activation::leaky_relu;
use burn::tensor::module::adaptive_avg_pool2d;
use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use uwnr_gan::config::{
    ENCODER_IN, GeneratorConfig, INIT_STD, LEAKY_SLOPE, PAPER_Z_DIM, draw_z, initial_raw,
};
use uwnr_gan::config::{RAW_PARAMS, RGB};

use crate::error::{GanError, Result};
use crate::imaging::{WaterParams, render};

/// Builds burn's generator from its config (the config lives in the render wing, `uwnr-gan`,
/// which renders without burn).
pub trait GeneratorInit {
    /// Builds the generator (weights N(0, 0.02), biases zero, the head's bias at the initial
    /// parameters).
    fn init(&self, device: &Device) -> Result<Generator>;
}

impl GeneratorInit for GeneratorConfig {
    fn init(&self, device: &Device) -> Result<Generator> {
        self.validate()?;
        let mut encoder = Vec::with_capacity(self.widths.len());
        let mut cin = ENCODER_IN;
        for &c in &self.widths {
            encoder.push(
                Conv2dConfig::new([cin, c], [3, 3])
                    .with_stride([2, 2])
                    .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                    .with_initializer(normal_init())
                    .init(device),
            );
            cin = c;
        }
        let hidden = LinearConfig::new(cin + self.z_dim, self.hidden)
            .with_initializer(normal_init())
            .init(device);
        let mut head = LinearConfig::new(self.hidden, RAW_PARAMS)
            .with_initializer(normal_init())
            .init(device);
        let bias = Tensor::<1>::from_data(
            TensorData::new(initial_raw().to_vec(), [RAW_PARAMS]),
            device,
        );
        head.bias = Some(Param::from_tensor(bias));
        Ok(Generator {
            encoder,
            hidden,
            head,
            config: self.clone(),
        })
    }
}

/// Kernel of the discriminator's convolutions (pix2pix `kw = 4`).
pub const DISC_KERNEL: usize = 4;
/// Widest discriminator layer, in multiples of its base width (pix2pix `min(2**n, 8)`).
pub const DISC_MAX_MULT: usize = 8;
/// The PatchGAN discriminator's architecture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DiscriminatorConfig {
    /// Channels of the first layer (pix2pix `ndf`, 64).
    pub width: usize,
    /// Stride-2 layers (pix2pix `n_layers`, 3: the 70x70 PatchGAN).
    pub layers: usize,
}

impl Default for DiscriminatorConfig {
    fn default() -> Self {
        Self {
            width: 64,
            layers: 3,
        }
    }
}

impl DiscriminatorConfig {
    /// Checks the config can build a network.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.layers == 0 {
            return Err(GanError::InvalidConfig {
                field: "discriminator",
                reason: format!(
                    "width {} and layers {} must be at least 1",
                    self.width, self.layers
                ),
            });
        }
        Ok(())
    }

    /// Channels of every conv, in order (the last is the 1-channel output).
    fn channels(&self) -> Vec<(usize, usize)> {
        let w = self.width;
        let mult = |n: usize| (1_usize << n.min(usize::BITS as usize - 1)).min(DISC_MAX_MULT);
        let mut out = vec![(RGB, w)];
        for n in 1..=self.layers {
            out.push((w * mult(n - 1), w * mult(n)));
        }
        out.push((w * mult(self.layers), 1));
        out
    }

    /// Number of parameters: `16·c_in·c_out + c_out` per conv (2,764,737 for the default, the
    /// pix2pix 70x70 PatchGAN without its norms' affine parameters).
    #[must_use]
    pub fn param_count(&self) -> usize {
        let k = DISC_KERNEL * DISC_KERNEL;
        self.channels().iter().map(|(i, o)| k * i * o + o).sum()
    }

    /// Smallest input side that leaves at least one patch: `3 · 2^layers`.
    #[must_use]
    pub fn min_input(&self) -> usize {
        3 << self.layers
    }

    /// Builds the discriminator (weights N(0, 0.02), biases zero).
    pub fn init(&self, device: &Device) -> Result<Discriminator> {
        self.validate()?;
        let chans = self.channels();
        let last = chans.len() - 1;
        let convs = chans
            .iter()
            .enumerate()
            .map(|(i, &(cin, cout))| {
                // The first `layers` convs halve the size, the last two keep it (less one).
                let stride = if i < self.layers { 2 } else { 1 };
                Conv2dConfig::new([cin, cout], [DISC_KERNEL, DISC_KERNEL])
                    .with_stride([stride, stride])
                    .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                    .with_initializer(normal_init())
                    .init(device)
            })
            .collect::<Vec<_>>();
        // Norms after every conv but the first and the output.
        let norms = chans[1..last]
            .iter()
            .map(|&(_, c)| InstanceNormConfig::new(c).with_affine(false).init(device))
            .collect();
        Ok(Discriminator { convs, norms })
    }
}

/// N(0, 0.02).
fn normal_init() -> Initializer {
    Initializer::Normal {
        mean: 0.0,
        std: INIT_STD,
    }
}

/// Both networks of the baseline.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GanConfig {
    /// The parameter generator.
    pub generator: GeneratorConfig,
    /// The PatchGAN discriminator.
    pub discriminator: DiscriminatorConfig,
}

impl GanConfig {
    /// Checks both networks' configs.
    pub fn validate(&self) -> Result<()> {
        self.generator.validate()?;
        self.discriminator.validate()
    }

    /// Builds both networks.
    pub fn init(&self, device: &Device) -> Result<Gan> {
        Ok(Gan {
            generator: self.generator.init(device)?,
            discriminator: self.discriminator.init(device)?,
        })
    }
}

/// The parameter generator with its imaging layer.
#[derive(Module, Debug)]
pub struct Generator {
    /// Stride-2 conv3x3 layers over `[clean, depth]`.
    pub encoder: Vec<Conv2d>,
    /// `c_last + z_dim → hidden`.
    pub hidden: Linear,
    /// `hidden → RAW_PARAMS`.
    pub head: Linear,
    /// The architecture (and the imaging settings the render uses).
    #[module(skip)]
    pub config: GeneratorConfig,
}

impl Generator {
    /// Predicts the image-formation parameters of each image.
    ///
    /// # Shapes
    /// - `clean`: `[b, 3, h, w]` in [0, 1]; `depth`: `[b, 1, h, w]` in [0, 1]; `z`: `[b, z_dim]`
    /// - output: [`WaterParams`] with `b` rows
    pub fn params(&self, clean: Tensor<4>, depth: Tensor<4>, z: Tensor<2>) -> WaterParams {
        let s = self.config.encoder_size;
        let x = Tensor::cat(vec![clean, depth], 1); // [b, 4, h, w]
        let mut x = adaptive_avg_pool2d(x, [s, s]); // [b, 4, s, s]
        for conv in &self.encoder {
            x = leaky_relu(conv.forward(x), LEAKY_SLOPE); // [b, c, s/2, s/2] per layer
        }
        let [b, c, _, _] = x.dims();
        let feature = adaptive_avg_pool2d(x, [1, 1]).reshape([b, c]); // [b, c]
        let h = Tensor::cat(vec![feature, z], 1); // [b, c + z_dim]
        let h = leaky_relu(self.hidden.forward(h), LEAKY_SLOPE); // [b, hidden]
        WaterParams::from_raw(self.head.forward(h)) // [b, RAW_PARAMS] mapped
    }

    /// Predicts the parameters and renders the underwater images.
    ///
    /// # Shapes
    /// - `clean`: `[b, 3, h, w]` in [0, 1]; `depth`: `[b, 1, h, w]` in [0, 1] (larger = farther);
    ///   `z`: `[b, z_dim]`
    /// - output: the render `[b, 3, h, w]` in [0, 1] and its parameters
    pub fn forward(
        &self,
        clean: Tensor<4>,
        depth: Tensor<4>,
        z: Tensor<2>,
    ) -> Result<(Tensor<4>, WaterParams)> {
        let [b, _, _, _] = clean.dims();
        let zd = z.dims();
        if zd != [b, self.config.z_dim] {
            return Err(GanError::ShapeMismatch {
                what: "water code z",
                expected: vec![b, self.config.z_dim],
                got: zd.to_vec(),
            });
        }
        let params = self.params(clean.clone(), depth.clone(), z);
        let out = render(clean, depth, &params, &self.config.imaging)?;
        Ok((out, params))
    }
}

/// The PatchGAN discriminator.
#[derive(Module, Debug)]
pub struct Discriminator {
    /// The convolutions, the last giving one logit per patch.
    pub convs: Vec<Conv2d>,
    /// Instance norms after every conv but the first and the last.
    pub norms: Vec<InstanceNorm>,
}

impl Discriminator {
    /// One real/fake logit per patch.
    ///
    /// # Shapes
    /// - `image`: `[b, 3, h, w]`, each side at least [`DiscriminatorConfig::min_input`];
    ///   output `[b, 1, h', w']` (`h' = h / 2^layers − 2` for sides divisible by `2^layers`)
    pub fn forward(&self, image: Tensor<4>) -> Tensor<4> {
        let last = self.convs.len() - 1;
        let mut x = image;
        for (i, conv) in self.convs.iter().enumerate() {
            x = conv.forward(x);
            if i == last {
                break;
            }
            if let Some(norm) = i.checked_sub(1).and_then(|n| self.norms.get(n)) {
                x = norm.forward(x);
            }
            x = leaky_relu(x, LEAKY_SLOPE);
        }
        x // [b, 1, h', w']
    }
}

/// The generator and the discriminator as one module, so the run framework checkpoints and
/// resumes both (and one optimiser, keyed by parameter ids, serves both).
#[derive(Module, Debug)]
pub struct Gan {
    /// The parameter generator.
    pub generator: Generator,
    /// The PatchGAN discriminator.
    pub discriminator: Discriminator,
}

/// Water codes `z` for a batch of `b` images, uniform in [−1, 1] (as WaterGAN and UWGAN draw
/// them), from a ChaCha8 generator seeded with `seed`: the same seed gives the same codes.
///
/// # Shapes
/// - output `[b, z_dim]`
#[must_use]
pub fn sample_z(seed: u64, b: usize, z_dim: usize, device: &Device) -> Tensor<2> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let v = draw_z(&mut rng, b * z_dim);
    Tensor::<2>::from_data(TensorData::new(v, [b, z_dim]), device)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::to_vec;
    use burn::tensor::Distribution;

    fn small() -> GanConfig {
        GanConfig {
            generator: GeneratorConfig {
                z_dim: 8,
                widths: vec![8, 16],
                hidden: 16,
                encoder_size: 16,
                imaging: uwnr_gan::ImagingConfig::default(),
            },
            discriminator: DiscriminatorConfig {
                width: 8,
                layers: 3,
            },
        }
    }

    #[test]
    fn parameter_counts_match_the_formulas_and_the_built_networks() {
        let d = Device::flex();
        let cfg = GanConfig::default();
        assert_eq!(cfg.generator.param_count(), 35_003);
        assert_eq!(cfg.discriminator.param_count(), 2_764_737);
        let gan = cfg.init(&d).unwrap();
        assert_eq!(gan.generator.num_params(), cfg.generator.param_count());
        assert_eq!(
            gan.discriminator.num_params(),
            cfg.discriminator.param_count()
        );
        let s = small();
        let gan = s.init(&d).unwrap();
        assert_eq!(gan.generator.num_params(), s.generator.param_count());
        assert_eq!(
            gan.discriminator.num_params(),
            s.discriminator.param_count()
        );
    }

    #[test]
    fn shapes_of_both_networks() {
        let d = Device::flex();
        let gan = small().init(&d).unwrap();
        let clean = Tensor::<4>::random([2, 3, 32, 40], Distribution::Uniform(0.0, 1.0), &d);
        let depth = Tensor::<4>::random([2, 1, 32, 40], Distribution::Uniform(0.0, 1.0), &d);
        let z = sample_z(1, 2, 8, &d);
        let (out, p) = gan.generator.forward(clean, depth, z).unwrap();
        assert_eq!(out.dims(), [2, 3, 32, 40]);
        assert_eq!(p.beta.dims(), [2, 3]);
        let logits = gan.discriminator.forward(out);
        assert_eq!(logits.dims(), [2, 1, 2, 3]);
        assert_eq!(small().discriminator.min_input(), 24);
        let tiny = gan.discriminator.forward(Tensor::zeros([1, 3, 24, 24], &d));
        assert_eq!(tiny.dims(), [1, 1, 1, 1]);
    }

    #[test]
    fn an_untrained_generator_renders_uwgans_initial_water() {
        let d = Device::flex();
        let g = small().generator.init(&d).unwrap();
        let clean = Tensor::<4>::ones([1, 3, 16, 16], &d) * 0.5;
        let depth = Tensor::<4>::ones([1, 1, 16, 16], &d) * 0.5;
        let p = g.params(clean, depth, sample_z(3, 1, 8, &d));
        let beta = to_vec(p.beta).unwrap();
        // Small N(0, 0.02) weights: within a few percent of the initial values.
        for (b, want) in beta.iter().zip(crate::imaging::UWGAN_BETA_INIT) {
            assert!((b - want).abs() < 0.05, "beta {b} vs {want}");
        }
    }

    #[test]
    fn a_seed_gives_the_same_codes_and_render() {
        let d = Device::flex();
        assert_eq!(
            to_vec(sample_z(5, 2, 8, &d)).unwrap(),
            to_vec(sample_z(5, 2, 8, &d)).unwrap()
        );
        assert_ne!(
            to_vec(sample_z(5, 2, 8, &d)).unwrap(),
            to_vec(sample_z(6, 2, 8, &d)).unwrap()
        );
        let z = to_vec(sample_z(5, 4, 8, &d)).unwrap();
        assert!(z.iter().all(|v| (-1.0..=1.0).contains(v)));
    }

    #[test]
    fn invalid_configs_name_their_field() {
        let mut g = GeneratorConfig::default();
        g.widths.clear();
        assert!(matches!(
            g.validate(),
            Err(uwnr_gan::GanError::InvalidConfig {
                field: "generator.widths",
                ..
            })
        ));
        let g = GeneratorConfig {
            encoder_size: 4,
            ..GeneratorConfig::default()
        };
        assert!(matches!(
            g.validate(),
            Err(uwnr_gan::GanError::InvalidConfig {
                field: "generator.encoder_size",
                ..
            })
        ));
        let dc = DiscriminatorConfig {
            width: 0,
            layers: 3,
        };
        assert!(dc.validate().is_err());
        let json = r#"{"generator": {"z_dim": 4}, "discriminator": {"width": 8}}"#;
        let c: GanConfig = serde_json::from_str(json).unwrap();
        assert_eq!(
            (
                c.generator.z_dim,
                c.generator.hidden,
                c.discriminator.layers
            ),
            (4, 64, 3)
        );
        assert!(serde_json::from_str::<GanConfig>(r#"{"generatr": {}}"#).is_err());
    }
}
