//! Each loss against values computed by hand or by a plain f64 reference written here.

use std::collections::HashMap;
use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use safetensors::tensor::{Dtype, TensorView};
use uwnr_train::TrainError;
use uwnr_train::config::LightFieldLoss;
use uwnr_train::losses::{
    LF_LOG_FLOOR, LF_POOL, LF_RELEASED_SCALE, LF_SIGMAS, LF_TRUNCATE_SIGMAS, SSIM_C1, dark_channel,
    dark_channel_loss, gaussian_blur, l1, light_field_loss, light_field_map, ssim, ssim_loss,
};
use uwnr_train::vgg::{VGG19_CONVS, Vgg19Features};

fn t4(data: Vec<f32>, shape: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(data, shape), device)
}

fn scalar(t: Tensor<1>) -> f64 {
    f64::from(t.into_scalar::<f32>())
}

fn values(t: Tensor<4>) -> Vec<f32> {
    t.into_data().try_to_vec::<f32>().unwrap()
}

fn random(n: usize, seed: u64) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| rng.random::<f32>()).collect()
}

#[test]
fn l1_is_the_mean_absolute_difference() {
    let d = Device::flex();
    let a = t4(vec![0.0, 1.0, 2.0, 3.0], [1, 1, 2, 2], &d);
    let b = t4(vec![1.0; 4], [1, 1, 2, 2], &d);
    // (1 + 0 + 1 + 2) / 4
    assert!((scalar(l1(a, b)) - 1.0).abs() < 1e-7);
}

#[test]
fn dark_channel_is_min_over_g_b_then_a_clipped_window() {
    let d = Device::flex();
    // G and B planes (x10); R is 0 everywhere and must be ignored.
    let g = [5., 4., 9., 9., 9., 9., 9., 9., 9., 9., 9., 1.];
    let mut b = [8.0_f32; 12];
    b[5] = 2.0;
    let mut data = vec![0.0_f32; 12];
    data.extend(g.iter().map(|v| v / 10.0));
    data.extend(b.iter().map(|v| v / 10.0));
    let x = t4(data, [1, 3, 3, 4], &d);
    // min(G, B) = [[5,4,8,8],[8,2,8,8],[8,8,8,1]]; 3x3 minimum with the window clipped at the
    // borders (worked out by hand):
    let expected = [2., 2., 2., 8., 2., 2., 1., 1., 2., 2., 1., 1.].map(|v: f32| v / 10.0);
    let got = values(dark_channel(x.clone(), 3));
    for (g, e) in got.iter().zip(expected) {
        assert!((g - e).abs() < 1e-7, "{got:?}");
    }
    let zeros = t4(vec![0.0; 36], [1, 3, 3, 4], &d);
    let mean: f32 = expected.iter().sum::<f32>() / 12.0;
    assert!((scalar(dark_channel_loss(x, zeros, 3)) - f64::from(mean)).abs() < 1e-6);
}

#[test]
fn dark_channel_loss_has_gradients() {
    let d = Device::flex().autodiff();
    let x = t4(random(2 * 3 * 20 * 20, 1), [2, 3, 20, 20], &d).require_grad();
    let y = t4(random(2 * 3 * 20 * 20, 2), [2, 3, 20, 20], &d);
    let loss = dark_channel_loss(x.clone(), y, 15);
    let grads = loss.backward();
    let g = x.grad(&grads).unwrap();
    let g: Vec<f32> = g.into_data().try_to_vec().unwrap();
    // Only G and B pixels that are window minima receive gradient; R never does.
    let r_plane = &g[..400];
    assert!(r_plane.iter().all(|&v| v == 0.0));
    assert!(g.iter().any(|&v| v != 0.0));
}

