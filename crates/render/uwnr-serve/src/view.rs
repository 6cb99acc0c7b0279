//! What the page asks to render, and the command lines that render the same thing: the method
//! options map onto a [`MethodSpec`] exactly as `uwnr render`'s flags do (`uwnr-cli`'s
//! `commands/method.rs`), and onto those flags.

use serde::{Deserialize, Serialize};
use uwnr_baselines::{ColourSpace, Range, WaterType};
use uwnr_render::{MethodKind, MethodSpec, Precision, ReferenceUse};

use crate::error::{Result, ServeError};

/// Where the clean image comes from.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CleanSource {
    /// Image `index` of the `--clean` folder.
    Index(usize),
    /// An image dropped into the page.
    Upload(String),
}

/// Where the depth comes from.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthChoice {
    /// The built-in prior.
    #[default]
    Prior,
    /// The map in `depth/` beside the clean image (`X/rgb/NAME` with `X/depth/`).
    Beside,
    /// A map dropped into the page.
    Upload(String),
}

/// How large a render is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderSize {
    /// The clean image shrunk to the preview size (longer side).
    #[default]
    Preview,
    /// The clean image's own size: what the shown `uwnr render` command writes.
    Full,
}

/// One method with the options the page shows for it (the flags of `uwnr render`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MethodOptions {
    pub method: MethodKind,
    /// `--seed`: the render's random parameters are drawn from `item_seed(seed, 0)`.
    #[serde(default)]
    pub seed: u64,
    /// `--water-type` (jerlov); `None`: drawn from the seed.
    #[serde(default)]
    pub water_type: Option<WaterType>,
    /// `--depth-scale MIN,MAX` in metres (uwnr: the scene scale of relative depth; jerlov: its
    /// distance scale).
    #[serde(default)]
    pub depth_scale: Option<(f64, f64)>,
    /// `--precision` (uwnr).
    #[serde(default)]
    pub precision: Precision,
    /// `--reinhard-space` (reinhard).
    #[serde(default)]
    pub reinhard_space: Option<ColourSpace>,
    /// `--mean-only` (reinhard).
    #[serde(default)]
    pub mean_only: bool,
}

/// A render the page asks for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewRequest {
    /// The cell of the page this render fills: a newer request for it makes older ones stale.
    pub view: String,
    pub clean: CleanSource,
    #[serde(default)]
    pub depth: DepthChoice,
    /// Index in the `--references` folder (ignored by methods that read no reference).
    #[serde(default)]
    pub reference: Option<usize>,
    /// The method and its options.
    pub options: MethodOptions,
    #[serde(default)]
    pub size: RenderSize,
    /// The dataset the page would make: K references per clean image drawn with this seed.
    #[serde(default)]
    pub dataset: Option<DatasetDraw>,
}

/// `uwnr dataset`'s reference draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DatasetDraw {
    pub k: usize,
    pub seed: u64,
}

const JERLOV: &[MethodKind] = &[MethodKind::Jerlov];
const DEPTH_SCALED: &[MethodKind] = &[MethodKind::Uwnr, MethodKind::Jerlov];
const REINHARD: &[MethodKind] = &[MethodKind::Reinhard];
const UWNR: &[MethodKind] = &[MethodKind::Uwnr];

/// The six methods the page compares (the haze control is left out).
pub const PAGE_METHODS: [MethodKind; 6] = [
    MethodKind::Uwnr,
    MethodKind::Uwgan,
    MethodKind::Jerlov,
    MethodKind::Uisa,
    MethodKind::Seathru,
    MethodKind::Reinhard,
];

impl MethodOptions {
    /// Refuses an option the method does not have, as `uwnr render` refuses its flag.
    pub fn check(&self) -> Result<()> {
        let m = self.method;
        let flags: [(&str, bool, &[MethodKind]); 5] = [
            ("water_type", self.water_type.is_some(), JERLOV),
            ("depth_scale", self.depth_scale.is_some(), DEPTH_SCALED),
            ("precision", self.precision != Precision::F32, UWNR),
            ("reinhard_space", self.reinhard_space.is_some(), REINHARD),
            ("mean_only", self.mean_only, REINHARD),
        ];
        for (name, set, applies) in flags {
            if set && !applies.contains(&m) {
                return Err(ServeError::BadRequest(format!(
                    "option {name} does not apply to method {m}"
                )));
            }
        }
        if !PAGE_METHODS.contains(&m) {
            return Err(ServeError::BadRequest(format!(
                "method {m} is not one the page renders"
            )));
        }
        if let Some((a, b)) = self.depth_scale
            && !(a.is_finite() && b.is_finite() && a > 0.0 && a <= b)
        {
            return Err(ServeError::BadRequest(format!(
                "depth scale {a},{b} must be positive metres with MIN <= MAX"
            )));
        }
        Ok(())
    }

