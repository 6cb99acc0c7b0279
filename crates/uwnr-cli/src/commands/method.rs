//! Mapping the baseline flags of `uwnr render` onto `uwnr_baselines::Method`.

use anyhow::{Context, Result, bail};
use uwnr_baselines::{
    ColourSpace, GivenCoefficients, JerlovParams, Method, Range, ReferenceCoefficients,
    ReinhardParams, SampledCoefficients, SeathruCoefficients, SeathruParams, UisaParams, WaterType,
};

use crate::cli::{BaselineOpts, MethodArg, SeathruSource};

fn range((min, max): (f64, f64)) -> Range {
    Range { min, max }
}

/// Refuses a baseline option that none of `methods` uses, with one line naming the option and
/// the method(s): an option that does not apply is a mistake, not something to ignore.
pub fn refuse_inapplicable(
    methods: &[MethodArg],
    o: &BaselineOpts,
    have_reference: bool,
) -> Result<()> {
    use MethodArg::{Jerlov, Reinhard, Seathru, Uisa, Uwnr};
    let seathru_given = o.seathru == Some(SeathruSource::Given);
    // Sea-thru takes its coefficients from the reference when one is given, unless told.
    let seathru_fitted = match o.seathru {
        Some(SeathruSource::Reference) => true,
        Some(_) => false,
        None => have_reference && o.method_config.is_none(),
    };
    // (flag, is it set, the methods it applies to)
    let flags: [(&str, bool, &[MethodArg]); 9] = [
        (
            "--method-config",
            o.method_config.is_some(),
            &[Jerlov, Uisa, Seathru, Reinhard],
        ),
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
            .map(|&m| method_name(m))
            .collect::<Vec<_>>()
            .join(",")
    };
    for (flag, set, applies) in flags {
        if set && !methods.iter().any(|m| applies.contains(m)) {
            let to = applies.iter().map(|&m| method_name(m)).collect::<Vec<_>>();
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

/// The name `--method` gives a method.
#[must_use]
pub fn method_name(m: MethodArg) -> &'static str {
    match m {
        MethodArg::Uwnr => "uwnr",
        MethodArg::Uwgan => "uwgan",
        MethodArg::Jerlov => "jerlov",
        MethodArg::Uisa => "uisa",
        MethodArg::Seathru => "seathru",
        MethodArg::Reinhard => "reinhard",
    }
}

/// The baseline named by `--method` with its flags applied; `None` for the networks (`uwnr`,
/// `uwgan`). Callers first
/// refuse flags that apply to none of their methods ([`refuse_inapplicable`]).
pub fn baseline_method(
    method: MethodArg,
    o: &BaselineOpts,
    have_reference: bool,
) -> Result<Option<Method>> {
    let from_file = match &o.method_config {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            let m: Method = serde_json::from_str(&text)
                .with_context(|| format!("parsing method config {}", path.display()))?;
            Some(m)
        }
        None => None,
    };
    let mut m = match method {
        MethodArg::Uwnr | MethodArg::Uwgan => return Ok(None),
        MethodArg::Jerlov => match from_file {
            Some(m @ Method::Jerlov(_)) => m,
            None => Method::Jerlov(JerlovParams::default()),
            Some(other) => bail!("--method-config is for {}, not jerlov", other.name()),
        },
        MethodArg::Uisa => match from_file {
            Some(m @ Method::Uisa(_)) => m,
            None => Method::Uisa(UisaParams::default()),
            Some(other) => bail!("--method-config is for {}, not uisa", other.name()),
        },
        MethodArg::Seathru => match from_file {
            Some(m @ Method::Seathru(_)) => m,
            None => Method::Seathru(SeathruParams {
                coefficients: if have_reference {
                    SeathruCoefficients::FromReference(ReferenceCoefficients::default())
                } else {
                    SeathruCoefficients::Sampled(SampledCoefficients::default())
                },
                ..SeathruParams::default()
            }),
            Some(other) => bail!("--method-config is for {}, not seathru", other.name()),
        },
        MethodArg::Reinhard => match from_file {
            Some(m @ Method::Reinhard(_)) => m,
            None => Method::Reinhard(ReinhardParams::default()),
            Some(other) => bail!("--method-config is for {}, not reinhard", other.name()),
        },
    };
    match &mut m {
        Method::Jerlov(p) => {
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
        Method::Seathru(p) => {
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
        Method::Reinhard(p) => {
            if let Some(s) = o.reinhard_space {
                p.space = ColourSpace::from(s);
            }
            if o.mean_only {
                p.match_std = false;
            }
        }
        Method::Uisa(_) => {}
    }
    if m.needs_reference() && !have_reference {
        bail!("--method {} needs --reference", m.name());
    }
    Ok(Some(m))
}
