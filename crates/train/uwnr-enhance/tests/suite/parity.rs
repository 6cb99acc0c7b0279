//! Shallow-UWnet against an independent PyTorch build of it (`tools/shallow_uwnet_parity.py`),
//! the parameter count, weights round trips and errors.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use uwnr_core::Image;
use uwnr_enhance::weights::{load, save};
use uwnr_enhance::{Dropout, EnhanceError, ShallowUwnetConfig};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn device() -> Device {
    uwnr_train::device_from_name("flex").unwrap()
}

fn io() -> (Vec<f32>, Vec<f32>) {
    let (t, _) = uwnr_model::read_tensor_file(&fixture("parity_w16_io.safetensors")).unwrap();
    (t["input"].data.clone(), t["output"].data.clone())
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn the_papers_network_has_219456_parameters() {
    assert_eq!(ShallowUwnetConfig::default().param_count(), 219_456);
    let d = device();
    let net = ShallowUwnetConfig::default().init(&d).unwrap();
    use burn::module::Module;
    assert_eq!(net.num_params(), 219_456);
}

#[test]
fn matches_pytorch_from_safetensors_and_from_a_state_dict() {
    let d = device();
    let (input, want) = io();
    for file in ["parity_w16.safetensors", "parity_w16.pth"] {
        let (net, config) = load(&fixture(file), &d).unwrap();
        assert_eq!((config.width, config.blocks), (16, 3), "{file}");
        let x = Tensor::<4>::from_data(TensorData::new(input.clone(), [1, 3, 24, 40]), &d);
        let got = net.forward(x).into_data().try_into_vec::<f32>().unwrap();
        let diff = max_diff(&got, &want);
        assert!(diff < 1e-4, "{file}: max abs difference {diff}");
    }
}

#[test]
fn save_and_load_round_trip() {
    let d = device();
    let (net, config) = load(&fixture("parity_w16.safetensors"), &d).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.safetensors");
    save(&net, &config, &path, &BTreeMap::new()).unwrap();
    let (again, c2) = load(&path, &d).unwrap();
    assert_eq!(config, c2);
    let (input, _) = io();
    let x = || Tensor::<4>::from_data(TensorData::new(input.clone(), [1, 3, 24, 40]), &d);
    let a = net.forward(x()).into_data().try_into_vec::<f32>().unwrap();
    let b = again
        .forward(x())
        .into_data()
        .try_into_vec::<f32>()
        .unwrap();
    assert_eq!(a, b);
}

#[test]
fn wrong_weights_are_named() {
    let d = device();
    // The UWNR generator's weights are not Shallow-UWnet's.
    let uwnr = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../render/uwnr-model/tests/fixtures/parity_w8.safetensors");
    let err = load(&uwnr, &d).unwrap_err();
    assert!(matches!(err, EnhanceError::MissingKey { .. }), "{err}");

    let (mut tensors, _) =
        uwnr_model::read_tensor_file(&fixture("parity_w16.safetensors")).unwrap();
    let config = ShallowUwnetConfig {
        width: 16,
        ..ShallowUwnetConfig::default()
    };
    tensors.get_mut("blocks.1.conv1.weight").unwrap().shape = vec![13, 16, 1, 9];
    let err = uwnr_enhance::weights::from_tensors(&tensors, &config, "x", &d).unwrap_err();
    assert!(err.to_string().contains("blocks.1.conv1.weight"), "{err}");
}

#[test]
fn dropout_acts_in_training_only_and_is_seeded() {
    let d = device();
    let (net, _) = load(&fixture("parity_w16.safetensors"), &d).unwrap();
    let (input, want) = io();
    let x = || Tensor::<4>::from_data(TensorData::new(input.clone(), [1, 3, 24, 40]), &d);
    let run = |seed: u64| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut drop = Dropout {
            p: 0.2,
            rng: &mut rng,
        };
        net.forward_train(x(), &mut drop)
            .into_data()
            .try_into_vec::<f32>()
            .unwrap()
    };
    let (a, b, c) = (run(1), run(1), run(2));
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert!(max_diff(&a, &want) > 1e-3);
}

#[test]
fn enhances_images_of_any_size() {
    let d = device();
    let (net, _) = load(&fixture("parity_w16.safetensors"), &d).unwrap();
    let img = Image::filled(37, 21, 3, 0.4);
    let out = uwnr_enhance::enhance(&net, &img, &d).unwrap();
    assert_eq!(out.size(), (37, 21));
    assert!(out.data().iter().all(|v| (0.0..=1.0).contains(v)));
    let grey = Image::filled(8, 8, 1, 0.4);
    assert!(uwnr_enhance::enhance(&net, &grey, &d).is_err());
}
