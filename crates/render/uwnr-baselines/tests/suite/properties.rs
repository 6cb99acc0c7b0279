//! Invariants of the baselines on random inputs: outputs in [0, 1], the clean image back at zero
//! range, determinism for a seed, variation across seeds where something is sampled, physical
//! monotonicity, agreement between models that coincide, and clear errors.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use uwnr_baselines::{
    BaselineError, ColourSpace, GivenCoefficients, JERLOV_TYPES, JerlovParams, Method, Range,
    ReferenceCoefficients, ReinhardParams, RenderInput, SampledCoefficients, SeathruCoefficients,
    SeathruParams, UisaParams, WaterType, render,
};
use uwnr_core::Image;

/// Random cases per property.
const CASES: u64 = 12;

fn random_image(rng: &mut ChaCha8Rng, w: usize, h: usize, c: usize) -> Image {
    let data: Vec<f32> = (0..w * h * c).map(|_| rng.random::<f32>()).collect();
    Image::from_planar(w, h, c, data).unwrap()
}

/// A smooth random underwater-looking reference: a tinted gradient plus noise.
fn random_reference(rng: &mut ChaCha8Rng) -> Image {
    let (w, h) = (rng.random_range(8..80), rng.random_range(8..80));
    let tint: [f32; 3] = [
        rng.random_range(0.0..0.5),
        rng.random_range(0.2..1.0),
        rng.random_range(0.2..1.0),
    ];
    let mut data = vec![0.0f32; 3 * w * h];
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                let v = tint[c] * (0.3 + 0.7 * y as f32 / h as f32) + 0.1 * rng.random::<f32>();
                data[(c * h + y) * w + x] = v.min(1.0);
            }
        }
    }
    Image::from_planar(w, h, 3, data).unwrap()
}

/// Every method with a non-trivial setting, including all coefficient modes.
fn all_methods() -> Vec<Method> {
    vec![
        Method::Jerlov(JerlovParams::default()),
        Method::Jerlov(JerlovParams {
            water_type: Some(WaterType::C9),
            illuminate_scene: true,
            ..JerlovParams::default()
        }),
        Method::Uisa(UisaParams::default()),
        Method::Uisa(UisaParams {
            attenuation_ratio: uwnr_baselines::AttenuationRatio::Wavelength,
            background_pick: uwnr_baselines::BackgroundPick::QuarterRank,
            ..UisaParams::default()
        }),
        Method::Seathru(SeathruParams::default()),
        Method::Seathru(SeathruParams {
            coefficients: SeathruCoefficients::Given(GivenCoefficients::default()),
            ..SeathruParams::default()
        }),
        Method::Seathru(SeathruParams {
            coefficients: SeathruCoefficients::FromReference(ReferenceCoefficients::default()),
            ..SeathruParams::default()
        }),
        Method::Reinhard(ReinhardParams::default()),
        Method::Reinhard(ReinhardParams {
            space: ColourSpace::Lab,
            ..ReinhardParams::default()
        }),
        Method::Reinhard(ReinhardParams {
            space: ColourSpace::Rgb,
            match_std: false,
        }),
    ]
}

struct Case {
    clean: Image,
    depth: Image,
    reference: Image,
}

fn case(seed: u64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h) = (rng.random_range(1..40), rng.random_range(1..40));
    Case {
        clean: random_image(&mut rng, w, h, 3),
        depth: random_image(&mut rng, w, h, 1),
        reference: random_reference(&mut rng),
    }
}

impl Case {
    fn input(&self) -> RenderInput<'_> {
        RenderInput {
            clean: &self.clean,
            depth: &self.depth,
            reference: Some(&self.reference),
        }
    }
}

#[test]
fn outputs_stay_in_unit_range_and_keep_the_size() {
    for k in 0..CASES {
        let c = case(k);
        for m in all_methods() {
            let out = render(&m, &c.input(), k).unwrap_or_else(|e| panic!("{}: {e}", m.name()));
            assert_eq!(out.image.size(), c.clean.size(), "{}", m.name());
            assert_eq!(out.image.channels(), 3);
            assert!(
                out.image.data().iter().all(|v| (0.0..=1.0).contains(v)),
                "{} case {k}: value outside [0, 1]",
                m.name()
            );
            assert_eq!(crate::value(&out.params)["method"], m.name());
        }
    }
}

