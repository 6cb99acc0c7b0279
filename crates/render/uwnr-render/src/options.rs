//! The options a user sets on a method, in one type: how they read from the command line's flags
//! (`uwnr render`, `dataset`, `experiment`), from the page's form (`uwnr serve`, as JSON), which
//! ones a method has, how they set a [`MethodSpec`], and how they write back as flags (the
//! page's copyable commands).
//!
//! The JSON form names each option as its flag does, in snake case
//! (`{"method": "jerlov", "water_type": "3C", "depth_scale": [2, 6]}`). A method's full settings
//! (what `--method-config` files and Python's keywords hold) are [`MethodSpec`]'s own fields;
//! these options are the few a user sets most, applied over them.

use serde::{Deserialize, Serialize};
use uwnr_baselines::{
    ColourSpace, GivenCoefficients, Range, ReferenceCoefficients, SampledCoefficients,
    SeathruCoefficients, WaterType,
};

use crate::error::{RenderError, Result};
use crate::method::{MethodKind, MethodSpec, Precision, ReferenceUse};

/// Where Sea-thru's coefficients come from (`--seathru`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SeathruSource {
    /// Sampled per image from the documented ranges.
    Sampled,
    /// Fitted from the reference image.
    Reference,
    /// Given with `beta_d`, `beta_b` and `b_inf`.
    Given,
}

/// A method and the options set on it (each `None`/`false`/default: the method's own setting).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MethodOptions {
    pub method: MethodKind,
    /// `--seed`: the render's random parameters are drawn from it.
    #[serde(default)]
    pub seed: u64,
    /// `--water-type` (jerlov); `None`: drawn from the seed.
    #[serde(default)]
    pub water_type: Option<WaterType>,
    /// `--depth-scale MIN,MAX` in metres (uwnr: the scene scale of relative depth; jerlov and
    /// seathru: their distance scale).
    #[serde(default)]
    pub depth_scale: Option<(f64, f64)>,
    /// `--background-depth MIN,MAX` in metres (jerlov, seathru).
    #[serde(default)]
    pub background_depth: Option<(f64, f64)>,
    /// `--seathru` (seathru).
    #[serde(default)]
    pub seathru: Option<SeathruSource>,
    /// `--beta-d R,G,B` (seathru given).
    #[serde(default)]
    pub beta_d: Option<[f64; 3]>,
    /// `--beta-b R,G,B` (seathru given).
    #[serde(default)]
    pub beta_b: Option<[f64; 3]>,
    /// `--b-inf R,G,B` (seathru given).
    #[serde(default)]
    pub b_inf: Option<[f64; 3]>,
    /// `--reinhard-space` (reinhard).
    #[serde(default)]
    pub reinhard_space: Option<ColourSpace>,
    /// `--mean-only` (reinhard).
    #[serde(default)]
    pub mean_only: bool,
    /// `--precision` (uwnr).
    #[serde(default)]
    pub precision: Precision,
}

use MethodKind::{Jerlov, Reinhard, Seathru, Uwnr};

fn range((min, max): (f64, f64)) -> Range {
    Range { min, max }
}

fn invalid(message: String) -> RenderError {
    RenderError::Invalid(message)
}

impl MethodOptions {
    /// The options with `method` as the method.
    #[must_use]
    pub fn with_method(&self, method: MethodKind) -> Self {
        Self {
            method,
            ..self.clone()
        }
    }

    /// `(flag, is it set, the methods it applies to)` for every option but the seed.
    fn applicability(&self) -> [(&'static str, bool, &'static [MethodKind]); 10] {
        [
            ("--water-type", self.water_type.is_some(), &[Jerlov]),
            (
                "--depth-scale",
                self.depth_scale.is_some(),
                &[Uwnr, Jerlov, Seathru],
            ),
            (
                "--background-depth",
                self.background_depth.is_some(),
                &[Jerlov, Seathru],
            ),
            ("--seathru", self.seathru.is_some(), &[Seathru]),
            ("--beta-d", self.beta_d.is_some(), &[Seathru]),
            ("--beta-b", self.beta_b.is_some(), &[Seathru]),
            ("--b-inf", self.b_inf.is_some(), &[Seathru]),
            (
                "--reinhard-space",
                self.reinhard_space.is_some(),
                &[Reinhard],
            ),
            ("--mean-only", self.mean_only, &[Reinhard]),
            ("--precision", self.precision != Precision::F32, &[Uwnr]),
        ]
    }

