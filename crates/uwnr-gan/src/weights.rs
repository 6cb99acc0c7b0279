//! Generator weights as safetensors: burn's module paths as keys (`encoder.0.weight`,
//! `encoder.0.bias`, ..., `hidden.weight`, `head.bias`; linear weights in burn's `[in, out]`
//! layout) and the [`GeneratorConfig`] as JSON in the metadata, so [`load_generator`] rebuilds
//! the network from the file alone. Only the generator is exported: rendering needs no
//! discriminator (training checkpoints keep both, in uwnr-run's own files).

use std::collections::BTreeMap;
use std::path::Path;

use burn::store::{ModuleSnapshot, SafetensorsStore};
use burn::tensor::Device;

use crate::error::{GanError, Result};
use crate::model::{Generator, GeneratorConfig};

/// The generator's weights inside each checkpoint folder.
pub const GENERATOR_FILE: &str = "generator.safetensors";
/// Safetensors metadata key of the [`GeneratorConfig`] (JSON).
pub const CONFIG_METADATA_KEY: &str = "uwnr.gan.generator_config";

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

/// The generator config stored in a weights file's metadata.
pub fn read_config(path: &Path) -> Result<GeneratorConfig> {
    config_from_bytes(&read(path)?, path)
}

/// Loads a generator saved by [`save_generator`]: its config from the metadata, then every
/// tensor, checking none is missing, unexpected or of the wrong shape.
pub fn load_generator(path: &Path, device: &Device) -> Result<Generator> {
    load_generator_from_bytes(read(path)?, path, device)
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

fn read(path: &Path) -> Result<Vec<u8>> {
    Ok(
        std::fs::read(path).map_err(|source| uwnr_run::RunError::Io {
            path: path.to_path_buf(),
            source,
        })?,
    )
}

/// The [`GeneratorConfig`] in the metadata of the safetensors `bytes` (named `name` in errors).
fn config_from_bytes(bytes: &[u8], name: &Path) -> Result<GeneratorConfig> {
    let bad = |reason: String| GanError::Weights {
        path: name.to_path_buf(),
        reason,
    };
    let (_, meta) = safetensors::SafeTensors::read_metadata(bytes)
        .map_err(|e| bad(format!("not a safetensors file: {e}")))?;
    let json = meta
        .metadata()
        .as_ref()
        .and_then(|m| m.get(CONFIG_METADATA_KEY))
        .ok_or_else(|| {
            bad(format!(
                "no {CONFIG_METADATA_KEY} metadata (not a uwnr-gan generator?)"
            ))
        })?;
    let config: GeneratorConfig = serde_json::from_str(json)
        .map_err(|e| bad(format!("metadata {CONFIG_METADATA_KEY}: {e}")))?;
    config.validate()?;
    Ok(config)
}

/// How the bundled generator is named in messages and dataset settings.
pub const BUNDLED_GAN_NAME: &str = "bundled UWGAN model";

/// The bundled generator's weights (`assets/model/uwgan-default.safetensors`, embedded at build
/// time when it exists and the `bundled-model` feature is on), or `None` in a build without.
#[must_use]
pub fn bundled_gan_weights() -> Option<&'static [u8]> {
    #[cfg(uwnr_bundled_gan)]
    {
        Some(include_bytes!(env!("UWNR_BUNDLED_GAN")))
    }
    #[cfg(not(uwnr_bundled_gan))]
    {
        None
    }
}

/// The generator of `weights`, or the bundled one; with the weight bytes (for fingerprints) and
/// where they came from.
pub fn generator_or_bundled(
    weights: Option<&Path>,
    device: &Device,
) -> Result<(Generator, Vec<u8>, String)> {
    let (bytes, name) = match weights {
        Some(p) => (read(p)?, p.display().to_string()),
        None => (
            bundled_gan_weights()
                .ok_or_else(|| GanError::Weights {
                    path: BUNDLED_GAN_NAME.into(),
                    reason: "this build has no bundled UWGAN model: pass the weights of a \
                             `uwnr gan train` run (checkpoints/best/generator.safetensors)"
                        .into(),
                })?
                .to_vec(),
            BUNDLED_GAN_NAME.to_string(),
        ),
    };
    let generator = load_generator_from_bytes(bytes.clone(), Path::new(&name), device)?;
    Ok((generator, bytes, name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::to_vec;
    use crate::model::sample_z;
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
