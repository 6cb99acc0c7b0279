//! `uwnr depth`: the depth map a render would use for a clean image (bright = far).

use std::process::ExitCode;

use anyhow::{Context, Result};
use uwnr_core::io::{DecodeLimits, load_rgb, save_gray};

use crate::cli::DepthArgs;

pub fn run(a: &DepthArgs) -> Result<ExitCode> {
    let clean = load_rgb(&a.clean, &DecodeLimits::default())
        .with_context(|| format!("reading clean image {}", a.clean.display()))?;
    if a.depth.prior_trust.is_some() {
        anyhow::bail!("--prior-trust does not apply to `uwnr depth` (it sets how renders respond)");
    }
    let source = super::depth_source(&a.depth)?;
    let prepared = source.prepare().context("preparing the depth source")?;
    let depth = prepared
        .depth_for(&clean, Some(&a.clean))
        .with_context(|| format!("depth of {}", a.clean.display()))?;
    for n in &depth.notes {
        eprintln!("note: {n}");
    }
    save_gray(&a.output, &depth.map).with_context(|| format!("writing {}", a.output.display()))?;
    eprintln!(
        "depth {}x{} written to {}",
        depth.map.width(),
        depth.map.height(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