    /// Refuses an option that none of `methods` has (a run may render several), naming the
    /// option and the methods it applies to: an option that does not apply is a mistake, not
    /// something to ignore. `seathru_fitted`: Sea-thru takes its coefficients from the reference
    /// (it then gives the distance itself).
    pub fn refuse_inapplicable(&self, methods: &[MethodKind], seathru_fitted: bool) -> Result<()> {
        let names = || {
            methods
                .iter()
                .map(|m| m.name())
                .collect::<Vec<_>>()
                .join(",")
        };
        for (flag, set, applies) in self.applicability() {
            if set && !methods.iter().any(|m| applies.contains(m)) {
                let to = applies.iter().map(|m| m.name()).collect::<Vec<_>>();
                return Err(invalid(format!(
                    "{flag} does not apply to --method {} (only to {})",
                    names(),
                    to.join(", ")
                )));
            }
        }
        let only_seathru = |m: &[MethodKind]| m.contains(&Seathru) && !m.contains(&Jerlov);
        if self.depth_scale.is_some()
            && only_seathru(methods)
            && !methods.contains(&Uwnr)
            && seathru_fitted
        {
            return Err(invalid(
                "--depth-scale does not apply to --method seathru with coefficients from the \
                 reference (the fit gives the distance)"
                    .into(),
            ));
        }
        if self.background_depth.is_some()
            && only_seathru(methods)
            && self.seathru == Some(SeathruSource::Given)
        {
            return Err(invalid(
                "--background-depth does not apply to --method seathru with --seathru given".into(),
            ));
        }
        if self.seathru != Some(SeathruSource::Given)
            && methods.contains(&Seathru)
            && (self.beta_d.is_some() || self.beta_b.is_some() || self.b_inf.is_some())
        {
            return Err(invalid(
                "--beta-d, --beta-b and --b-inf need --seathru given".into(),
            ));
        }
        for (flag, r) in [
            ("--depth-scale", self.depth_scale),
            ("--background-depth", self.background_depth),
        ] {
            if let Some((a, b)) = r
                && !(a.is_finite() && b.is_finite() && a > 0.0 && a <= b)
            {
                return Err(invalid(format!(
                    "{flag} {a},{b} must be positive metres with MIN <= MAX"
                )));
            }
        }
        Ok(())
    }

    /// Sets the options on `spec` (the method's defaults or a `--method-config`); options the
    /// method does not have are left alone (a run of several methods sets each its own; refuse
    /// the others first with [`Self::refuse_inapplicable`]).
    fn apply(&self, spec: &mut MethodSpec) {
        match spec {
            MethodSpec::Uwnr(s) => s.precision = self.precision,
            MethodSpec::Jerlov(p) => {
                if let Some(t) = self.water_type {
                    p.water_type = Some(t);
                }
                if let Some(r) = self.depth_scale {
                    p.depth_scale = range(r);
                }
                if let Some(r) = self.background_depth {
                    p.background_depth = range(r);
                }
            }
            MethodSpec::Seathru(p) => {
                match self.seathru {
                    Some(SeathruSource::Given) => {
                        let d = GivenCoefficients::default();
                        p.coefficients = SeathruCoefficients::Given(GivenCoefficients {
                            beta_d: self.beta_d.unwrap_or(d.beta_d),
                            beta_b: self.beta_b.unwrap_or(d.beta_b),
                            b_inf: self.b_inf.unwrap_or(d.b_inf),
                        });
                    }
                    Some(SeathruSource::Sampled) => {
                        p.coefficients =
                            SeathruCoefficients::Sampled(SampledCoefficients::default());
                    }
                    Some(SeathruSource::Reference) => {
                        p.coefficients =
                            SeathruCoefficients::FromReference(ReferenceCoefficients::default());
                    }
                    None => {}
                }
                if let Some(r) = self.depth_scale {
                    p.depth_scale = range(r);
                }
                if let Some(r) = self.background_depth {
                    match &mut p.coefficients {
                        SeathruCoefficients::Sampled(s) => s.background_depth = range(r),
                        SeathruCoefficients::FromReference(s) => s.background_depth = range(r),
                        SeathruCoefficients::Given(_) => {}
                    }
                }
            }
            MethodSpec::Reinhard(p) => {
                if let Some(s) = self.reinhard_space {
                    p.space = s;
                }
                if self.mean_only {
                    p.match_std = false;
                }
            }
            // The methods with no options of their own (their settings come from a
            // `--method-config`), so that a method added needs nothing here.
            _ => {}
        }
    }

