//! Parity of the burn generator with an independent PyTorch implementation, and the error
//! paths of the weights loader.
//!
//! The fixtures come from `tools/torch_parity.py` (width 8, seeded random weights, input
//! 1x7x32x48, reference output computed in float64). Regenerate them with
//! `python3 tools/torch_parity.py` from the repository root.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use uwnr_train::{Device, load_generator, load_generator_from_bytes, save_generator};

use burn::tensor::{Tensor, TensorData};
use uwnr_model::weights::SOURCE_METADATA_KEY;
use uwnr_model::{GeneratorConfig, ModelError, WeightsDtype, WeightsFormat, read_weights};
use uwnr_train::generator_to_tensors;

/// Max abs difference allowed between the f32 burn forward and the f64 torch reference. The
/// torch f32 forward differs from the f64 one by about 4e-7 on this input.
const PARITY_TOL: f32 = 1e-4;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../render/uwnr-model/tests/fixtures")
        .join(name)
}

/// `input`, `output` and the four `mean.K` tensors of the reference.
fn reference() -> BTreeMap<String, (Vec<usize>, Vec<f32>)> {
    let bytes = std::fs::read(fixture("parity_w8_io.safetensors")).unwrap();
    let st = safetensors::SafeTensors::deserialize(&bytes).unwrap();
    st.iter()
        .map(|(k, v)| {
            assert_eq!(v.dtype(), safetensors::Dtype::F32);
            let data = v
                .data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            (k.to_string(), (v.shape().to_vec(), data))
        })
        .collect()
}

fn tensor4(shape: &[usize], data: &[f32], device: &Device) -> Tensor<4> {
    Tensor::from_data(
        TensorData::new(data.to_vec(), [shape[0], shape[1], shape[2], shape[3]]),
        device,
    )
}

fn max_abs(a: Tensor<4>, b: &[f32]) -> f32 {
    let a = a.into_data().try_to_vec::<f32>().unwrap();
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

fn check_parity(generator: &uwnr_train::Generator, device: &Device, what: &str) {
    let reference = reference();
    let (shape, input) = &reference["input"];
    let x = tensor4(shape, input, device);
    let (y, means) = generator.forward_returning_channel_means(x);
    let err = max_abs(y, &reference["output"].1);
    println!("{what}: output max abs diff vs torch f64 = {err:.3e}");
    assert!(err < PARITY_TOL, "{what}: {err}");
    for (k, m) in means.into_iter().enumerate() {
        let (shape, want) = &reference[&format!("mean.{k}")];
        assert_eq!(m.dims().to_vec(), *shape);
        let err = max_abs(m, want);
        assert!(err < PARITY_TOL, "{what}: mean {k}: {err}");
    }
}

#[test]
fn safetensors_fixture_matches_torch() {
    let device = Device::flex();
    let (g, config, info) = load_generator(&fixture("parity_w8.safetensors"), &device).unwrap();
    assert_eq!(config, GeneratorConfig::with_base_width(8));
    assert_eq!(info.format, WeightsFormat::Safetensors);
    assert_eq!(info.dtype, WeightsDtype::F16);
    assert!(info.metadata[SOURCE_METADATA_KEY].contains("torch_parity.py"));
    assert_eq!(info.ignored_keys.len(), 8, "{:?}", info.ignored_keys);
    check_parity(&g, &device, "safetensors f16");
}

/// The same parity on libtorch (`--features tch`, with `LIBTORCH_USE_PYTORCH=1` and torch's
/// `lib` directory on `LD_LIBRARY_PATH`).
#[cfg(feature = "tch")]
#[test]
fn tch_device_matches_torch() {
    let device = uwnr_model::device_from_name("tch").unwrap();
    let (g, _, _) = load_generator(&fixture("parity_w8.safetensors"), &device).unwrap();
    check_parity(&g, &device, "tch device");
}

#[test]
fn authors_checkpoint_fixture_matches_torch() {
    let device = Device::flex();
    let (g, config, info) = load_generator(&fixture("parity_w8_ckpt.pth"), &device).unwrap();
    // No metadata in a torch checkpoint: the config is inferred from the shapes.
    assert_eq!(config, GeneratorConfig::with_base_width(8));
    assert_eq!(info.format, WeightsFormat::TorchCheckpoint);
    assert_eq!(info.dtype, WeightsDtype::F32);
    check_parity(&g, &device, "torch checkpoint");

    // The same bytes from memory (written to a temporary file internally).
    let bytes = std::fs::read(fixture("parity_w8_ckpt.pth")).unwrap();
    let (g, _, _) = load_generator_from_bytes(&bytes, &device).unwrap();
    check_parity(&g, &device, "torch checkpoint from bytes");
}

#[test]
fn save_and_reload_round_trips() {
    let device = Device::flex();
    let (g, config, _) = load_generator(&fixture("parity_w8.safetensors"), &device).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let meta = BTreeMap::from([(SOURCE_METADATA_KEY.to_string(), "round trip".to_string())]);
    for dtype in [WeightsDtype::F32, WeightsDtype::F16] {
        let path = dir.path().join(format!("g-{dtype:?}.safetensors"));
        save_generator(&g, &config, &path, dtype, &meta).unwrap();
        let loaded = read_weights(&path).unwrap();
        assert_eq!(loaded.config, config);
        assert_eq!(loaded.info.dtype, dtype);
        assert_eq!(loaded.info.metadata[SOURCE_METADATA_KEY], "round trip");
        // The full authors' key set, unused norms included, at their PyTorch init.
        let norm = &loaded.tensors["down2.mpconv.2.norm.weight"];
        assert_eq!(norm.shape, [8]);
        assert!(norm.data.iter().all(|&v| v == 1.0));
        // The fixture's weights are f16-exact, so both dtypes reproduce them exactly.
        let original = generator_to_tensors(&g, &config).unwrap();
        assert_eq!(loaded.tensors, original);
        let (g2, _, _) = load_generator(&path, &device).unwrap();
        check_parity(&g2, &device, &format!("saved {dtype:?}"));
    }
    // No temporary files left behind by the atomic write.
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 2);
}

