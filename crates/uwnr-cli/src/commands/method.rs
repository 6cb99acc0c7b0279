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

/// The baseline named by `--method` with its flags applied; `None` for `uwnr`.
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
        MethodArg::Uwnr => {
            if from_file.is_some() {
                bail!("--method-config needs --method jerlov|uisa|seathru|reinhard");
            }
            return Ok(None);
        }
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
            if let Some(t) = &o.water_type {
                let wt: WaterType = serde_json::from_value(serde_json::Value::String(t.clone()))
                    .with_context(|| {
                        format!("unknown water type {t:?} (I, IA, IB, II, III, 1C, 3C, 5C, 7C, 9C)")
                    })?;
                p.water_type = Some(wt);
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
            if let Some(s) = &o.reinhard_space {
                p.space = match s.to_ascii_lowercase().as_str() {
                    "lalphabeta" | "lab-ruderman" => ColourSpace::LAlphaBeta,
                    "lab" | "cielab" => ColourSpace::Lab,
                    "rgb" => ColourSpace::Rgb,
                    _ => bail!("unknown Reinhard colour space {s:?} (lalphabeta, lab or rgb)"),
                };
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
