//! The anchored variant: its output stage in burn against the plain one, the engine against
//! burn with random weights, and the depth response its structure guarantees.

use burn::module::Param;
use burn::tensor::{Distribution, Tensor, TensorData};
use uwnr_core::Image;
use uwnr_core::lightfield::{LightFieldMap, light_field_for_with};
use uwnr_core::resize::resize_bilinear;
use uwnr_model::finish::finish;
use uwnr_model::style::{
    REFERENCE_DEPTH, anchor, colour_transfer, detail_share, estimate_water, retain_detail,
};
use uwnr_model::{Backend, GeneratorConfig, ReferenceStyle, RenderOptions, Water};
use uwnr_train::burn_style::finish_tensor;
use uwnr_train::{Device, GeneratorInit, RenderOn, network_from_generator};

use crate::common::{max_abs, wave_image as image};

/// A low-contrast blue-green "underwater" reference: red flattened most.
fn reference(w: usize, h: usize) -> Image {
    let base = image(w, h, 3, 0.8, 2.0);
    let (gain, offset) = ([0.1f32, 0.5, 0.6], [0.1f32, 0.3, 0.35]);
    let data = (0..3)
        .flat_map(|c| base.plane(c).iter().map(move |v| v * gain[c] + offset[c]))
        .collect();
    Image::from_planar(w, h, 3, data).unwrap()
}

fn constant(w: usize, h: usize, v: f32) -> Image {
    Image::filled(w, h, 1, v)
}

#[test]
fn the_output_stage_in_burn_matches_the_plain_one() {
    let (w, h) = (40, 24);
    let device = Device::flex();
    let raw = {
        let mut d = image(w, h, 6, 0.6, 1.0).into_data();
        d.iter_mut().for_each(|v| *v = (*v - 0.5) * 0.8);
        Image::from_planar(w, h, 6, d).unwrap()
    };
    let water = estimate_water(&reference(32, 32)).unwrap();
    let clean = image(w, h, 3, 1.0, 0.0);
    let a = colour_transfer(&clean, &water).unwrap();
    let depth = image(w, h, 1, 0.2, 3.0);
    let want = finish(
        raw.clone(),
        a.clone(),
        &depth,
        &water,
        &uwnr_model::DepthResponse::default(),
    )
    .unwrap();
    let t = |img: &Image| {
        Tensor::<4>::from_data(
            TensorData::new(img.data().to_vec(), [1, img.channels(), h, w]),
            &device,
        )
    };
    let v =
        |x: [f32; 3]| Tensor::<4>::from_data(TensorData::new(x.to_vec(), [1, 3, 1, 1]), &device);
    let got =
        finish_tensor(t(&raw), t(&a), t(&depth), v(water.veil), v(water.beta)).clamp(0.0, 1.0);
    let got = Image::from_planar(w, h, 3, got.into_data().try_to_vec::<f32>().unwrap()).unwrap();
    let d = max_abs(&got, &want);
    assert!(d < 1e-5, "burn vs plain output stage: {d}");
}

/// An anchored network at width 8 whose last convolution is random (a fresh one outputs 0).
fn perturbed(device: &Device) -> (uwnr_train::Generator, GeneratorConfig) {
    let config = GeneratorConfig::anchored(8);
    // Seeded under the loop's lock, so that a run of a parallel test is not reseeded midway.
    let g = uwnr_train::init_seeded(5, device, || {
        let mut g = config.init(device)?;
        let [o, i, k, _] = g.out.weight.dims();
        g.out.weight = Param::from_tensor(Tensor::random(
            [o, i, k, k],
            Distribution::Normal(0.0, 0.05),
            device,
        ));
        Ok::<_, uwnr_train::TrainError>(g)
    })
    .unwrap();
    (g, config)
}

