//! Generator weights as safetensors: burn's module paths as keys (`encoder.0.weight`,
//! `encoder.0.bias`, ..., `hidden.weight`, `head.bias`; linear weights in burn's `[in, out]`
//! layout) and the [`GeneratorConfig`] as JSON in the metadata, so [`load_generator`] rebuilds
//! the network from the file alone. Read here for rendering; the training wing
//! (`uwnr-gan-train`) writes them. Only the generator is exported: rendering needs no
//! discriminator.

use std::path::Path;

use safetensors::{Dtype, SafeTensors};

use crate::config::{ENCODER_IN, GeneratorConfig, RAW_PARAMS};
use crate::error::{GanError, Result};
use crate::generator::{Conv, Generator, Linear};

/// The generator's weights inside each checkpoint folder.
pub const GENERATOR_FILE: &str = "generator.safetensors";
/// Safetensors metadata key of the [`GeneratorConfig`] (JSON).
pub const CONFIG_METADATA_KEY: &str = "uwnr.gan.generator_config";
/// How the bundled generator is named in messages and dataset settings.
pub const BUNDLED_GAN_NAME: &str = "bundled UWGAN model";

/// The generator config stored in a weights file's metadata.
pub fn read_config(path: &Path) -> Result<GeneratorConfig> {
    config_from_bytes(&read(path)?, path)
}

/// Loads a generator saved by `uwnr gan train`: its config from the metadata, then every
/// tensor, checking none is missing, unexpected or of the wrong shape.
pub fn load_generator(path: &Path) -> Result<Generator> {
    load_generator_from_bytes(&read(path)?, path)
}

/// [`load_generator`] from the bytes of a weights file; `name` says where they came from (a
/// path, or the bundled model) in errors.
pub fn load_generator_from_bytes(bytes: &[u8], name: &Path) -> Result<Generator> {
    let bad = |reason: String| GanError::Weights {
        path: name.to_path_buf(),
        reason,
    };
    let config = config_from_bytes(bytes, name)?;
    let st =
        SafeTensors::deserialize(bytes).map_err(|e| bad(format!("not a safetensors file: {e}")))?;
    let mut reader = Reader {
        st: &st,
        name,
        used: Vec::new(),
    };
    let mut encoder = Vec::with_capacity(config.widths.len());
    let mut cin = ENCODER_IN;
    for (i, &cout) in config.widths.iter().enumerate() {
        encoder.push(Conv {
            weight: reader.tensor(format!("encoder.{i}.weight"), &[cout, cin, 3, 3])?,
            bias: reader.tensor(format!("encoder.{i}.bias"), &[cout])?,
            cin,
            cout,
        });
        cin = cout;
    }
    let hidden = reader.linear("hidden", cin + config.z_dim, config.hidden)?;
    let head = reader.linear("head", config.hidden, RAW_PARAMS)?;
    let unexpected: Vec<String> = st
        .names()
        .into_iter()
        .filter(|k| !reader.used.iter().any(|u| u == k))
        .map(str::to_string)
        .collect();
    if !unexpected.is_empty() {
        return Err(bad(format!(
            "tensors do not match the generator: unexpected {unexpected:?}"
        )));
    }
    Ok(Generator {
        encoder,
        hidden,
        head,
        config,
    })
}

/// Takes the tensors of a weights file by key, checking shape and dtype, and remembers which
/// were taken.
struct Reader<'a> {
    st: &'a SafeTensors<'a>,
    name: &'a Path,
    used: Vec<String>,
}

impl Reader<'_> {
    fn bad(&self, reason: String) -> GanError {
        GanError::Weights {
            path: self.name.to_path_buf(),
            reason,
        }
    }

    /// The f32 tensor `key` of `shape`.
    fn tensor(&mut self, key: String, shape: &[usize]) -> Result<Vec<f32>> {
        let view = self.st.tensor(&key).map_err(|_| {
            self.bad(format!(
                "tensors do not match the generator: {key} is missing"
            ))
        })?;
        if view.shape() != shape {
            return Err(self.bad(format!(
                "tensors do not match the generator: {key} has shape {:?}, expected {shape:?}",
                view.shape()
            )));
        }
        if view.dtype() != Dtype::F32 {
            return Err(self.bad(format!("{key} is {:?}, expected F32", view.dtype())));
        }
        let data = view
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        self.used.push(key);
        Ok(data)
    }

    /// The linear layer `name` (`[din, dout]` weight, `[dout]` bias).
    fn linear(&mut self, name: &str, din: usize, dout: usize) -> Result<Linear> {
        Ok(Linear {
            weight: self.tensor(format!("{name}.weight"), &[din, dout])?,
            bias: self.tensor(format!("{name}.bias"), &[dout])?,
            din,
            dout,
        })
    }
}

fn read(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| GanError::Weights {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// The [`GeneratorConfig`] in the metadata of the safetensors `bytes` (named `name` in errors).
pub fn config_from_bytes(bytes: &[u8], name: &Path) -> Result<GeneratorConfig> {
    let bad = |reason: String| GanError::Weights {
        path: name.to_path_buf(),
        reason,
    };
    let (_, meta) = SafeTensors::read_metadata(bytes)
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

/// The bytes of `weights`, or of the bundled generator, with where they came from.
pub fn weights_or_bundled(weights: Option<&Path>) -> Result<(Vec<u8>, String)> {
    Ok(match weights {
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
    })
}

/// The generator of `weights`, or the bundled one; with the weight bytes (for fingerprints) and
/// where they came from.
pub fn generator_or_bundled(weights: Option<&Path>) -> Result<(Generator, Vec<u8>, String)> {
    let (bytes, name) = weights_or_bundled(weights)?;
    let generator = load_generator_from_bytes(&bytes, Path::new(&name))?;
    Ok((generator, bytes, name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn junk_and_files_without_the_config_are_refused() {
        let err = load_generator_from_bytes(b"junk", Path::new("x")).unwrap_err();
        assert!(matches!(err, GanError::Weights { .. }), "{err}");
        let bytes = safetensors::serialize(
            [(
                "a",
                safetensors::tensor::TensorView::new(Dtype::F32, vec![1], &[0u8; 4]).unwrap(),
            )],
            None,
        )
        .unwrap();
        let err = load_generator_from_bytes(&bytes, Path::new("x")).unwrap_err();
        assert!(err.to_string().contains(CONFIG_METADATA_KEY), "{err}");
    }

    #[test]
    fn the_bundled_generator_loads_when_this_build_has_one() {
        match bundled_gan_weights() {
            Some(b) => {
                let (g, bytes, name) = generator_or_bundled(None).unwrap();
                assert_eq!(bytes, b);
                assert_eq!(name, BUNDLED_GAN_NAME);
                assert_eq!(g.config.widths.len(), g.encoder.len());
            }
            None => {
                let err = generator_or_bundled(None).unwrap_err().to_string();
                assert!(err.contains("no bundled UWGAN model"), "{err}");
            }
        }
    }
}