    /// Whether Sea-thru takes its coefficients from the reference when these options are set on
    /// `base` (the method's defaults or a `--method-config`): then the fit gives the distance, and
    /// `--depth-scale` does not apply ([`Self::refuse_inapplicable`]).
    #[must_use]
    pub fn seathru_fitted(&self, base: &MethodSpec) -> bool {
        match self.seathru {
            Some(s) => s == SeathruSource::Reference,
            None => matches!(
                base,
                MethodSpec::Seathru(p)
                    if matches!(p.coefficients, SeathruCoefficients::FromReference(_))
            ),
        }
    }

    /// The method's defaults with the options set, as `uwnr render` builds it (`have_reference`:
    /// a reference is given, so Sea-thru fits its coefficients to it unless told otherwise).
    /// Options the method lacks are refused.
    pub fn spec(&self, have_reference: bool) -> Result<MethodSpec> {
        let base = MethodSpec::defaults(self.method, have_reference);
        self.refuse_inapplicable(&[self.method], self.seathru_fitted(&base))?;
        self.spec_over(base, have_reference)
    }

    /// The options set on `base` (the method's defaults or a `--method-config`), refused when the
    /// render needs a reference and none is given: the one place `uwnr render`, `dataset`,
    /// `experiment` and the page check it before anything loads. Callers refuse the options
    /// none of their methods has first ([`Self::refuse_inapplicable`]; a run of several
    /// methods sets each method its own and leaves it the others).
    pub fn spec_over(&self, mut base: MethodSpec, have_reference: bool) -> Result<MethodSpec> {
        self.apply(&mut base);
        if base.reference_use() == ReferenceUse::Required && !have_reference {
            return Err(invalid(format!(
                "--method {} needs a reference, a real underwater image whose water is rendered \
                 (--reference; --references for a dataset)",
                self.method
            )));
        }
        Ok(base)
    }

    /// The flags of `uwnr render` and `uwnr dataset` that set these options (`--method` first;
    /// without `--seed`, which callers place).
    #[must_use]
    pub fn flags(&self) -> Vec<String> {
        let mut f = vec!["--method".to_string(), self.method.name().to_string()];
        let mut push = |flag: &str, value: String| {
            f.push(flag.to_string());
            f.push(value);
        };
        if let Some(t) = self.water_type {
            push("--water-type", json_name(&t));
        }
        for (flag, r) in [
            ("--depth-scale", self.depth_scale),
            ("--background-depth", self.background_depth),
        ] {
            if let Some((a, b)) = r {
                push(
                    flag,
                    if a == b {
                        format!("{a}")
                    } else {
                        format!("{a},{b}")
                    },
                );
            }
        }
        if let Some(s) = self.seathru {
            push("--seathru", json_name(&s));
        }
        for (flag, v) in [
            ("--beta-d", self.beta_d),
            ("--beta-b", self.beta_b),
            ("--b-inf", self.b_inf),
        ] {
            if let Some([r, g, b]) = v {
                push(flag, format!("{r},{g},{b}"));
            }
        }
        if let Some(s) = self.reinhard_space {
            push("--reinhard-space", json_name(&s));
        }
        if self.mean_only {
            f.push("--mean-only".into());
        }
        if self.precision != Precision::F32 {
            f.push("--precision".into());
            f.push(json_name(&self.precision));
        }
        f
    }
}