#[test]
fn the_engine_matches_burn_for_the_anchored_variant() {
    let device = Device::flex();
    let (g, config) = perturbed(&device);
    let engine = network_from_generator(&g, &config, &RenderOn::Engine(Backend::Engine)).unwrap();
    let burn = network_from_generator(&g, &config, &RenderOn::Burn(device)).unwrap();
    let style = ReferenceStyle::new(&reference(64, 48), &config).unwrap();
    assert!(style.water.is_some());
    let (w, h) = (70, 41);
    let clean = image(w, h, 3, 1.0, 0.5);
    let depth = image(w, h, 1, 0.3, 1.5);
    for opts in [
        RenderOptions::default(),
        RenderOptions {
            max_tile_pixels: 0,
            tile: 64,
            overlap: 32,
            ..Default::default()
        },
    ] {
        let a = engine.render(&clean, &depth, &style, &opts).unwrap();
        let b = burn.render(&clean, &depth, &style, &opts).unwrap();
        let d = max_abs(&a, &b);
        assert!(d < 1e-4, "{opts:?}: engine vs flex {d}");
    }
    // A style without water is refused by name.
    let bare = ReferenceStyle::from_light_field(style.light_field.clone().unwrap());
    let err = engine
        .render(&clean, &depth, &bare, &RenderOptions::default())
        .unwrap_err();
    assert!(err.to_string().contains("water"), "{err}");
}

#[test]
fn a_fresh_anchored_model_is_the_colour_transfer_at_the_reference_depth() {
    let device = Device::flex();
    let config = GeneratorConfig::anchored(8);
    // Seeded under the loop's lock, so that this draw never lands inside a parallel run's.
    let g = uwnr_train::init_seeded(3, &device, || config.init(&device)).unwrap();
    let net = network_from_generator(&g, &config, &RenderOn::Engine(Backend::Engine)).unwrap();
    let reference = reference(64, 48);
    let style = ReferenceStyle::new(&reference, &config).unwrap();
    let clean = image(48, 32, 3, 1.0, 0.5);
    let out = net
        .render(
            &clean,
            &constant(48, 32, REFERENCE_DEPTH),
            &style,
            &RenderOptions {
                depth: uwnr_model::DepthResponse::absolute(),
                ..Default::default()
            },
        )
        .unwrap();
    let lf = resize_bilinear(style.light_field.as_ref().unwrap(), 48, 32).unwrap();
    let want = anchor(&clean, style.water.as_ref().unwrap(), &lf, |im| {
        Ok(light_field_for_with(im, 48, 32, LightFieldMap::Absolute)?)
    })
    .unwrap();
    assert!(max_abs(&out, &want) < 1e-5);
}

fn luminance_std(img: &Image) -> f64 {
    let n = img.width() * img.height();
    let l: Vec<f64> = (0..n)
        .map(|i| {
            0.299 * f64::from(img.plane(0)[i])
                + 0.587 * f64::from(img.plane(1)[i])
                + 0.114 * f64::from(img.plane(2)[i])
        })
        .collect();
    let m = l.iter().sum::<f64>() / n as f64;
    (l.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n as f64).sqrt()
}

fn mean_rgb(img: &Image) -> [f64; 3] {
    std::array::from_fn(|c| {
        img.plane(c).iter().map(|&v| f64::from(v)).sum::<f64>() / img.plane(c).len() as f64
    })
}

#[test]
fn a_relative_map_responds_only_within_the_image() {
    let device = Device::flex();
    let (g, config) = perturbed(&device);
    let net = network_from_generator(&g, &config, &RenderOn::Engine(Backend::Engine)).unwrap();
    let style = ReferenceStyle::new(&reference(64, 48), &config).unwrap();
    let clean = image(48, 32, 3, 1.0, 0.5);
    let opts = RenderOptions::default();
    assert_eq!(opts.depth, uwnr_model::DepthResponse::default());
    let near = net
        .render(&clean, &constant(48, 32, 0.0), &style, &opts)
        .unwrap();
    let far = net
        .render(&clean, &constant(48, 32, 1.0), &style, &opts)
        .unwrap();
    assert!(max_abs(&near, &far) < 1e-6);
}

