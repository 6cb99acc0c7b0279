//! `uwnr info`: parameters, GMac at a size, and where the weights came from.

use std::process::ExitCode;

use anyhow::Result;
use uwnr_model::GeneratorConfig;

use crate::cli::InfoArgs;

pub fn run(a: &InfoArgs) -> Result<ExitCode> {
    let (w, h) = a.size;
    if a.weights.is_none()
        && let Some(config) = uwnr_model::bundled_config()
    {
        return describe_bundled(&config?);
    }
    let (config, source) = if let Some(path) = &a.weights {
        let (config, info, source) = super::model_facts(path)?;
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

/// `uwnr info` on the bundled model: what runs.
fn describe_bundled(config: &GeneratorConfig) -> Result<ExitCode> {
    println!(
        "model:       {} (assets/model/uwnr-default.json)",
        uwnr_model::BUNDLED_MODEL_NAME
    );
    if config.runs_network() {
        println!("correction:  a network (MHB-Unet), whose weights this build does not carry");
        return Ok(ExitCode::SUCCESS);
    }
    println!("correction:  none: no network is loaded or run, no light field is computed");
    let spec = uwnr_render::UwnrSpec::default();
    let follows = if spec.balance_water_share == 0.0 {
        String::new()
    } else {
        format!(
            ", following each reference's water by {} of its cast as real clean sides do",
            spec.balance_water_share
        )
    };
    println!(
        "renders:     the photo brought to the white point of the real pairs' clean sides (the \
         clean balance, R G B x {:?}{follows}); the reference's water (gain and offset per channel, read \
         off its statistics by the bundled water bank's linear regressor) on the photo's own \
         colours{}; the depth \
         stage (farther is hazier); the effects (particles, light from above, colours the water \
         removes, forward scattering that widens with distance; a medium and a vignette are \
         off; `--method-config` sets them)",
        spec.balance.0,
        if config.detail_retention {
            ", with the reference's share of fine detail"
        } else {
            ""
        }
    );
    println!("weights:     none (--weights FILE renders with a trained network's correction)");
    Ok(ExitCode::SUCCESS)
}
