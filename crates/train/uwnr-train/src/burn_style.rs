//! The render's tensor operations that training differentiates through, on burn tensors: the
//! normalised Gaussian blur and the finish of the anchored variant (`N = A (1 + G) + O`, then
//! the depth response towards the veil). Their per-image forms, which rendering uses, are in
//! `uwnr_model::style`; the tests compare the two.

use burn::tensor::module::conv2d;
use burn::tensor::ops::ConvOptions;
use burn::tensor::{Tensor, TensorData};
use uwnr_model::blur::{blur_radius, gaussian_kernel, inside_mass};
use uwnr_model::style::{LOCAL_DEPTH_STRENGTH, MAX_GAIN, SMOOTH_SIGMA};

/// Gaussian blur of every channel, separable, with the kernel truncated at
/// `uwnr_model::style::BLUR_TRUNCATE_SIGMAS` sigmas (and at the image size) and renormalised over the part
/// inside the image at the borders (normalised convolution): a constant image stays constant.
///
/// # Shapes
/// - `x`: `[b, c, h, w]`; output: `[b, c, h, w]`
pub fn gaussian_blur(x: Tensor<4>, sigma: f64) -> Tensor<4> {
    let [_, c, h, w] = x.dims();
    let device = x.device();
    let (rx, ry) = (blur_radius(sigma, w), blur_radius(sigma, h));
    let (kx, ky) = (gaussian_kernel(sigma, rx), gaussian_kernel(sigma, ry));
    let weight = |k: &[f64], shape: [usize; 4]| {
        let data: Vec<f32> = (0..c).flat_map(|_| k.iter().map(|&v| v as f32)).collect();
        Tensor::<4>::from_data(TensorData::new(data, shape), &device)
    };
    let horiz = conv2d(
        x,
        weight(&kx, [c, 1, 1, kx.len()]),
        None,
        ConvOptions::new([1, 1], [0, rx], [1, 1], c),
    ); // [b, c, h, w]
    let blurred = conv2d(
        horiz,
        weight(&ky, [c, 1, ky.len(), 1]),
        None,
        ConvOptions::new([1, 1], [ry, 0], [1, 1], c),
    ); // [b, c, h, w]
    let (mx, my) = (inside_mass(&kx, w), inside_mass(&ky, h));
    let norm: Vec<f32> = my
        .iter()
        .flat_map(|&a| mx.iter().map(move |&b| (a * b) as f32))
        .collect();
    blurred / Tensor::<4>::from_data(TensorData::new(norm, [1, 1, h, w]), &device)
}

/// `uwnr_model::finish::finish` on a batch, differentiable (training), with each sample's reference at the
/// sample's own mean depth: in self-reconstruction the reference is the target, the same scene,
/// so only the within-image part of the depth response acts.
///
/// # Shapes
/// - `raw`: `[b, 6, h, w]`; `anchor`: `[b, 3, h, w]`; `depth`: `[b, 1, h, w]`;
///   `veil`, `beta`: `[b, 3, 1, 1]`; output `[b, 3, h, w]`, not clamped (the loss sees the
///   unclamped values so that gradients flow everywhere)
pub fn finish_tensor(
    raw: Tensor<4>,
    anchor: Tensor<4>,
    depth: Tensor<4>,
    veil: Tensor<4>,
    beta: Tensor<4>,
) -> Tensor<4> {
    let [b, _, h, w] = raw.dims();
    let fields = gaussian_blur(raw, SMOOTH_SIGMA);
    let g = fields.clone().slice([0..b, 0..3, 0..h, 0..w]);
    let o = fields.slice([0..b, 3..6, 0..h, 0..w]);
    let n = anchor * (g + 1.0) + o;
    let m = depth.clone().mean_dim(3).mean_dim(2); // [b, 1, 1, 1]
    let factor = (beta.neg() * ((depth - m) * LOCAL_DEPTH_STRENGTH))
        .exp()
        .clamp_max(MAX_GAIN); // [b, 3, h, w]
    (n - veil.clone()) * factor + veil
}