/// The serde name of a unit enum value (the command line's value names are the same).
fn json_name<T: Serialize>(v: &T) -> String {
    match serde_json::to_value(v) {
        Ok(serde_json::Value::String(s)) => s,
        other => format!("{other:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(json: &str) -> MethodOptions {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn options_set_the_spec_and_write_back_as_flags() {
        let o = options(
            r#"{"method":"jerlov","water_type":"3C","depth_scale":[2,6],"background_depth":[8,9]}"#,
        );
        let MethodSpec::Jerlov(p) = o.spec(false).unwrap() else {
            panic!()
        };
        assert_eq!(p.water_type, Some(WaterType::C3));
        assert_eq!((p.depth_scale.min, p.background_depth.max), (2.0, 9.0));
        assert_eq!(
            o.flags().join(" "),
            "--method jerlov --water-type 3C --depth-scale 2,6 --background-depth 8,9"
        );
        let o = options(
            r#"{"method":"seathru","seathru":"given","beta_d":[0.1,0.2,0.3],"depth_scale":[3,3]}"#,
        );
        let MethodSpec::Seathru(p) = o.spec(true).unwrap() else {
            panic!()
        };
        assert!(
            matches!(p.coefficients, SeathruCoefficients::Given(g) if g.beta_d == [0.1, 0.2, 0.3])
        );
        assert_eq!(
            o.flags().join(" "),
            "--method seathru --depth-scale 3 --seathru given --beta-d 0.1,0.2,0.3"
        );
        let o = options(r#"{"method":"reinhard","reinhard_space":"lab","mean_only":true}"#);
        assert_eq!(
            o.flags().join(" "),
            "--method reinhard --reinhard-space lab --mean-only"
        );
        let o = options(r#"{"method":"uwnr","precision":"bf16","depth_scale":[1,4]}"#);
        let MethodSpec::Uwnr(s) = o.spec(true).unwrap() else {
            panic!()
        };
        assert_eq!(s.precision, Precision::Bf16);
    }

    #[test]
    fn options_a_method_lacks_are_refused_in_one_line() {
        let err =
            |json: &str, reference: bool| options(json).spec(reference).unwrap_err().to_string();
        assert_eq!(
            err(r#"{"method":"uisa","water_type":"3C"}"#, true),
            "--water-type does not apply to --method uisa (only to jerlov)"
        );
        assert!(err(r#"{"method":"uwgan","precision":"bf16"}"#, true).contains("--precision"));
        assert!(err(r#"{"method":"seathru","depth_scale":[2,4]}"#, true).contains("the fit gives"));
        assert!(
            options(r#"{"method":"seathru","depth_scale":[2,4]}"#)
                .spec(false)
                .is_ok()
        );
        assert!(
            err(r#"{"method":"seathru","beta_d":[1,1,1]}"#, true).contains("need --seathru given")
        );
        assert!(err(r#"{"method":"jerlov","depth_scale":[4,2]}"#, true).contains("MIN <= MAX"));
        assert!(err(r#"{"method":"reinhard"}"#, false).contains("needs a reference"));
        assert!(err(r#"{"method":"uwnr"}"#, false).contains("needs a reference"));
        assert!(options(r#"{"method":"uwgan"}"#).spec(false).is_ok());
        // Several methods: an option one of them has is accepted.
        let o = options(r#"{"method":"uisa","water_type":"3C"}"#);
        assert!(
            o.refuse_inapplicable(&[MethodKind::Uisa, Jerlov], true)
                .is_ok()
        );
        assert!(serde_json::from_str::<MethodOptions>(r#"{"method":"uisa","wter":1}"#).is_err());
    }
}
