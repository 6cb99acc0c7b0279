use super::*;

fn tiny_network(backend: &Backend) -> uwnr_model::Network {
    let config = GeneratorConfig::with_base_width(8);
    let tensors = uwnr_model::weights::keys::seeded_tensors(&config, 1);
    uwnr_model::Network::from_tensors(&config, tensors, backend)
        .unwrap()
        .0
}

#[test]
fn bf16_products_are_recorded_and_f32_settings_keep_their_old_form() {
    let params = |backend: &Backend| {
        Renderer::network(
            tiny_network(backend),
            RenderOptions::default(),
            "w".into(),
            b"x",
        )
        .settings_params()
        .unwrap()
    };
    let f32 = params(&Backend::Engine);
    let bf16 = params(&Backend::EngineBf16);
    assert!(f32.get("precision").is_none(), "{f32}");
    assert_eq!(bf16["precision"], "bf16");
    assert_ne!(f32, bf16, "a resume with the other precision is refused");
    let mut without = bf16.clone();
    without.as_object_mut().unwrap().remove("precision");
    assert_eq!(without, f32, "nothing else differs");
}

#[test]
fn baselines_record_their_method_json_and_haze_its_spec() {
    let r = Renderer::load(MethodSpec::defaults(MethodKind::Reinhard, true)).unwrap();
    assert_eq!(
        r.settings_params().unwrap(),
        serde_json::to_value(r.spec().baseline().unwrap()).unwrap()
    );
    assert_eq!(r.reference_use(), ReferenceUse::Required);
    let h = Renderer::load(MethodSpec::defaults(MethodKind::Haze, false)).unwrap();
    assert_eq!(h.settings_params().unwrap()["method"], "haze");
    assert_eq!(h.reference_use(), ReferenceUse::Ignored);
}