#[test]
fn zero_depth_gives_the_clean_image_back() {
    for k in 0..CASES {
        let c = case(100 + k);
        let zero = Image::filled(c.clean.width(), c.clean.height(), 1, 0.0);
        let input = RenderInput {
            depth: &zero,
            ..c.input()
        };
        for m in all_methods() {
            let lit = matches!(&m, Method::Jerlov(p) if p.illuminate_scene);
            if matches!(m, Method::Reinhard(_)) || lit {
                continue; // Not physical in depth / scene lit by the background light.
            }
            let out = render(&m, &input, k).unwrap();
            for (a, b) in out.image.data().iter().zip(c.clean.data()) {
                assert!((a - b).abs() < 1e-6, "{}: {a} vs {b}", m.name());
            }
        }
    }
}

#[test]
fn same_seed_same_image_and_params() {
    let c = case(7);
    for m in all_methods() {
        let a = render(&m, &c.input(), 99).unwrap();
        let b = render(&m, &c.input(), 99).unwrap();
        assert_eq!(a.image, b.image, "{}", m.name());
        assert_eq!(a.params, b.params, "{}", m.name());
    }
}

#[test]
fn different_seeds_differ_where_something_is_sampled() {
    let c = case(8);
    let sampled = [
        Method::Jerlov(JerlovParams::default()),
        Method::Seathru(SeathruParams::default()),
        Method::Seathru(SeathruParams {
            coefficients: SeathruCoefficients::FromReference(ReferenceCoefficients::default()),
            ..SeathruParams::default()
        }),
    ];
    for m in sampled {
        let a = render(&m, &c.input(), 1).unwrap();
        let b = render(&m, &c.input(), 2).unwrap();
        assert_ne!(a.image, b.image, "{}", m.name());
        assert_ne!(a.params, b.params, "{}", m.name());
    }
    // Nothing is sampled in these: the seed must not matter.
    for m in [
        Method::Uisa(UisaParams::default()),
        Method::Reinhard(ReinhardParams::default()),
    ] {
        let a = render(&m, &c.input(), 1).unwrap();
        let b = render(&m, &c.input(), 2).unwrap();
        assert_eq!(a.image, b.image, "{}", m.name());
    }
}

#[test]
fn random_water_type_covers_all_ten_types() {
    let clean = Image::filled(2, 2, 3, 0.5);
    let depth = Image::filled(2, 2, 1, 0.5);
    let input = RenderInput {
        clean: &clean,
        depth: &depth,
        reference: None,
    };
    let mut seen = std::collections::BTreeSet::new();
    for seed in 0..200 {
        let out = render(&Method::Jerlov(JerlovParams::default()), &input, seed).unwrap();
        seen.insert(
            crate::value(&out.params)["water_type"]
                .as_str()
                .unwrap()
                .to_owned(),
        );
        let s = crate::value(&out.params)["depth_scale_m"].as_f64().unwrap();
        let d = crate::value(&out.params)["background_depth_m"]
            .as_f64()
            .unwrap();
        assert!(s > 0.5 && s <= 15.0, "{s}");
        assert!(d > 3.0 && d <= 5.0, "{d}");
    }
    assert_eq!(seen.len(), JERLOV_TYPES.len(), "{seen:?}");
}

#[test]
fn farther_pixels_are_closer_to_the_background() {
    // Uniform grey scene, depth increasing along the row: with one attenuation for signal and
    // backscatter, |I − B| = |J − B|·t must shrink with depth.
    let w = 16;
    let clean = Image::filled(w, 1, 3, 0.5);
    let depth =
        Image::from_planar(w, 1, 1, (0..w).map(|x| x as f32 / (w - 1) as f32).collect()).unwrap();
    let reference = case(3).reference;
    let input = RenderInput {
        clean: &clean,
        depth: &depth,
        reference: Some(&reference),
    };
    let given = GivenCoefficients {
        beta_d: [0.4, 0.1, 0.05],
        beta_b: [0.4, 0.1, 0.05],
        b_inf: [0.1, 0.4, 0.6],
    };
    let methods = [
        (
            Method::Jerlov(JerlovParams {
                water_type: Some(WaterType::C3),
                background_gain: 0.5,
                ..JerlovParams::default()
            }),
            "background_rgb",
        ),
        (
            Method::Seathru(SeathruParams {
                coefficients: SeathruCoefficients::Given(given),
                ..SeathruParams::default()
            }),
            "b_inf_rgb",
        ),
        (Method::Uisa(UisaParams::default()), "background_rgb"),
    ];
    for (m, key) in methods {
        let out = render(&m, &input, 5).unwrap();
        for c in 0..3 {
            let b = crate::value(&out.params)[key][c].as_f64().unwrap() as f32;
            let p = out.image.plane(c);
            let dist: Vec<f32> = p.iter().map(|v| (v - b).abs()).collect();
            assert!(
                dist.windows(2).all(|d| d[1] <= d[0] + 1e-5),
                "{} channel {c}: {p:?}",
                m.name()
            );
            assert!(
                dist[w - 1] < dist[0] || dist[0] < 1e-6,
                "{} channel {c}: {p:?}",
                m.name()
            );
        }
    }
}