#[test]
fn blur_keeps_constants_and_matches_a_direct_sum() {
    let d = Device::flex();
    let c = t4(vec![0.3; 2 * 9 * 11], [1, 2, 9, 11], &d);
    for v in values(gaussian_blur(c, 4.0)) {
        assert!((v - 0.3).abs() < 1e-6);
    }
    let data = random(9 * 11, 3);
    let got = values(gaussian_blur(t4(data.clone(), [1, 1, 9, 11], &d), 2.0));
    let want = blur_ref(&data, 11, 9, 2.0);
    for (g, w) in got.iter().zip(&want) {
        assert!((f64::from(*g) - w).abs() < 1e-5, "{g} {w}");
    }
}

/// Direct 2-D normalised Gaussian blur of one plane (the reference).
fn blur_ref(p: &[f32], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let r = (LF_TRUNCATE_SIGMAS * sigma).ceil() as i64;
    let (rx, ry) = (r.min(w as i64 - 1), r.min(h as i64 - 1));
    let g = |k: i64| (-((k * k) as f64) / (2.0 * sigma * sigma)).exp();
    let mut out = vec![0.0; w * h];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let (mut s, mut m) = (0.0, 0.0);
            for dy in -ry..=ry {
                for dx in -rx..=rx {
                    let (yy, xx) = (y + dy, x + dx);
                    if yy >= 0 && xx >= 0 && yy < h as i64 && xx < w as i64 {
                        let k = g(dx) * g(dy);
                        s += k * f64::from(p[(yy * w as i64 + xx) as usize]);
                        m += k;
                    }
                }
            }
            out[(y * w as i64 + x) as usize] = s / m;
        }
    }
    out
}

/// The paper's light-field map in plain f64: 3x3 average pooling, normalised Gaussian blurs with
/// the sigmas scaled to the pooled grid, mean, floor, log, min-max over the sample.
fn light_field_ref(x: &[f32], c: usize, h: usize, w: usize) -> Vec<f64> {
    let (ph, pw) = (h / LF_POOL, w / LF_POOL);
    let mut maps = Vec::new();
    for ch in 0..c {
        let plane = &x[ch * h * w..(ch + 1) * h * w];
        let pooled: Vec<f32> = (0..ph * pw)
            .map(|i| {
                let (py, px) = (i / pw, i % pw);
                let mut s = 0.0;
                for dy in 0..LF_POOL {
                    for dx in 0..LF_POOL {
                        s += plane[(py * LF_POOL + dy) * w + px * LF_POOL + dx];
                    }
                }
                s / (LF_POOL * LF_POOL) as f32
            })
            .collect();
        let mut mean = vec![0.0; ph * pw];
        for s in LF_SIGMAS {
            let sigma = s * (1.0 / LF_POOL as f64) / LF_RELEASED_SCALE;
            for (m, b) in mean.iter_mut().zip(blur_ref(&pooled, pw, ph, sigma)) {
                *m += b / LF_SIGMAS.len() as f64;
            }
        }
        maps.extend(mean.into_iter().map(|v| v.max(LF_LOG_FLOOR).ln()));
    }
    let lo = maps.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = maps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    maps.into_iter()
        .map(|v| (v - lo) / (hi - lo + 1e-6))
        .collect()
}

#[test]
fn light_field_map_matches_the_reference() {
    let d = Device::flex();
    let (h, w) = (30, 36);
    let a = random(3 * h * w, 4);
    let mut b: Vec<f32> = random(3 * h * w, 5).iter().map(|v| v * 0.5).collect();
    // Some values at 0: the floor must hold them.
    b[..40].fill(0.0);
    let x = t4([a.clone(), b.clone()].concat(), [2, 3, h, w], &d);
    let got = values(light_field_map(x));
    let want: Vec<f64> = [light_field_ref(&a, 3, h, w), light_field_ref(&b, 3, h, w)].concat();
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert!((f64::from(*g) - w).abs() < 2e-4, "{g} {w}");
    }
    // Each sample spans [0, 1].
    let n = want.len() / 2;
    let max0 = got[..n].iter().copied().fold(0.0, f32::max);
    assert!((max0 - 1.0).abs() < 1e-4);
}

