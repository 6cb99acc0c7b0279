//! `uwnr convert`: any weights uwnr reads -> safetensors in the authors' key names, with the
//! config in the metadata and the chosen precision (f16 halves the file).

use std::collections::BTreeMap;
use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_model::weights::SOURCE_METADATA_KEY;
use uwnr_model::{WeightsDtype, save_weights};

use crate::cli::{ConvertArgs, DtypeArg};

pub fn run(a: &ConvertArgs) -> Result<ExitCode> {
    let (loaded, _) = super::load_model(&a.input)?;
    let (config, info) = (loaded.config, loaded.info);
    let mut tensors = loaded.tensors;
    // The full key set, as the authors' `load_state_dict` expects it.
    uwnr_model::weights::keys::add_unused_norms(&config, &mut tensors);
    let source = a
        .source
        .clone()
        .or_else(|| info.metadata.get(SOURCE_METADATA_KEY).cloned())
        .unwrap_or_else(|| {
            a.input
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        });
    let metadata = BTreeMap::from([(SOURCE_METADATA_KEY.to_string(), source)]);
    let dtype = match a.dtype {
        DtypeArg::F32 => WeightsDtype::F32,
        DtypeArg::F16 => WeightsDtype::F16,
        DtypeArg::Bf16 => WeightsDtype::Bf16,
    };
    save_weights(&tensors, &config, &a.output, dtype, &metadata)
        .with_context(|| format!("writing {}", a.output.display()))?;
    let size = std::fs::metadata(&a.output).map(|m| m.len()).unwrap_or(0);
    eprintln!(
        "wrote {} ({:?}, base width {}, {:.1} MB)",
        a.output.display(),
        a.dtype,
        config.base_width,
        size as f64 / 1e6
    );
    Ok(ExitCode::SUCCESS)
}