#[test]
fn an_optional_reference_is_used_when_given_and_sampled_without() {
    let r = Renderer::load_keywords(MethodKind::Seathru, &Map::new()).unwrap();
    assert_eq!(r.reference_use(), ReferenceUse::Optional);
    let clean = Image::filled(16, 12, 3, 0.5);
    let depth = Image::filled(16, 12, 1, 0.5);
    let response = DepthResponse::default();
    let worker = r.worker();
    let without = worker.render(&clean, &depth, &response, None, 3).unwrap();
    assert_eq!(without.params.to_value()["coefficients"]["mode"], "sampled");
    let given: Map<String, Value> =
        serde_json::from_str(r#"{"coefficients":{"mode":"sampled"}}"#).unwrap();
    let sampled = Renderer::load_keywords(MethodKind::Seathru, &given).unwrap();
    assert_eq!(sampled.reference_use(), ReferenceUse::Ignored);
    let needs = Renderer::load(MethodSpec::defaults(MethodKind::Uisa, true)).unwrap();
    let e = needs
        .worker()
        .render(&clean, &depth, &response, None, 3)
        .err()
        .unwrap();
    assert!(
        matches!(e, RenderError::NeedsReference { method: "uisa" }),
        "{e}"
    );
}

#[test]
fn the_network_reads_the_style_the_baselines_the_image() {
    let net = Renderer::network(
        tiny_network(&Backend::Engine),
        RenderOptions::default(),
        "w".into(),
        b"",
    );
    let reference = Arc::new(Image::filled(40, 30, 3, 0.3));
    let prepared = net.prepare_reference(Arc::clone(&reference)).unwrap();
    assert!(prepared.style.is_some() && prepared.image.is_none());
    let clean = Image::filled(32, 32, 3, 0.5);
    let depth = Image::filled(32, 32, 1, 0.5);
    let out = net
        .worker()
        .render(
            &clean,
            &depth,
            &DepthResponse::default(),
            Some(prepared.input()),
            0,
        )
        .unwrap();
    assert_eq!(out.image.size(), (32, 32));
    assert_eq!(out.params.to_value()["weights"], "w");
    let reinhard = Renderer::load(MethodSpec::defaults(MethodKind::Reinhard, true)).unwrap();
    let prepared = reinhard.prepare_reference(Arc::clone(&reference)).unwrap();
    assert!(prepared.style.is_none());
    // The baselines share the decoded reference rather than copy it.
    assert!(Arc::ptr_eq(prepared.image.as_ref().unwrap(), &reference));
}

#[test]
fn missing_weights_are_one_clear_error() {
    let spec = MethodSpec::Uwnr(UwnrSpec {
        weights: Some("no/such/weights.safetensors".into()),
        ..UwnrSpec::default()
    });
    let e = Renderer::load(spec).err().unwrap().to_string();
    assert!(
        e.starts_with("loading weights no/such/weights.safetensors"),
        "{e}"
    );
}

/// `r`'s render of `clean` (32 x 32) after `reference`, at a flat depth and seed 0.
fn render_after(r: &Renderer, reference: &Image, clean: &Image) -> Image {
    let prepared = r.prepare_reference(Arc::new(reference.clone())).unwrap();
    r.worker()
        .render(
            clean,
            &Image::filled(32, 32, 1, 0.5),
            &DepthResponse::default(),
            Some(prepared.input()),
            0,
        )
        .unwrap()
        .image
}

#[test]
fn the_clean_balance_runs_before_the_water_and_is_recorded() {
    // The bundled model with no effects, at the bank's balance and at none.
    if uwnr_model::bundled_model_bytes().is_none() {
        eprintln!("skipped: this build has no bundled model (`cargo test --workspace` has it)");
        return;
    }
    // The balanced clean side (v8's); the lit one, the default, is tested below.
    let load = |balance: CleanBalance| {
        Renderer::load(MethodSpec::Uwnr(UwnrSpec {
            effects: WaterEffects::NONE,
            balance,
            clean_side: CleanSide::Balanced,
            ..UwnrSpec::default()
        }))
        .unwrap()
    };
    let (bank, none) = (load(CleanBalance::BANK), load(CleanBalance::NONE));
    assert_eq!(UwnrSpec::default().balance, CleanBalance::BANK);
    assert_eq!(UwnrSpec::default().clean_side, CleanSide::Lit);
    let recorded = bank.settings_params().unwrap();
    assert_eq!(recorded["balance"], serde_json::json!(CleanBalance::BANK.0));
    // None keeps the settings' old form, so datasets made before the balance resume unchanged,
    // and a resume across the two is refused (the records differ).
    let old = none.settings_params().unwrap();
    assert!(old.get("balance").is_none(), "{old}");
    assert_eq!(recorded["clean_side"], "balanced", "{recorded}");
    let mut stripped = recorded.clone();
    stripped.as_object_mut().unwrap().remove("balance");
    stripped.as_object_mut().unwrap().remove("clean_side");
    stripped
        .as_object_mut()
        .unwrap()
        .remove("balance_water_share");
    assert_eq!(stripped, old, "nothing else differs");

    // The clean side a dataset stores: the balanced photo here; the photo as given when the
    // method asks for it, which is then not recorded (the old form).
    let photo = Renderer::load(MethodSpec::Uwnr(UwnrSpec {
        clean_side: CleanSide::Photo,
        ..UwnrSpec::default()
    }))
    .unwrap();
    assert!(photo.settings_params().unwrap().get("clean_side").is_none());

    // What the calibration measures from: the balanced photo for uwnr, the photo for the rest.
    let clean = Image::filled(32, 32, 3, 0.5);
    let balanced = bank.balanced(&clean, None).unwrap();
    let (photo_balanced, none_balanced) = (
        photo.balanced(&clean, None).unwrap(),
        none.balanced(&clean, None).unwrap(),
    );
    assert!(matches!(
        photo.clean_side(&clean, &photo_balanced).unwrap(),
        std::borrow::Cow::Borrowed(_)
    ));
    assert!(matches!(
        none.clean_side(&clean, &none_balanced).unwrap(),
        std::borrow::Cow::Borrowed(_)
    ));
    assert_eq!(*bank.clean_side(&clean, &balanced).unwrap(), *balanced);
    assert!(balanced.plane(0)[0] < 0.5 && balanced.plane(2)[0] > 0.5);
    assert!(matches!(
        none.balanced(&clean, None).unwrap(),
        std::borrow::Cow::Borrowed(_)
    ));
    let reinhard = Renderer::load(MethodSpec::defaults(MethodKind::Reinhard, true)).unwrap();
    assert!(matches!(
        reinhard.balanced(&clean, None).unwrap(),
        std::borrow::Cow::Borrowed(_)
    ));

    // The render after a grey reference: the bank's balance cools it, as the balanced photo.
    let grey = Image::filled(40, 30, 3, 0.3);
    let (b, n) = (
        render_after(&bank, &grey, &clean),
        render_after(&none, &grey, &clean),
    );
    let mean = |img: &Image, c: usize| img.plane(c).iter().sum::<f32>() / 1024.0;
    assert!(
        mean(&b, 0) < mean(&n, 0),
        "red {} {}",
        mean(&b, 0),
        mean(&n, 0)
    );
    assert!(
        mean(&b, 2) > mean(&n, 2),
        "blue {} {}",
        mean(&b, 2),
        mean(&n, 2)
    );
    // A balance out of range is refused before anything is loaded.
    let bad = MethodSpec::Uwnr(UwnrSpec {
        balance: CleanBalance([1.0, 1.0, 9.0]),
        ..UwnrSpec::default()
    });
    assert!(
        bad.validate()
            .unwrap_err()
            .to_string()
            .contains("clean balance")
    );
}

#[test]
fn the_clean_balance_follows_the_reference_s_water_by_its_share() {
    if uwnr_model::bundled_model_bytes().is_none() {
        eprintln!("skipped: this build has no bundled model (`cargo test --workspace` has it)");
        return;
    }
    let load = |share: f32| {
        Renderer::load(MethodSpec::Uwnr(UwnrSpec {
            effects: WaterEffects::NONE,
            balance_water_share: share,
            ..UwnrSpec::default()
        }))
        .unwrap()
    };
    let (follows, fixed) = (load(uwnr_model::water::BANK_WATER_SHARE), load(0.0));
    // Recorded when it follows; the fixed balance keeps v8's record.
    let (rf, r0) = (
        follows.settings_params().unwrap(),
        fixed.settings_params().unwrap(),
    );
    assert_eq!(
        rf["balance_water_share"],
        serde_json::json!(uwnr_model::water::BANK_WATER_SHARE)
    );
    assert!(r0.get("balance_water_share").is_none(), "{r0}");
    // A green reference and a blue one, each with its water's colour throughout.
    let reference = |rgb: [f32; 3]| {
        let mut img = Image::filled(48, 36, 3, 0.0);
        for (c, v) in rgb.iter().enumerate() {
            img.plane_mut(c).fill(*v);
        }
        img
    };
    let (green, blue) = (reference([0.1, 0.5, 0.3]), reference([0.1, 0.3, 0.5]));
    let clean = Image::filled(32, 32, 3, 0.5);
    let side = |r: &Renderer, img: &Image| {
        let style = r.reference_style(img, false).unwrap();
        let balanced = r.balanced(&clean, Some(&style)).unwrap();
        let out = r.clean_side(&clean, &balanced).unwrap().into_owned();
        assert_eq!(*balanced, out);
        std::array::from_fn::<f32, 3, _>(|c| out.plane(c)[0])
    };
    let (g, b) = (side(&follows, &green), side(&follows, &blue));
    assert!(g[1] > b[1] && g[2] < b[2], "green {g:?} blue {b:?}");
    // The fixed balance gives both the same clean side, v8's.
    let (g0, b0) = (side(&fixed, &green), side(&fixed, &blue));
    assert_eq!(g0, b0);
    let v8 = fixed.balanced(&clean, None).unwrap();
    assert_eq!(g0, std::array::from_fn(|c| v8.plane(c)[0]));
    // The render starts from the same balanced photo: greener after the green reference.
    let mean = |img: &Image, c: usize| img.plane(c).iter().sum::<f32>() / 1024.0;
    let (rg, r0g) = (
        render_after(&follows, &green, &clean),
        render_after(&fixed, &green, &clean),
    );
    assert!(
        mean(&rg, 1) > mean(&r0g, 1),
        "green {} {}",
        mean(&rg, 1),
        mean(&r0g, 1)
    );
    // A share out of [0, 1] is refused before anything is loaded.
    let bad = MethodSpec::Uwnr(UwnrSpec {
        balance_water_share: 1.5,
        ..UwnrSpec::default()
    });
    assert!(
        bad.validate()
            .unwrap_err()
            .to_string()
            .contains("balance_water_share")
    );
}

#[test]
fn a_lit_clean_side_carries_the_underwater_side_s_light() {
    if uwnr_model::bundled_model_bytes().is_none() {
        eprintln!("skipped: this build has no bundled model (`cargo test --workspace` has it)");
        return;
    }
    let load = |clean_side, effects| {
        Renderer::load(MethodSpec::Uwnr(UwnrSpec {
            effects,
            clean_side,
            ..UwnrSpec::default()
        }))
        .unwrap()
    };
    let light = WaterEffects {
        light_from_above: 0.6,
        ..WaterEffects::NONE
    };
    let (lit, balanced) = (
        load(CleanSide::Lit, light),
        load(CleanSide::Balanced, light),
    );
    assert_eq!(lit.settings_params().unwrap()["clean_side"], "lit");
    let clean = Image::filled(32, 32, 3, 0.5);
    let (lit_balanced, flat_balanced) = (
        lit.balanced(&clean, None).unwrap(),
        balanced.balanced(&clean, None).unwrap(),
    );
    let side = lit.clean_side(&clean, &lit_balanced).unwrap();
    let flat = balanced.clean_side(&clean, &flat_balanced).unwrap();
    let (w, h) = clean.size();
    for c in 0..3 {
        for y in [0, h / 2, h - 1] {
            let gain = 1.0 + 0.6 * (0.5 - (y as f32 + 0.5) / h as f32);
            let (got, want) = (side.plane(c)[y * w + 3], flat.plane(c)[y * w + 3] * gain);
            assert!(
                (got - want).abs() < 1e-6,
                "channel {c} row {y}: {got} against {want}"
            );
        }
    }
    // The top brighter than the balanced photo, the bottom darker: the light from above the
    // underwater side has.
    assert!(
        side.plane(1)[3] > flat.plane(1)[3]
            && side.plane(1)[(h - 1) * w] < flat.plane(1)[(h - 1) * w]
    );
    // The underwater side is the same whichever clean side is stored.
    let reference = Image::filled(32, 32, 3, 0.4);
    assert_eq!(
        render_after(&lit, &reference, &clean),
        render_after(&balanced, &reference, &clean)
    );
    // Without light in the effects a lit clean side is the balanced one.
    let dark = load(CleanSide::Lit, WaterEffects::NONE);
    let dark_balanced = dark.balanced(&clean, None).unwrap();
    assert_eq!(*dark.clean_side(&clean, &dark_balanced).unwrap(), *flat);
    assert_ne!(
        dark.settings_params().unwrap(),
        load(CleanSide::Balanced, WaterEffects::NONE)
            .settings_params()
            .unwrap(),
        "recorded, so a resume across the two is refused"
    );
}