#[test]
fn farther_is_hazier_and_closer_to_the_veiling_light_whatever_the_weights() {
    let device = Device::flex();
    let (g, config) = perturbed(&device);
    let net = network_from_generator(&g, &config, &RenderOn::Engine(Backend::Engine)).unwrap();
    let style = ReferenceStyle::new(&reference(64, 48), &config).unwrap();
    let veil = style.water.as_ref().unwrap().veil;
    let (w, h) = (48, 32);
    let clean = image(w, h, 3, 1.0, 0.5);
    let absolute = RenderOptions {
        depth: uwnr_model::DepthResponse::absolute(),
        ..Default::default()
    };
    let renders: Vec<Image> = [0.0, 0.25, 0.5, 0.75, 1.0]
        .iter()
        .map(|&d| {
            net.render(&clean, &constant(w, h, d), &style, &absolute)
                .unwrap()
        })
        .collect();
    let change = renders[0]
        .data()
        .iter()
        .zip(renders[4].data())
        .map(|(a, b)| f64::from((a - b).abs()))
        .sum::<f64>()
        / renders[0].data().len() as f64;
    assert!(
        change * 255.0 > 15.0,
        "depth 0 vs 1 changes {:.1}/255",
        change * 255.0
    );
    for pair in renders.windows(2) {
        assert!(luminance_std(&pair[1]) < luminance_std(&pair[0]));
        let dist = |img: &Image| {
            let m = mean_rgb(img);
            (0..3)
                .map(|c| (m[c] - f64::from(veil[c])).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        assert!(dist(&pair[1]) <= dist(&pair[0]) + 1e-6);
    }
}

/// A 3-channel image: a smooth ramp plus a checkerboard of amplitude `fine[c]` per channel.
fn ramp_and_grain(w: usize, h: usize, fine: [f32; 3]) -> Image {
    let data = (0..3)
        .flat_map(|c| {
            (0..w * h).map(move |i| {
                let (x, y) = (i % w, i / w);
                let ramp = 0.2 + 0.6 * (x as f32 / w as f32);
                let checker = if (x + y) % 2 == 0 { 0.5 } else { -0.5 };
                ramp + fine[c] * checker + 0.05 * (y as f32 / h as f32)
            })
        })
        .collect();
    Image::from_planar(w, h, 3, data).unwrap()
}

#[test]
fn the_share_of_detail_tells_grain_from_large_scale_contrast() {
    let share = detail_share(&ramp_and_grain(64, 48, [0.0, 0.05, 0.2]));
    // A smooth ramp: windows see little of its spread; grain raises the share.
    assert!(share[0] < 0.15, "{share:?}");
    assert!(share[0] < share[1] && share[1] < share[2], "{share:?}");
    // A flat channel and an image smaller than a window have no share.
    let flat = Image::filled(16, 16, 3, 0.4);
    assert!(detail_share(&flat).iter().all(|v| v.is_nan()));
    assert!(
        detail_share(&ramp_and_grain(5, 5, [0.1; 3]))
            .iter()
            .all(|v| v.is_nan())
    );
}

fn std_of(p: &[f32]) -> f64 {
    let n = p.len() as f64;
    let m = p.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    (p.iter().map(|&v| (f64::from(v) - m).powi(2)).sum::<f64>() / n).sqrt()
}

#[test]
fn detail_retention_moves_each_channel_towards_the_reference_share() {
    let anchor_img = ramp_and_grain(64, 48, [0.05, 0.05, 0.05]);
    let before = detail_share(&anchor_img);
    let reference = ramp_and_grain(80, 60, [0.15, 0.05, 0.01]);
    let want = detail_share(&reference);
    let after = detail_share(&retain_detail(anchor_img.clone(), want).unwrap());
    // Red takes more grain, blue less, green about as much as it had.
    assert!(after[0] > before[0] + 0.05, "{before:?} -> {after:?}");
    assert!(after[2] < before[2] - 0.03, "{before:?} -> {after:?}");
    assert!(
        (after[1] - before[1]).abs() < 0.02,
        "{before:?} -> {after:?}"
    );
    for c in [0, 2] {
        assert!(
            (after[c] - want[c]).abs() < (before[c] - want[c]).abs() * 0.6,
            "channel {c}: {before:?} -> {after:?}, reference {want:?}"
        );
    }
    // The colour statistics are kept: means move by less than a level, spreads stay.
    let retained = retain_detail(anchor_img.clone(), want).unwrap();
    for c in 0..3 {
        let (s0, s1) = (std_of(anchor_img.plane(c)), std_of(retained.plane(c)));
        assert!((s0 - s1).abs() < 1e-3, "channel {c}: spread {s0} -> {s1}");
    }
    let (m0, m1) = (mean_rgb(&anchor_img), mean_rgb(&retained));
    assert!(
        m0.iter().zip(m1).all(|(a, b)| (a - b).abs() < 2e-3),
        "{m0:?} {m1:?}"
    );
    // A share that cannot be read leaves the channel as it is.
    let img = ramp_and_grain(32, 32, [0.05; 3]);
    assert!(max_abs(&retain_detail(img.clone(), [f32::NAN; 3]).unwrap(), &img) < 1e-7);
}

#[test]
fn detail_retention_is_a_config_choice_that_old_files_do_not_make() {
    let plain = GeneratorConfig::anchored(8);
    let json = serde_json::to_string(&plain).unwrap();
    assert!(!json.contains("detail"), "{json}");
    let detail = GeneratorConfig {
        detail_retention: true,
        ..plain
    };
    let json = serde_json::to_string(&detail).unwrap();
    assert_eq!(
        serde_json::from_str::<GeneratorConfig>(&json).unwrap(),
        detail
    );
    detail.validate().unwrap();
    let paper = GeneratorConfig {
        detail_retention: true,
        ..GeneratorConfig::with_base_width(8)
    };
    let err = paper.validate().unwrap_err();
    assert!(err.to_string().contains("detail_retention"), "{err}");
    // The style carries the reference's share only for a model that retains it.
    let reference = reference(64, 48);
    let without = ReferenceStyle::new(&reference, &plain).unwrap();
    assert!(without.water.unwrap().detail.is_none());
    let with = ReferenceStyle::new(&reference, &detail).unwrap();
    assert_eq!(with.water.unwrap().detail, Some(detail_share(&reference)));
}

#[test]
fn a_fresh_detail_retaining_model_renders_its_anchor() {
    let device = Device::flex();
    let config = GeneratorConfig {
        detail_retention: true,
        ..GeneratorConfig::anchored(8)
    };
    // Seeded under the loop's lock, so that this draw never lands inside a parallel run's.
    let g = uwnr_train::init_seeded(3, &device, || config.init(&device)).unwrap();
    let net = network_from_generator(&g, &config, &RenderOn::Engine(Backend::Engine)).unwrap();
    let reference = ramp_and_grain(64, 48, [0.2, 0.02, 0.02]);
    let style = ReferenceStyle::new(&reference, &config).unwrap();
    let clean = image(48, 32, 3, 1.0, 0.5);
    let absolute = RenderOptions {
        depth: uwnr_model::DepthResponse::absolute(),
        ..Default::default()
    };
    let out = net
        .render(
            &clean,
            &constant(48, 32, REFERENCE_DEPTH),
            &style,
            &absolute,
        )
        .unwrap();
    let lf = resize_bilinear(style.light_field.as_ref().unwrap(), 48, 32).unwrap();
    let lf_of = |im: &Image| Ok(light_field_for_with(im, 48, 32, LightFieldMap::Absolute)?);
    let water = style.water.unwrap();
    let want = anchor(&clean, &water, &lf, lf_of).unwrap();
    assert!(max_abs(&out, &want) < 1e-5);
    let plain = anchor(
        &clean,
        &Water {
            detail: None,
            ..water
        },
        &lf,
        lf_of,
    )
    .unwrap();
    assert!(
        max_abs(&want, &plain) > 1e-3,
        "detail retention changed nothing"
    );
}