#[test]
fn light_field_loss_variants() {
    let d = Device::flex();
    let (h, w) = (24, 24);
    let a = random(3 * h * w, 6);
    let b = random(3 * h * w, 7);
    let x = t4(a.clone(), [1, 3, h, w], &d);
    let y = t4(b.clone(), [1, 3, h, w], &d);
    // Released: the blur radius is 0, so the term is a plain L1.
    let released = scalar(light_field_loss(
        x.clone(),
        y.clone(),
        LightFieldLoss::Released,
    ));
    let plain: f64 = a
        .iter()
        .zip(&b)
        .map(|(p, q)| f64::from((p - q).abs()))
        .sum::<f64>()
        / a.len() as f64;
    assert!((released - plain).abs() < 1e-6);
    // Paper: L1 between the maps.
    let paper = scalar(light_field_loss(x.clone(), y, LightFieldLoss::Paper));
    let (ma, mb) = (light_field_ref(&a, 3, h, w), light_field_ref(&b, 3, h, w));
    let want: f64 = ma.iter().zip(&mb).map(|(p, q)| (p - q).abs()).sum::<f64>() / ma.len() as f64;
    assert!((paper - want).abs() < 2e-4, "{paper} {want}");
    // The map ignores a brightness change that keeps the log-domain shape: x and 2x agree.
    let doubled = t4(a.iter().map(|v| v * 2.0).collect(), [1, 3, h, w], &d);
    assert!(scalar(light_field_loss(x, doubled, LightFieldLoss::Paper)) < 1e-4);
}

#[test]
fn ssim_by_hand() {
    let d = Device::flex();
    let x = t4(random(2 * 3 * 16 * 16, 8), [2, 3, 16, 16], &d);
    assert!((scalar(ssim(x.clone(), x.clone())) - 1.0).abs() < 1e-5);
    assert!(scalar(ssim_loss(x.clone(), x)).abs() < 1e-5);
    // Two flat images a and b: the variances vanish, SSIM = (2ab + C1) / (a^2 + b^2 + C1).
    let (a, b) = (0.2_f64, 0.6_f64);
    let fa = t4(vec![a as f32; 3 * 16 * 16], [1, 3, 16, 16], &d);
    let fb = t4(vec![b as f32; 3 * 16 * 16], [1, 3, 16, 16], &d);
    let want = (2.0 * a * b + SSIM_C1) / (a * a + b * b + SSIM_C1);
    assert!((scalar(ssim(fa, fb)) - want).abs() < 1e-4);
}

/// A VGG19-shaped safetensors file with small random values, torchvision key names.
fn tiny_vgg(seed: u64, bad_shape: bool, skip: Option<&str>) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut store: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
    for (i, (index, cin, cout)) in VGG19_CONVS.iter().enumerate() {
        let cin = if bad_shape && i == 2 { cin + 1 } else { *cin };
        let n = cout * cin * 9;
        let w: Vec<u8> = (0..n)
            .flat_map(|_| ((rng.random::<f32>() - 0.5) * 0.1).to_le_bytes())
            .collect();
        let b: Vec<u8> = (0..*cout)
            .flat_map(|_| (rng.random::<f32>() * 0.01).to_le_bytes())
            .collect();
        store.push((
            format!("features.{index}.weight"),
            vec![*cout, cin, 3, 3],
            w,
        ));
        store.push((format!("features.{index}.bias"), vec![*cout], b));
    }
    // A key of a later layer, ignored by the loader.
    store.push(("features.14.bias".into(), vec![2], vec![0; 8]));
    let views: HashMap<String, TensorView<'_>> = store
        .iter()
        .filter(|(k, _, _)| Some(k.as_str()) != skip)
        .map(|(k, s, d)| {
            (
                k.clone(),
                TensorView::new(Dtype::F32, s.clone(), d).unwrap(),
            )
        })
        .collect();
    safetensors::serialize(&views, None).unwrap()
}