#[test]
fn seathru_with_equal_coefficients_is_the_jerlov_model() {
    // β^D = β^B = −ln N (type 5C), B^∞ = 1.5·N^4 (clipped), fixed distance 6 m, on both sides.
    let c = case(11);
    let n = WaterType::C5.transmittance();
    let beta = n.map(|x| -x.ln());
    let background = n.map(|x| (1.5 * x.powf(4.0)).min(1.0));
    let jerlov = Method::Jerlov(JerlovParams {
        water_type: Some(WaterType::C5),
        depth_scale: Range::fixed(6.0),
        background_depth: Range::fixed(4.0),
        ..JerlovParams::default()
    });
    let seathru = Method::Seathru(SeathruParams {
        coefficients: SeathruCoefficients::Given(GivenCoefficients {
            beta_d: beta,
            beta_b: beta,
            b_inf: background,
        }),
        depth_scale: Range::fixed(6.0),
    });
    let a = render(&jerlov, &c.input(), 0).unwrap();
    let b = render(&seathru, &c.input(), 0).unwrap();
    for (x, y) in a.image.data().iter().zip(b.image.data()) {
        assert!((x - y).abs() < 1e-5, "{x} vs {y}");
    }
}

#[test]
fn seathru_sampled_water_stays_on_the_requested_part_of_the_manifold() {
    let c = case(12);
    let m = Method::Seathru(SeathruParams {
        coefficients: SeathruCoefficients::Sampled(SampledCoefficients {
            water: Range::new(7.0, 9.0),
            ..SampledCoefficients::default()
        }),
        ..SeathruParams::default()
    });
    for seed in 0..20 {
        let out = render(&m, &c.input(), seed).unwrap();
        let record = crate::value(&out.params);
        let pos = record["coefficients"]["jerlov_position"].as_f64().unwrap();
        assert!(pos > 7.0 && pos <= 9.0, "{pos}");
        let name = record["coefficients"]["nearest_water_type"]
            .as_str()
            .unwrap();
        assert!(["5C", "7C", "9C"].contains(&name), "{name}");
    }
}

#[test]
fn uisa_reproduces_the_reference_median_transmission() {
    // With a black clean image I_R = B_R·(1 − t_R), so the red transmission can be read back; its
    // median must be the reference's. An odd pixel count makes the median one pixel (with an even
    // count, sorting by decreasing transmission picks the other middle depth).
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let clean = Image::filled(31, 21, 3, 0.0);
    let depth = random_image(&mut rng, 31, 21, 1);
    let reference = random_reference(&mut rng);
    let input = RenderInput {
        clean: &clean,
        depth: &depth,
        reference: Some(&reference),
    };
    let out = render(&Method::Uisa(UisaParams::default()), &input, 0).unwrap();
    let b_red = crate::value(&out.params)["background_rgb"][0]
        .as_f64()
        .unwrap() as f32;
    let mut t: Vec<f32> = out.image.plane(0).iter().map(|v| 1.0 - v / b_red).collect();
    t.sort_by(f32::total_cmp);
    let got = t[(t.len() - 1) / 2];
    let want = crate::value(&out.params)["reference_median_transmission"]
        .as_f64()
        .unwrap() as f32;
    assert!((got - want).abs() < 1e-4, "{got} vs {want}");
}

