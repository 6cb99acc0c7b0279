//! Training the anchored variant's correction for realism: the MHB-Unet with the reference's
//! light field, as in the paper, but judged by a discriminator against real underwater photos
//! instead of by a paired target it could copy (`config.adversarial`, [`AdversarialConfig`];
//! what it measured: `docs/RESULTS.md`, "The correction trained for realism").
//!
//! The data are pairs whose underwater side is a real photo: with a paired set they are the
//! real pairs; with `tools/realism_pairs.py`, clean photos beside references of other scenes.
//! Each sample's light field and water come from that photo, as a render reads its reference.
//! The anchored generator starts at zero output, so a run starts exactly at the uncorrected
//! render (the anchor through the depth stage) and moves from it only as far as the
//! discriminator pays for against the content term.
//!
//! Each step (the GAN baseline's alternation, `uwnr_gan_train`):
//! 1. render the batch, `out = clamp(finish(G(x), anchor), 0, 1)`, and the same without
//!    correction, `plain = clamp(finish(0, anchor), 0, 1)`;
//! 2. `d_loss = L_D(D(pool(real)), D(pool(out)))` with `out` detached, gradients of the
//!    discriminator only, an update;
//! 3. `g = weight · L_G(D(pool(out))) + content · L1(out, plain) + paired terms`, with the
//!    updated discriminator, gradients of the generator only, an update.
//!
//! With `stages` ([`RenderStages`]), the discriminator sees `out` (in step 2 and 3) through the
//! water's effects and the camera a dataset's render goes through, straight-through:
//! `seen = out + detach(stages(out) - out)`, so the generator's gradient passes them unchanged.
//!
//! `pool` is an average over `downsample x downsample` blocks. `metrics.csv` holds `d_loss,
//! adversarial, content, paired, total`, the total being the generator's objective.

use burn::module::Module;
use burn::optim::{GradientsParams, ModuleOptimizer};
use burn::tensor::module::adaptive_avg_pool2d;
use burn::tensor::{Device, Tensor, TensorData};
use uwnr_gan_train::Discriminator;

use crate::augment::{TARGET_CHANNELS, WATER_VALUES};
use crate::burn_style::finish_tensor;
use crate::config::{AdversarialConfig, RenderStages};
use crate::error::{Result, TrainError};
use crate::generator::Generator;
use crate::loader::Batch;
use crate::losses::{Criterion, l1};

/// `metrics.csv` columns of an adversarial run and their legend names.
pub const ADVERSARIAL_TERMS: [(&str, &str); 5] = [
    ("d_loss", "discriminator"),
    ("adversarial", "generator (adversarial)"),
    ("content", "content (L1 to the uncorrected render)"),
    ("paired", "paired terms (weighted)"),
    ("total", "generator total"),
];

/// The generator and its discriminator as one module, so the run checkpoints and resumes both
/// (one optimiser, keyed by parameter ids, serves both, as in `uwnr_gan_train::Gan`).
#[derive(Module, Debug)]
pub struct Critic {
    /// The MHB-Unet whose correction is trained.
    pub generator: Generator,
    /// The PatchGAN discriminator on pooled images.
    pub discriminator: Discriminator,
}

/// A batch on the device: the network input, the real photos, the anchor, depth, veil, beta.
struct BatchTensors {
    x: Tensor<4>,
    real: Tensor<4>,
    anchor: Tensor<4>,
    depth: Tensor<4>,
    veil: Tensor<4>,
    beta: Tensor<4>,
}

impl BatchTensors {
    fn new(batch: &Batch, device: &Device) -> Result<Self> {
        let (b, c) = (batch.size, batch.crop);
        if batch.depth.is_empty() {
            return Err(TrainError::InvalidConfig {
                field: "adversarial",
                reason: "the batch has no anchor (not the anchored variant)".into(),
            });
        }
        let cin = batch.input.len() / (b * c * c).max(1);
        let t4 = |v: &[f32], ch: usize| {
            Tensor::<4>::from_data(TensorData::new(v.to_vec(), [b, ch, c, c]), device)
        };
        let x = t4(&batch.input, cin);
        // The anchored variant's input planes 6..9 are the anchor.
        let anchor = x.clone().slice([0..b, 6..9, 0..c, 0..c]);
        let water = Tensor::<2>::from_data(
            TensorData::new(batch.water.clone(), [b, WATER_VALUES]),
            device,
        );
        Ok(Self {
            x,
            real: t4(&batch.target, TARGET_CHANNELS),
            anchor,
            depth: t4(&batch.depth, 1),
            veil: water.clone().slice([0..b, 0..3]).reshape([b, 3, 1, 1]),
            beta: water.slice([0..b, 3..6]).reshape([b, 3, 1, 1]),
        })
    }
}

/// The mean over `k x k` blocks (`k` divides the sides).
fn pool(x: Tensor<4>, k: usize) -> Tensor<4> {
    if k <= 1 {
        return x;
    }
    let [_, _, h, w] = x.dims();
    adaptive_avg_pool2d(x, [h / k, w / k])
}

