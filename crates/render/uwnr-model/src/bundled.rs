//! The default model shipped inside uwnr's binaries: `assets/model/uwnr-default.json`, its
//! config, embedded at build time when it exists and the `bundled-model` feature is on (see
//! `build.rs`). Its correction is none ([`crate::config::Correction::None`]): the water read off
//! the reference, the depth stage and the effects, with no network, so it carries no weights.
//! The command-line tool and the Python package both take it from here.

use crate::config::GeneratorConfig;
use crate::error::{ModelError, Result};

/// How the bundled model is named in messages and dataset settings.
pub const BUNDLED_MODEL_NAME: &str = "bundled model";

/// The bundled model's file (its config as JSON), or `None` in a build without it.
#[must_use]
pub fn bundled_model_bytes() -> Option<&'static [u8]> {
    #[cfg(uwnr_bundled_model)]
    {
        Some(include_bytes!(env!("UWNR_BUNDLED_MODEL")))
    }
    #[cfg(not(uwnr_bundled_model))]
    {
        None
    }
}

/// The bundled model's config, or `None` in a build without it.
pub fn bundled_config() -> Option<Result<GeneratorConfig>> {
    bundled_model_bytes().map(|bytes| {
        let config: GeneratorConfig = serde_json::from_slice(bytes)
            .map_err(|e| ModelError::InvalidOptions(format!("the bundled model's config: {e}")))?;
        config.validate()?;
        Ok(config)
    })
}

/// The bundled model, ready to render, or `None` in a build without it.
pub fn bundled_network() -> Option<Result<crate::Network>> {
    bundled_config().map(|c| c.and_then(|c| crate::Network::uncorrected(&c)))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_bundled_model_runs_no_network() {
        let Some(config) = super::bundled_config() else {
            eprintln!("skipped: this build has no bundled model");
            return;
        };
        let config = config.unwrap();
        assert!(
            !config.runs_network() && !config.reads_light_field(),
            "{config:?}"
        );
        assert!(crate::Network::uncorrected(&config).is_ok());
    }
}
