//! `uwnr lightfield`: the light-field map of a reference (the released code's procedure).

use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_core::io::{DecodeLimits, load_rgb, save_rgb};
use uwnr_core::lightfield::{light_field_for_with, light_field_with};

use crate::cli::LightfieldArgs;

pub fn run(a: &LightfieldArgs) -> Result<ExitCode> {
    let reference = load_rgb(&a.reference, &DecodeLimits::default())
        .with_context(|| format!("reading reference {}", a.reference.display()))?;
    let map = match a.size {
        Some((w, h)) => light_field_for_with(&reference, w, h, a.map),
        None => light_field_with(&reference, a.map),
    }
    .with_context(|| format!("light field of {}", a.reference.display()))?;
    save_rgb(&a.output, &map).with_context(|| format!("writing {}", a.output.display()))?;
    eprintln!(
        "light field {}x{} written to {}",
        map.width(),
        map.height(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