#[test]
fn errors_name_the_problem() {
    let c = case(4);
    let no_ref = RenderInput {
        reference: None,
        ..c.input()
    };
    for m in [
        Method::Uisa(UisaParams::default()),
        Method::Reinhard(ReinhardParams::default()),
        Method::Seathru(SeathruParams {
            coefficients: SeathruCoefficients::FromReference(ReferenceCoefficients::default()),
            ..SeathruParams::default()
        }),
    ] {
        assert!(m.needs_reference());
        match render(&m, &no_ref, 0) {
            Err(BaselineError::MissingReference { method }) => assert_eq!(method, m.name()),
            other => panic!("{}: {other:?}", m.name()),
        }
    }
    let small = Image::filled(3, 3, 1, 0.5);
    let bad_depth = RenderInput {
        depth: &small,
        ..c.input()
    };
    let err = render(&Method::Jerlov(JerlovParams::default()), &bad_depth, 0).unwrap_err();
    assert!(matches!(err, BaselineError::DepthSize { .. }), "{err}");
    let mut nan = c.depth.clone();
    nan.data_mut()[0] = f32::NAN;
    let nan_depth = RenderInput {
        depth: &nan,
        ..c.input()
    };
    let err = render(&Method::Seathru(SeathruParams::default()), &nan_depth, 0).unwrap_err();
    assert!(
        matches!(err, BaselineError::NonFiniteDepth { count: 1 }),
        "{err}"
    );
    let grey = Image::filled(c.clean.width(), c.clean.height(), 1, 0.5);
    let grey_clean = RenderInput {
        clean: &grey,
        ..c.input()
    };
    let err = render(&Method::Uisa(UisaParams::default()), &grey_clean, 0).unwrap_err();
    assert!(
        matches!(
            err,
            BaselineError::Channels {
                what: "clean image",
                ..
            }
        ),
        "{err}"
    );
}

/// A reference with a strong colour cast `tint` (RGB) over the whole frame, a little texture and
/// a brighter top (the open water the background search finds).
fn cast_reference(rng: &mut ChaCha8Rng, tint: [f32; 3]) -> Image {
    let (w, h) = (64, 48);
    let mut data = vec![0.0f32; 3 * w * h];
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                let v = tint[c] * (1.0 - 0.5 * y as f32 / h as f32) + 0.04 * rng.random::<f32>();
                data[(c * h + y) * w + x] = v.min(1.0);
            }
        }
    }
    Image::from_planar(w, h, 3, data).unwrap()
}

/// Mean of channel `c`.
fn channel_mean(img: &Image, c: usize) -> f64 {
    let p = img.plane(c);
    p.iter().map(|&v| f64::from(v)).sum::<f64>() / p.len() as f64
}

#[test]
fn a_strongly_cast_reference_gives_a_clearly_cast_seathru_render() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    let method = Method::Seathru(SeathruParams {
        coefficients: SeathruCoefficients::FromReference(ReferenceCoefficients::default()),
        ..SeathruParams::default()
    });
    // Cyan-blue, blue-green and green casts, as in real underwater photos (red nearly gone).
    let tints = [
        [0.05, 0.5, 0.9],
        [0.1, 0.7, 0.7],
        [0.15, 0.6, 0.35],
        [0.02, 0.35, 0.6],
    ];
    for (i, tint) in tints.into_iter().enumerate() {
        let reference = cast_reference(&mut rng, tint);
        // A colourful, balanced clean photo and a depth that grows towards the top.
        let (w, h) = (48, 40);
        let clean = random_image(&mut rng, w, h, 3);
        let depth_data: Vec<f32> = (0..w * h)
            .map(|k| 0.2 + 0.8 * (1.0 - (k / w) as f32 / h as f32))
            .collect();
        let depth = Image::from_planar(w, h, 1, depth_data).unwrap();
        for seed in 0..6 {
            let input = RenderInput {
                clean: &clean,
                depth: &depth,
                reference: Some(&reference),
            };
            let out = render(&method, &input, seed).unwrap();
            let change = (0..3)
                .map(|c| {
                    let (a, b) = (out.image.plane(c), clean.plane(c));
                    a.iter()
                        .zip(b)
                        .map(|(x, y)| f64::from((x - y).abs()))
                        .sum::<f64>()
                        / a.len() as f64
                })
                .sum::<f64>()
                / 3.0;
            // The render takes on the cast: red falls behind the stronger of green and blue by
            // a clear margin, where the clean image has them level.
            let (r, g, b) = (
                channel_mean(&out.image, 0),
                channel_mean(&out.image, 1),
                channel_mean(&out.image, 2),
            );
            let clean_gap =
                channel_mean(&clean, 1).max(channel_mean(&clean, 2)) - channel_mean(&clean, 0);
            assert!(
                change * 255.0 > 15.0,
                "tint {i} seed {seed}: mean change {:.1}/255 ({})",
                change * 255.0,
                crate::value(&out.params)
            );
            assert!(
                g.max(b) - r > clean_gap + 0.12,
                "tint {i} seed {seed}: rgb means {r:.3} {g:.3} {b:.3} ({})",
                crate::value(&out.params)
            );
        }
    }
}
