//! From the method flags of `uwnr render`, `uwnr dataset` and `uwnr experiment` to a
//! [`MethodSpec`]: the flags become `uwnr_render::MethodOptions` (which says which method has
//! which option and sets them, for the page too); here only the command line's own parts (the
//! model options, `--method-config`) are added.

use anyhow::{Context, Result, bail};
use uwnr_baselines::{ColourSpace, WaterType};
use uwnr_render::{MethodKind, MethodOptions, MethodSpec, Precision, Renderer};

use crate::cli::{BaselineOpts, DeviceArg, ModelOpts, PrecisionArg, SeathruSource};

/// The options the flags set on method `kind` (`uwnr_render::MethodOptions`, the type the page
/// and the commands it shows share). `--precision` is set on the methods it applies to only, so
/// that one run may render a network and baselines.
pub fn options(kind: MethodKind, o: &BaselineOpts, precision: PrecisionArg) -> MethodOptions {
    MethodOptions {
        method: kind,
        seed: 0,
        water_type: o.water_type.map(WaterType::from),
        depth_scale: o.depth_scale,
        background_depth: o.background_depth,
        seathru: o.seathru.map(|s| match s {
            SeathruSource::Sampled => uwnr_render::SeathruSource::Sampled,
            SeathruSource::Reference => uwnr_render::SeathruSource::Reference,
            SeathruSource::Given => uwnr_render::SeathruSource::Given,
        }),
        beta_d: o.beta_d,
        beta_b: o.beta_b,
        b_inf: o.b_inf,
        reinhard_space: o.reinhard_space.map(ColourSpace::from),
        mean_only: o.mean_only,
        precision: if kind.loads_weights() {
            precision.into()
        } else {
            Precision::F32
        },
    }
}

/// Method `kind`'s settings before the flags: its `--method-config` (every method but the GAN,
/// whose settings are its weights), or its defaults (`have_reference`: Sea-thru fits its
/// coefficients to the reference).
fn base_spec(kind: MethodKind, o: &BaselineOpts, have_reference: bool) -> Result<MethodSpec> {
    match &o.method_config {
        Some(path) if kind != MethodKind::Uwgan => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            MethodSpec::from_json(&text, Some(kind))
                .with_context(|| format!("method config {}", path.display()))
        }
        _ => Ok(MethodSpec::defaults(kind, have_reference)),
    }
}

/// Refuses a method option that none of `methods` uses, with one line naming the option and
/// the method(s) (`MethodOptions::refuse_inapplicable`; `--method-config` is the command
/// line's own).
pub fn refuse_inapplicable(
    methods: &[MethodKind],
    o: &BaselineOpts,
    have_reference: bool,
) -> Result<()> {
    let configurable: Vec<MethodKind> = MethodKind::ALL
        .into_iter()
        .filter(|k| *k != MethodKind::Uwgan)
        .collect();
    if o.method_config.is_some() && !methods.iter().any(|m| configurable.contains(m)) {
        let to = configurable.iter().map(|m| m.name()).collect::<Vec<_>>();
        let names = methods.iter().map(|m| m.name()).collect::<Vec<_>>();
        bail!(
            "--method-config does not apply to --method {} (only to {})",
            names.join(","),
            to.join(", ")
        );
    }
    let any = methods.first().copied().unwrap_or(MethodKind::Uwnr);
    let options = options(any, o, PrecisionArg::F32);
    // Sea-thru takes its coefficients from the reference when its settings say so.
    let seathru_fitted = methods.contains(&MethodKind::Seathru)
        && options.seathru_fitted(&base_spec(MethodKind::Seathru, o, have_reference)?);
    options.refuse_inapplicable(methods, seathru_fitted)?;
    Ok(())
}

/// Method `kind` with its flags applied: its [`base_spec`] with the options the flags set
/// ([`options`], `MethodOptions::spec_over`, which also refuses a render without the reference
/// it needs), then the model options for the networks (weights and tiling override the
/// config's). Callers first refuse flags that apply to none of their methods
/// ([`refuse_inapplicable`]).
pub fn method_spec(
    kind: MethodKind,
    o: &BaselineOpts,
    model: &ModelOpts,
    precision: PrecisionArg,
    have_reference: bool,
) -> Result<MethodSpec> {
    if kind.loads_weights() && model.device != DeviceArg::Engine {
        bail!(
            "renders run on the engine (uwnr-engine): --device flex|tch chooses where training runs \
             (uwnr train, enhance, gan, experiment); drop it here"
        );
    }
    if kind == MethodKind::Uwgan && precision == PrecisionArg::Bf16 {
        bail!("--precision bf16 applies to --method uwnr only (the UWGAN generator runs in f32)");
    }
    let base = base_spec(kind, o, have_reference)?;
    let mut spec = options(kind, o, precision).spec_over(base, have_reference)?;
    match &mut spec {
        MethodSpec::Uwnr(s) => {
            if model.weights.is_some() {
                s.weights.clone_from(&model.weights);
            }
            if s.weights.is_none() {
                // The bundled model runs no network: flags for one would do nothing.
                if let Some(flag) = model.tiling_flag() {
                    bail!(
                        "{flag} tiles a network, and the bundled model runs none (its correction is \
                         none): drop it, or give --weights"
                    );
                }
                if precision == PrecisionArg::Bf16 {
                    bail!(
                        "--precision bf16 applies to a network, and the bundled model runs none \
                         (its correction is none): drop it, or give --weights"
                    );
                }
            }
            s.max_whole_pixels = model.max_whole_pixels.unwrap_or(s.max_whole_pixels);
            s.tile = model.tile.unwrap_or(s.tile);
            s.overlap = model.overlap.unwrap_or(s.overlap);
        }
        MethodSpec::Uwgan(s) => {
            if let Some(flag) = model.tiling_flag() {
                bail!("{flag} tiles the UWNR network; --method uwgan renders whole images");
            }
            s.weights.clone_from(&model.weights);
        }
        _ => {}
    }
    Ok(spec)
}

/// [`method_spec`], loaded.
pub fn renderer(
    kind: MethodKind,
    o: &BaselineOpts,
    model: &ModelOpts,
    precision: PrecisionArg,
    have_reference: bool,
) -> Result<Renderer> {
    let spec = method_spec(kind, o, model, precision, have_reference)?;
    Ok(Renderer::load(spec)?)
}