/// `out` ([b, 3, c, c]) through `stages`, straight-through (module doc): the values are the
/// stages' output, the gradient is the identity. Sample `i` draws its particles and noise from
/// `mix(seed + i)`; its depth and veil are the batch's.
pub fn through_stages(
    out: Tensor<4>,
    batch: &Batch,
    stages: &RenderStages,
    seed: u64,
    device: &Device,
) -> Result<Tensor<4>> {
    let [b, ch, h, w] = out.dims();
    let n = h * w;
    let failed = |what: &str, e: String| {
        TrainError::Model(uwnr_model::ModelError::Backend(format!(
            "the render stages ({what}): {e}"
        )))
    };
    if ch != 3 || batch.depth.len() != b * n || batch.water.len() != b * WATER_VALUES {
        return Err(failed(
            "shapes",
            format!("renders {b}x{ch}x{h}x{w} against the batch's depth and water"),
        ));
    }
    let values = out
        .clone()
        .detach()
        .into_data()
        .try_to_vec::<f32>()
        .map_err(|e| failed("reading the renders", format!("{e:?}")))?;
    let frame = stages.frame as f32;
    let mut seen = Vec::with_capacity(values.len());
    for i in 0..b {
        let s = uwnr_core::seed::mix(seed.wrapping_add(i as u64));
        let mut img =
            uwnr_core::Image::from_planar(w, h, 3, values[i * 3 * n..(i + 1) * 3 * n].to_vec())
                .map_err(|e| failed("a render", e.to_string()))?;
        let depth =
            uwnr_core::Image::from_planar(w, h, 1, batch.depth[i * n..(i + 1) * n].to_vec())
                .map_err(|e| failed("a depth map", e.to_string()))?;
        let water = &batch.water[i * WATER_VALUES..];
        let veil = [water[0], water[1], water[2]];
        stages
            .effects
            .apply_in_frame(&mut img, &depth, veil, s, frame)
            .map_err(|e| failed("effects", e.to_string()))?;
        let img = stages
            .camera
            .apply_in_frame(&img, uwnr_render::Camera::seed(s), frame)
            .map_err(|e| failed("camera", e.to_string()))?;
        seen.extend_from_slice(img.data());
    }
    let staged = Tensor::<4>::from_data(TensorData::new(seen, [b, 3, h, w]), device);
    Ok(out.clone() + (staged - out.detach()))
}

/// One adversarial step (module doc): a discriminator update, then a generator update, at the
/// learning rate `lr`; `seed` draws the stages' particles and noise.
/// Returns the module and `[d_loss, adversarial, content, paired, total]`.
pub fn adversarial_step(
    model: Critic,
    optim: &mut ModuleOptimizer,
    criterion: &Criterion,
    adv: &AdversarialConfig,
    batch: &Batch,
    (lr, seed): (f64, u64),
    device: &Device,
) -> Result<(Critic, [f64; 5])> {
    let t = BatchTensors::new(batch, device)?;
    let raw = model.generator.forward(t.x); // [b, 6, c, c]
    let plain = finish_tensor(
        raw.zeros_like(),
        t.anchor.clone(),
        t.depth.clone(),
        t.veil.clone(),
        t.beta.clone(),
    )
    .clamp(0.0, 1.0)
    .detach();
    // Clamped as a render is: values outside [0, 1] give the discriminator nothing to see and
    // the generator no gradient to push them further (unclamped, a run diverged at step 114).
    let out = finish_tensor(raw, t.anchor, t.depth, t.veil, t.beta).clamp(0.0, 1.0); // [b, 3, c, c]
    let k = adv.downsample;
    let seen = match &adv.stages {
        Some(st) => through_stages(out.clone(), batch, st, seed, device)?,
        None => out.clone(),
    };

    let real_logits = model.discriminator.forward(pool(t.real.clone(), k));
    let fake_logits = model.discriminator.forward(pool(seen.clone().detach(), k));
    let d_loss = adv.loss.discriminator(real_logits, fake_logits);
    let mut grads = d_loss.backward();
    let d_grads = GradientsParams::from_module(&mut grads, &model.discriminator);
    let model = optim.step(lr, model, d_grads);

    let g_adv = adv
        .loss
        .generator(model.discriminator.forward(pool(seen, k)));
    let content = l1(out.clone(), plain);
    let paired = criterion.forward(out, t.real).total;
    let total = g_adv.clone() * adv.weight + content.clone() * adv.content + paired.clone();
    let mut grads = total.backward();
    let g_grads = GradientsParams::from_module(&mut grads, &model.generator);
    let model = optim.step(lr, model, g_grads);
    // One read back of the five terms, in the columns' order.
    let v = Tensor::cat(
        vec![
            d_loss.detach(),
            g_adv.detach(),
            content.detach(),
            paired.detach(),
            total.detach(),
        ],
        0,
    )
    .into_data()
    .try_to_vec::<f32>()
    .map_err(|e| {
        TrainError::Model(uwnr_model::ModelError::Backend(format!(
            "reading the loss values: {e:?}"
        )))
    })?;
    let g = |i: usize| v.get(i).copied().map_or(f64::NAN, f64::from);
    Ok((model, [g(0), g(1), g(2), g(3), g(4)]))
}