#[test]
fn config_is_inferred_without_metadata() {
    let device = Device::flex();
    let loaded = read_weights(&fixture("parity_w8.safetensors")).unwrap();
    let views: Vec<(String, Vec<usize>, Vec<u8>)> = loaded
        .tensors
        .iter()
        .map(|(k, t)| {
            let bytes = t.data.iter().flat_map(|v| v.to_le_bytes()).collect();
            (k.clone(), t.shape.clone(), bytes)
        })
        .collect();
    let bytes = safetensors::serialize(
        views.iter().map(|(k, s, b)| {
            (
                k.as_str(),
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, s.clone(), b)
                    .unwrap(),
            )
        }),
        None,
    )
    .unwrap();
    let (g, config, info) = load_generator_from_bytes(&bytes, &device).unwrap();
    assert_eq!(config, GeneratorConfig::with_base_width(8));
    assert!(info.metadata.is_empty());
    check_parity(&g, &device, "no metadata");
}

/// Writes the fixture's tensors (f32) with one edit applied, as safetensors.
fn edited_fixture(edit: impl FnOnce(&mut BTreeMap<String, (Vec<usize>, Vec<f32>)>)) -> Vec<u8> {
    let loaded = read_weights(&fixture("parity_w8.safetensors")).unwrap();
    let mut map: BTreeMap<String, (Vec<usize>, Vec<f32>)> = loaded
        .tensors
        .into_iter()
        .map(|(k, t)| (k, (t.shape, t.data)))
        .collect();
    edit(&mut map);
    let encoded: Vec<(String, Vec<usize>, Vec<u8>)> = map
        .into_iter()
        .map(|(k, (s, d))| (k, s, d.iter().flat_map(|v| v.to_le_bytes()).collect()))
        .collect();
    safetensors::serialize(
        encoded.iter().map(|(k, s, b)| {
            (
                k.as_str(),
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, s.clone(), b)
                    .unwrap(),
            )
        }),
        None,
    )
    .unwrap()
}

#[test]
fn wrong_shape_names_the_key() {
    let bytes = edited_fixture(|m| {
        m.insert(
            "down2.mpconv.2.conk1.weight".into(),
            (vec![16, 16, 3, 3], vec![0.0; 16 * 16 * 9]),
        );
    });
    let err = load_generator_from_bytes(&bytes, &Device::flex()).unwrap_err();
    match &err {
        ModelError::ShapeMismatch { key, expected, got } => {
            assert_eq!(key, "down2.mpconv.2.conk1.weight");
            assert_eq!(expected, &[16, 16, 1, 1]);
            assert_eq!(got, &[16, 16, 3, 3]);
        }
        other => panic!("expected ShapeMismatch, got {other}"),
    }
    assert!(err.to_string().contains("down2.mpconv.2.conk1.weight"));
}

#[test]
fn missing_key_is_named() {
    let bytes = edited_fixture(|m| {
        m.remove("up3.up.0.bias");
    });
    let err = load_generator_from_bytes(&bytes, &Device::flex()).unwrap_err();
    assert!(
        matches!(&err, ModelError::MissingKey { key } if key == "up3.up.0.bias"),
        "{err}"
    );
}

#[test]
fn integer_dtype_is_refused_with_the_key() {
    let bytes = safetensors::serialize(
        [(
            "out.0.bias",
            safetensors::tensor::TensorView::new(safetensors::Dtype::I32, vec![3], &[0u8; 12])
                .unwrap(),
        )],
        None,
    )
    .unwrap();
    let err = load_generator_from_bytes(&bytes, &Device::flex()).unwrap_err();
    assert!(
        matches!(&err, ModelError::UnsupportedDtype { key, .. } if key == "out.0.bias"),
        "{err}"
    );
}

#[test]
fn non_checkpoint_file_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("notes.txt");
    std::fs::write(&path, "these are not weights, just some text in a file").unwrap();
    let err = load_generator(&path, &Device::flex()).unwrap_err();
    assert!(matches!(err, ModelError::UnknownFormat { .. }), "{err}");
    assert!(err.to_string().contains("notes.txt"), "{err}");

    // A zip that is not a torch checkpoint: a clear checkpoint error naming the file.
    let path = dir.path().join("archive.pth");
    std::fs::write(&path, b"PK\x03\x04 but not really a zip archive").unwrap();
    let err = load_generator(&path, &Device::flex()).unwrap_err();
    assert!(matches!(err, ModelError::Checkpoint { .. }), "{err}");
    assert!(err.to_string().contains("archive.pth"), "{err}");

    let err = load_generator(&dir.path().join("absent.safetensors"), &Device::flex()).unwrap_err();
    assert!(matches!(err, ModelError::Io { .. }), "{err}");
}
