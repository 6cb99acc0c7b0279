//! burn's generator as an implementation of `uwnr_model`'s forward pass, so that it renders
//! through the same padding and tiling code as the engine: validation renders of the network
//! being trained, and the parity checks between the two.

use burn::tensor::{Device, Tensor, TensorData};
use uwnr_core::Image;
use uwnr_engine::Planar;
use uwnr_model::config::LEVELS;
use uwnr_model::infer::render_with;
use uwnr_model::{
    Backend, Forward, GeneratorConfig, Implementation, ModelError, Network, ReferenceStyle,
    RenderOptions, Result, Variant,
};

use crate::burn_weights::{generator_to_tensors, read_tensor};
use crate::generator::Generator;

/// burn's generator on a device.
#[derive(Clone, Debug)]
pub struct BurnForward {
    /// The module.
    pub generator: Generator,
    /// Where it runs.
    pub device: Device,
}

impl BurnForward {
    fn tensor(&self, x: Planar) -> Tensor<4> {
        Tensor::from_data(
            TensorData::new(x.data, [1, x.channels, x.height, x.width]),
            &self.device,
        )
    }

    fn means(&self, means: &[Vec<f32>]) -> Vec<Tensor<4>> {
        means
            .iter()
            .map(|m| {
                Tensor::from_data(TensorData::new(m.clone(), [1, m.len(), 1, 1]), &self.device)
            })
            .collect()
    }
}

fn planar(t: Tensor<4>) -> Result<Planar> {
    let t = read_tensor(t)?;
    match t.shape[..] {
        [1, channels, height, width] => Ok(Planar {
            channels,
            height,
            width,
            data: t.data,
        }),
        _ => Err(ModelError::Backend(format!(
            "expected a [1, c, h, w] tensor, got {:?}",
            t.shape
        ))),
    }
}

impl Forward for BurnForward {
    fn channels(&self) -> (usize, usize) {
        let [_, cin, _, _] = self.generator.in_conv_down1.conv.weight.dims();
        let [cout, _, _, _] = self.generator.out.weight.dims();
        (cin, cout)
    }

    fn forward(&self, x: Planar) -> Result<Planar> {
        planar(self.generator.forward(self.tensor(x)))
    }

    fn forward_with_means(&self, x: Planar, means: &[Vec<f32>]) -> Result<Planar> {
        let means: [Tensor<4>; LEVELS] = self
            .means(means)
            .try_into()
            .map_err(|_| ModelError::InvalidOptions("channel means incomplete".into()))?;
        planar(
            self.generator
                .forward_with_channel_means(self.tensor(x), &means),
        )
    }

    fn attention_input(&self, x: Planar, known: &[Vec<f32>]) -> Result<Planar> {
        planar(
            self.generator
                .channel_attention_input(self.tensor(x), &self.means(known))?,
        )
    }
}

impl Implementation for BurnForward {
    fn name(&self) -> String {
        format!("{:?}", self.device)
    }

    fn clone_box(&self) -> Box<dyn Implementation> {
        Box::new(self.clone())
    }
}

/// Where a network built from burn's module runs: on burn itself, or on the engine with the
/// module's weights.
#[derive(Clone, Debug)]
pub enum RenderOn {
    /// burn's module on this device.
    Burn(Device),
    /// `uwnr-engine` (f32 or bf16 products) with the module's weights.
    Engine(Backend),
}

/// The network of a burn module (e.g. the one being trained) for rendering.
pub fn network_from_generator(
    generator: &Generator,
    config: &GeneratorConfig,
    on: &RenderOn,
) -> Result<Network> {
    match on {
        RenderOn::Burn(device) => Ok(Network::from_implementation(
            config,
            Box::new(BurnForward {
                generator: generator.clone(),
                device: device.clone(),
            }),
        )),
        RenderOn::Engine(backend) => {
            let tensors = generator_to_tensors(generator, config)?;
            Ok(Network::from_tensors(config, tensors, backend)?.0)
        }
    }
}

/// Renders `clean` (3 channels) as an underwater image in the style of `light_field` (3
/// channels, the light-field map of a real underwater image), using `depth` (1 channel), with a
/// generator of the paper's variant on burn. All three must have the same size; the output has
/// it too, with values in [0, 1].
pub fn render(
    generator: &Generator,
    clean: &Image,
    depth: &Image,
    light_field: &Image,
    opts: &RenderOptions,
    device: &Device,
) -> Result<Image> {
    if light_field.size() != clean.size() {
        return Err(ModelError::ImageSize {
            what: "light-field map",
            expected: clean.size(),
            got: light_field.size(),
        });
    }
    render_with(
        &BurnForward {
            generator: generator.clone(),
            device: device.clone(),
        },
        Variant::Paper,
        clean,
        depth,
        &ReferenceStyle::from_light_field(light_field.clone()),
        opts,
    )
}
