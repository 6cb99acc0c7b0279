//! `uwnr info`: parameters, GMac at a size, and where the weights came from.

use std::process::ExitCode;

use anyhow::Result;
use uwnr_model::GeneratorConfig;

use crate::cli::InfoArgs;

pub fn run(a: &InfoArgs) -> Result<ExitCode> {
    let (w, h) = a.size;
    let have_weights = a.weights.is_some() || super::bundled_weights().is_some();
    let (config, source) = if have_weights {
        let (config, info, source) = super::model_facts(a.weights.as_deref())?;
        println!("weights:     {source}");
        println!("format:      {:?}, {:?}", info.format, info.dtype);
        for (k, v) in &info.metadata {
            println!("  {k}: {v}");
        }
        if !info.ignored_keys.is_empty() {
            println!(
                "ignored:     {} unused keys (e.g. {})",
                info.ignored_keys.len(),
                info.ignored_keys[0]
            );
        }
        (config, Some(source))
    } else {
        let config = GeneratorConfig {
            base_width: a.base_width,
            ..GeneratorConfig::default()
        };
        (config, None)
    };
    if source.is_none() {
        println!(
            "weights:     none (this build has no bundled model; describing the architecture)"
        );
    }
    println!(
        "architecture: MHB-Unet, base width {}, {} -> {} channels",
        config.base_width, config.in_channels, config.out_channels
    );
    println!(
        "parameters:  {} used by the network, {} in the authors' checkpoint (with unused norms)",
        uwnr_model::param_count(&config, false),
        uwnr_model::param_count(&config, true)
    );
    println!("light field: {} map", config.light_field);
    println!(
        "variant:     {}",
        match config.variant {
            uwnr_model::Variant::Paper => "paper (clean, depth, light field in; the image out)",
            uwnr_model::Variant::Anchored =>
                "anchored (clean, light field, anchor in; smooth gain and offset out; depth through the image-formation stage)",
        }
    );
    if config.variant == uwnr_model::Variant::Anchored {
        let detail = if config.detail_retention {
            ", with the reference's share of fine detail"
        } else {
            ""
        };
        match config.anchor {
            uwnr_model::AnchorKind::Reinhard => println!(
                "anchor:      Reinhard transfer to the reference's statistics, its light field retained{detail}"
            ),
            uwnr_model::AnchorKind::Water => println!(
                "anchor:      the reference's water (gain and offset per channel, read off its statistics) on the photo's own colours{detail}"
            ),
        }
    }
    let (pw, ph) = (w.div_ceil(16) * 16, h.div_ceil(16) * 16);
    println!(
        "compute:     {:.2} GMac at {w}x{h} (padded to {pw}x{ph})",
        uwnr_model::gmacs(&config, ph, pw)
    );
    Ok(ExitCode::SUCCESS)
}
