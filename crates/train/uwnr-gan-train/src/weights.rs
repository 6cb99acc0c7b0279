//! Generator weights as safetensors, written and read as burn's module: burn's module paths as
//! keys (`encoder.0.weight`, ..., `head.bias`; linear weights in burn's `[in, out]` layout) and
//! the config as JSON in the metadata (`uwnr_gan::weights`, which reads the same files for
//! rendering without burn). Only the generator is exported: rendering needs no discriminator
//! (training checkpoints keep both, in uwnr-run's own files).

use std::collections::BTreeMap;
use std::path::Path;

use burn::store::{ModuleSnapshot, SafetensorsStore};
use burn::tensor::Device;

use uwnr_gan::weights::config_from_bytes;
pub use uwnr_gan::weights::{
    BUNDLED_GAN_NAME, CONFIG_METADATA_KEY, GENERATOR_FILE, bundled_gan_weights, read_config,
};

use crate::error::{GanError, Result};
use crate::model::{Generator, GeneratorInit};

/// Saves the generator (f32) with its config and `metadata` (replacing a file at `path`).
pub fn save_generator(
    generator: &Generator,
    path: &Path,
    metadata: &BTreeMap<String, String>,
) -> Result<()> {
    let bad = |reason: String| GanError::Weights {
        path: path.to_path_buf(),
        reason,
    };
    let config = serde_json::to_string(&generator.config).map_err(|e| bad(e.to_string()))?;
    let mut store = SafetensorsStore::from_file(path)
        .overwrite(true)
        .metadata(CONFIG_METADATA_KEY, config);
    for (k, v) in metadata {
        store = store.metadata(k.clone(), v.clone());
    }
    generator
        .save_into(&mut store)
        .map_err(|e| bad(format!("writing the generator: {e}")))
}

/// Loads a generator saved by [`save_generator`]: its config from the metadata, then every
/// tensor, checking none is missing, unexpected or of the wrong shape.
pub fn load_generator(path: &Path, device: &Device) -> Result<Generator> {
    let bytes = std::fs::read(path).map_err(|e| GanError::Weights {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    load_generator_from_bytes(bytes, path, device)
}

/// [`load_generator`] from the bytes of a weights file; `name` says where they came from (a
/// path, or the bundled model) in errors.
pub fn load_generator_from_bytes(
    bytes: Vec<u8>,
    name: &Path,
    device: &Device,
) -> Result<Generator> {
    let bad = |reason: String| GanError::Weights {
        path: name.to_path_buf(),
        reason,
    };
    let config = config_from_bytes(&bytes, name)?;
    let mut generator = config.init(device)?;
    let mut store = SafetensorsStore::from_bytes(Some(bytes));
    let result = generator
        .load_from(&mut store)
        .map_err(|e| bad(format!("reading the generator: {e}")))?;
    if !result.errors.is_empty() || !result.missing.is_empty() || !result.unused.is_empty() {
        return Err(bad(format!(
            "tensors do not match the generator: errors {:?}, missing {:?}, unexpected {:?}",
            result.errors, result.missing, result.unused
        )));
    }
    Ok(generator)
}

/// The generator of `weights`, or the bundled one, as burn's module; with the weight bytes and
/// where they came from.
pub fn generator_or_bundled(
    weights: Option<&Path>,
    device: &Device,
) -> Result<(Generator, Vec<u8>, String)> {
    let (bytes, name) = uwnr_gan::weights_or_bundled(weights)?;
    let generator = load_generator_from_bytes(bytes.clone(), Path::new(&name), device)?;
    Ok((generator, bytes, name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::to_vec;
    use crate::model::{GeneratorConfig, sample_z};
    use burn::tensor::Tensor;

    fn small() -> GeneratorConfig {
        GeneratorConfig {
            z_dim: 4,
            widths: vec![4, 8],
            hidden: 8,
            encoder_size: 8,
            ..GeneratorConfig::default()
        }
    }

    #[test]
    fn a_saved_generator_loads_back_with_its_config_and_renders_the_same() {
        let d = Device::flex();
        let cfg = GeneratorConfig {
            imaging: crate::imaging::ImagingConfig {
                blur: true,
                range_m: 4.0,
            },
            ..small()
        };
        let g = cfg.init(&d).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(GENERATOR_FILE);
        let mut meta = BTreeMap::new();
        meta.insert("source".to_string(), "test".to_string());
        save_generator(&g, &path, &meta).unwrap();
        // Saving again replaces the file.
        save_generator(&g, &path, &meta).unwrap();
        let back = load_generator(&path, &d).unwrap();
        assert_eq!(back.config, cfg);
        let clean = Tensor::<4>::ones([1, 3, 8, 8], &d) * 0.4;
        let depth = Tensor::<4>::ones([1, 1, 8, 8], &d) * 0.3;
        let z = sample_z(1, 1, 4, &d);
        let a = to_vec(
            g.forward(clean.clone(), depth.clone(), z.clone())
                .unwrap()
                .0,
        )
        .unwrap();
        let b = to_vec(back.forward(clean, depth, z).unwrap().0).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn weights_load_from_a_path_or_the_bundled_model() {
        let d = Device::flex();
        let g = small().init(&d).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(GENERATOR_FILE);
        save_generator(&g, &path, &BTreeMap::new()).unwrap();
        let (back, bytes, name) = generator_or_bundled(Some(&path), &d).unwrap();
        assert_eq!(back.config, g.config);
        assert_eq!(bytes, std::fs::read(&path).unwrap());
        assert_eq!(name, path.display().to_string());
        match bundled_gan_weights() {
            Some(b) => {
                let (_, bytes, name) = generator_or_bundled(None, &d).unwrap();
                assert_eq!(bytes, b);
                assert_eq!(name, BUNDLED_GAN_NAME);
            }
            None => {
                let err = generator_or_bundled(None, &d).unwrap_err().to_string();
                assert!(err.contains("no bundled UWGAN model"), "{err}");
            }
        }
        let err = load_generator_from_bytes(b"junk".to_vec(), Path::new("x"), &d).unwrap_err();
        assert!(matches!(err, GanError::Weights { .. }), "{err}");
    }

    #[test]
    fn a_file_without_the_config_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.safetensors");
        std::fs::write(&path, b"not safetensors").unwrap();
        let err = load_generator(&path, &Device::flex()).unwrap_err();
        assert!(matches!(err, GanError::Weights { .. }), "{err}");
    }
}