#[test]
fn vgg19_loader_and_perceptual_loss() {
    let d = Device::flex();
    let bytes = tiny_vgg(9, false, None);
    let vgg = Vgg19Features::from_bytes(&bytes, Path::new("tiny.safetensors"), &d).unwrap();
    let x = t4(random(3 * 12 * 12, 10), [1, 3, 12, 12], &d);
    let cuts = vgg.cuts(x.clone());
    let dims: Vec<[usize; 4]> = cuts.iter().map(|c| c.dims()).collect();
    assert_eq!(
        dims,
        [
            [1, 64, 12, 12],
            [1, 64, 12, 12],
            [1, 64, 6, 6],
            [1, 128, 6, 6],
            [1, 256, 3, 3]
        ]
    );
    // Cut [:1] is conv 0 alone: check one output against a direct sum over the file's values.
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    let f = |k: &str| -> Vec<f32> {
        st.tensor(k)
            .unwrap()
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    };
    let (w0, b0) = (f("features.0.weight"), f("features.0.bias"));
    let xv = values(x.clone());
    let (o, oy, ox) = (5_usize, 0_i64, 7_i64); // output channel 5 at the top border (padding 1)
    let mut want = f64::from(b0[o]);
    for ci in 0..3 {
        for ky in 0..3_i64 {
            for kx in 0..3_i64 {
                let (yy, xx) = (oy + ky - 1, ox + kx - 1);
                if (0..12).contains(&yy) && (0..12).contains(&xx) {
                    let wv = w0[((o * 3 + ci) * 3 + ky as usize) * 3 + kx as usize];
                    want += f64::from(wv) * f64::from(xv[ci * 144 + (yy * 12 + xx) as usize]);
                }
            }
        }
    }
    let got = values(cuts[0].clone())[o * 144 + (oy * 12 + ox) as usize];
    assert!((f64::from(got) - want).abs() < 1e-5, "{got} {want}");
    // The loss: 0 for identical inputs, the 0.2-weighted sum of the cut L1s otherwise.
    let y = t4(random(3 * 12 * 12, 11), [1, 3, 12, 12], &d);
    assert!(scalar(vgg.perceptual_loss(x.clone(), x.clone())).abs() < 1e-7);
    let want: f64 = vgg
        .cuts(x.clone())
        .into_iter()
        .zip(vgg.cuts(y.clone()))
        .map(|(a, b)| 0.2 * scalar(l1(a, b)))
        .sum();
    assert!((scalar(vgg.perceptual_loss(x, y)) - want).abs() < 1e-6);
}

#[test]
fn vgg19_loader_names_the_bad_key() {
    let d = Device::flex();
    let err = Vgg19Features::from_bytes(&tiny_vgg(1, true, None), Path::new("v"), &d).unwrap_err();
    assert!(
        matches!(&err, TrainError::Vgg { reason, .. } if reason.contains("features.5.weight")),
        "{err}"
    );
    let err = Vgg19Features::from_bytes(
        &tiny_vgg(1, false, Some("features.12.bias")),
        Path::new("v"),
        &d,
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("missing tensor features.12.bias"),
        "{err}"
    );
    let err = Vgg19Features::from_bytes(b"not a safetensors file", Path::new("v"), &d).unwrap_err();
    assert!(matches!(err, TrainError::Vgg { .. }));
}

#[test]
fn vgg_parameters_are_frozen_but_pass_gradients() {
    let d = Device::flex().autodiff();
    let vgg = Vgg19Features::from_bytes(&tiny_vgg(2, false, None), Path::new("v"), &d).unwrap();
    let x = t4(random(3 * 8 * 8, 12), [1, 3, 8, 8], &d).require_grad();
    let y = t4(random(3 * 8 * 8, 13), [1, 3, 8, 8], &d);
    let grads = vgg.perceptual_loss(x.clone(), y).backward();
    assert!(x.grad(&grads).is_some());
    assert!(vgg.conv0.weight.val().grad(&grads).is_none());
}
