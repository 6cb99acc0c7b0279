//! From the method flags of `uwnr render`, `uwnr dataset` and `uwnr experiment` to a
//! [`MethodSpec`]: the methods' defaults come from `uwnr-render`; here only the flags that
//! a method has on the command line are mapped onto its settings.

use anyhow::{Context, Result, bail};
use uwnr_baselines::{
    ColourSpace, GivenCoefficients, Range, ReferenceCoefficients, SampledCoefficients,
    SeathruCoefficients, WaterType,
};
use uwnr_render::{MethodKind, MethodSpec, Renderer};

use crate::cli::{BaselineOpts, DeviceArg, ModelOpts, PrecisionArg, SeathruSource};

fn range((min, max): (f64, f64)) -> Range {
    Range { min, max }
}

/// Refuses a method option that none of `methods` uses, with one line naming the option and
/// the method(s): an option that does not apply is a mistake, not something to ignore.
pub fn refuse_inapplicable(
    methods: &[MethodKind],
    o: &BaselineOpts,
    have_reference: bool,
) -> Result<()> {
    use MethodKind::{Jerlov, Reinhard, Seathru, Uwnr};
    let seathru_given = o.seathru == Some(SeathruSource::Given);
    // Sea-thru takes its coefficients from the reference when one is given, unless told.
    let seathru_fitted = match o.seathru {
        Some(SeathruSource::Reference) => true,
        Some(_) => false,
        None => have_reference && o.method_config.is_none(),
    };
    let configurable: Vec<MethodKind> = MethodKind::ALL
        .into_iter()
        .filter(|k| !k.loads_weights())
        .collect();
    // (flag, is it set, the methods it applies to)
    let flags: [(&str, bool, &[MethodKind]); 9] = [
        ("--method-config", o.method_config.is_some(), &configurable),
        ("--water-type", o.water_type.is_some(), &[Jerlov]),
        (
            "--depth-scale",
            o.depth_scale.is_some(),
            &[Uwnr, Jerlov, Seathru],
        ),
        ("--seathru", o.seathru.is_some(), &[Seathru]),
        ("--beta-d", o.beta_d.is_some(), &[Seathru]),
        ("--beta-b", o.beta_b.is_some(), &[Seathru]),
        ("--b-inf", o.b_inf.is_some(), &[Seathru]),
        ("--reinhard-space", o.reinhard_space.is_some(), &[Reinhard]),
        ("--mean-only", o.mean_only, &[Reinhard]),
    ];
    let names = || {
        methods
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(",")
    };
    for (flag, set, applies) in flags {
        if set && !methods.iter().any(|m| applies.contains(m)) {
            let to = applies.iter().map(|m| m.name()).collect::<Vec<_>>();
            bail!(
                "{flag} does not apply to --method {} (only to {})",
                names(),
                to.join(", ")
            );
        }
    }
    if o.depth_scale.is_some()
        && methods.contains(&Seathru)
        && !methods.contains(&Jerlov)
        && !methods.contains(&Uwnr)
        && seathru_fitted
    {
        bail!(
            "--depth-scale does not apply to --method seathru with coefficients from the \
             reference (the fit gives the distance)"
        );
    }
    if o.background_depth.is_some() {
        let jerlov = methods.contains(&Jerlov);
        let seathru = methods.contains(&Seathru);
        if seathru && !jerlov && seathru_given {
            bail!("--background-depth does not apply to --method seathru with --seathru given");
        }
        if !jerlov && !seathru {
            bail!(
                "--background-depth does not apply to --method {} (only to jerlov, seathru)",
                names()
            );
        }
    }
    Ok(())
}

/// Method `kind` with its flags applied: the networks take the model options and `precision`,
/// the other methods `--method-config` and their own flags. Callers first refuse flags that
/// apply to none of their methods ([`refuse_inapplicable`]).
pub fn method_spec(
    kind: MethodKind,
    o: &BaselineOpts,
    model: &ModelOpts,
    precision: PrecisionArg,
    have_reference: bool,
) -> Result<MethodSpec> {
    let mut spec = match &o.method_config {
        Some(path) if !kind.loads_weights() => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            MethodSpec::from_json(&text, Some(kind))
                .with_context(|| format!("method config {}", path.display()))?
        }
        _ => MethodSpec::defaults(kind, have_reference),
    };
    if kind.loads_weights() && model.device != DeviceArg::Engine {
        bail!(
            "renders run on the engine (uwnr-engine): --device flex|tch chooses where training runs \
             (uwnr train, enhance, gan, experiment); drop it here"
        );
    }
    match &mut spec {
        MethodSpec::Uwnr(s) => {
            s.weights.clone_from(&model.weights);
            s.precision = precision.into();
            s.max_whole_pixels = model.max_whole_pixels;
            s.tile = model.tile;
            s.overlap = model.overlap;
        }
        MethodSpec::Uwgan(s) => {
            if precision == PrecisionArg::Bf16 {
                bail!(
                    "--precision bf16 applies to --method uwnr only (the UWGAN generator runs in f32)"
                );
            }
            s.weights.clone_from(&model.weights);
        }
        MethodSpec::Jerlov(p) => {
            if let Some(t) = o.water_type {
                p.water_type = Some(WaterType::from(t));
            }
            if let Some(r) = o.depth_scale {
                p.depth_scale = range(r);
            }
            if let Some(r) = o.background_depth {
                p.background_depth = range(r);
            }
        }
        MethodSpec::Seathru(p) => {
            match o.seathru {
                Some(SeathruSource::Given) => {
                    let d = GivenCoefficients::default();
                    p.coefficients = SeathruCoefficients::Given(GivenCoefficients {
                        beta_d: o.beta_d.unwrap_or(d.beta_d),
                        beta_b: o.beta_b.unwrap_or(d.beta_b),
                        b_inf: o.b_inf.unwrap_or(d.b_inf),
                    });
                }
                Some(SeathruSource::Sampled) => {
                    p.coefficients = SeathruCoefficients::Sampled(SampledCoefficients::default());
                }
                Some(SeathruSource::Reference) => {
                    p.coefficients =
                        SeathruCoefficients::FromReference(ReferenceCoefficients::default());
                }
                None => {}
            }
            if o.seathru != Some(SeathruSource::Given)
                && (o.beta_d.is_some() || o.beta_b.is_some() || o.b_inf.is_some())
            {
                bail!("--beta-d, --beta-b and --b-inf need --seathru given");
            }
            if let Some(r) = o.depth_scale {
                p.depth_scale = range(r);
            }
            if let Some(r) = o.background_depth {
                match &mut p.coefficients {
                    SeathruCoefficients::Sampled(s) => s.background_depth = range(r),
                    SeathruCoefficients::FromReference(s) => s.background_depth = range(r),
                    SeathruCoefficients::Given(_) => {}
                }
            }
        }
        MethodSpec::Reinhard(p) => {
            if let Some(s) = o.reinhard_space {
                p.space = ColourSpace::from(s);
            }
            if o.mean_only {
                p.match_std = false;
            }
        }
        // The methods with no flags of their own (their settings come from --method-config), so
        // that a method added to uwnr-render needs nothing here.
        _ => {}
    }
    if !kind.loads_weights()
        && spec.reference_use() == uwnr_render::ReferenceUse::Required
        && !have_reference
    {
        bail!("--method {kind} needs --reference");
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