    /// The method spec, as `uwnr render` builds it from the same flags with a reference given
    /// (Sea-thru then fits its coefficients to the reference).
    pub fn spec(&self) -> Result<MethodSpec> {
        self.check()?;
        let mut spec = MethodSpec::defaults(self.method, true);
        match &mut spec {
            MethodSpec::Uwnr(s) => s.precision = self.precision,
            MethodSpec::Jerlov(p) => {
                if let Some(t) = self.water_type {
                    p.water_type = Some(t);
                }
                if let Some((min, max)) = self.depth_scale {
                    p.depth_scale = Range { min, max };
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
            _ => {}
        }
        Ok(spec)
    }

    /// Whether the render reads the reference.
    pub fn reads_reference(&self) -> Result<bool> {
        Ok(self.spec()?.reference_use() != ReferenceUse::Ignored)
    }

    /// The method flags of `uwnr render` and `uwnr dataset` (without `--seed`).
    #[must_use]
    pub fn flags(&self) -> Vec<String> {
        let mut f = vec!["--method".to_string(), self.method.name().to_string()];
        if let Some(t) = self.water_type {
            f.push("--water-type".into());
            f.push(json_name(&t));
        }
        if let Some((a, b)) = self.depth_scale {
            f.push("--depth-scale".into());
            f.push(if a == b {
                format!("{a}")
            } else {
                format!("{a},{b}")
            });
        }
        if self.precision != Precision::F32 {
            f.push("--precision".into());
            f.push(json_name(&self.precision));
        }
        if let Some(s) = self.reinhard_space {
            f.push("--reinhard-space".into());
            f.push(json_name(&s));
        }
        if self.mean_only {
            f.push("--mean-only".into());
        }
        f
    }
}

/// The serde name of a unit enum value (the CLI's value names are the same).
fn json_name<T: Serialize>(v: &T) -> String {
    match serde_json::to_value(v) {
        Ok(serde_json::Value::String(s)) => s,
        other => format!("{other:?}"),
    }
}

/// `s` quoted for a POSIX shell when it needs to be.
#[must_use]
pub fn shell_quote(s: &str) -> String {
    let safe = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-./,:=+@%".contains(c));
    if safe {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// A command line from words, each quoted as needed.
#[must_use]
pub fn command_line(words: &[String]) -> String {
    words
        .iter()
        .map(|w| shell_quote(w))
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(json: &str) -> MethodOptions {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn options_map_to_the_clis_flags_and_specs() {
        let o = options(r#"{"method":"jerlov","seed":3,"water_type":"3C","depth_scale":[2,6]}"#);
        assert_eq!(
            o.flags().join(" "),
            "--method jerlov --water-type 3C --depth-scale 2,6"
        );
        let MethodSpec::Jerlov(p) = o.spec().unwrap() else {
            panic!()
        };
        assert_eq!(p.water_type, Some(WaterType::C3));
        assert_eq!((p.depth_scale.min, p.depth_scale.max), (2.0, 6.0));
        let r = options(r#"{"method":"reinhard","reinhard_space":"lab","mean_only":true}"#);
        assert_eq!(
            r.flags().join(" "),
            "--method reinhard --reinhard-space lab --mean-only"
        );
        let u = options(r#"{"method":"uwnr","precision":"bf16","depth_scale":[3,3]}"#);
        assert_eq!(
            u.flags().join(" "),
            "--method uwnr --depth-scale 3 --precision bf16"
        );
        assert!(!options(r#"{"method":"uwgan"}"#).reads_reference().unwrap());
        assert!(
            options(r#"{"method":"seathru"}"#)
                .reads_reference()
                .unwrap()
        );
    }

    #[test]
    fn options_a_method_lacks_are_refused() {
        let e = options(r#"{"method":"uisa","water_type":"I"}"#)
            .spec()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("water_type does not apply to method uisa"),
            "{e}"
        );
        assert!(options(r#"{"method":"haze"}"#).spec().is_err());
        assert!(
            options(r#"{"method":"uwnr","depth_scale":[0,1]}"#)
                .spec()
                .is_err()
        );
    }

    #[test]
    fn words_are_quoted_for_the_shell_only_when_needed() {
        assert_eq!(shell_quote("a/b-c.png"), "a/b-c.png");
        assert_eq!(shell_quote("my photo.jpg"), "'my photo.jpg'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote(""), "''");
    }
}
