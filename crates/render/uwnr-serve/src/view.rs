//! What the page asks to render, and the command lines that render the same thing: the method
//! options are `uwnr_render::MethodOptions`, the type `uwnr render`'s flags become, so they set a
//! [`MethodSpec`] and write back as flags as the command line does.

use serde::{Deserialize, Serialize};
pub use uwnr_render::MethodOptions;
use uwnr_render::{DepthPolicy, MethodKind, MethodSpec, ReferenceUse};

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

/// The six methods the page compares (the haze control is left out).
pub const PAGE_METHODS: [MethodKind; 6] = [
    MethodKind::Uwnr,
    MethodKind::Uwgan,
    MethodKind::Jerlov,
    MethodKind::Uisa,
    MethodKind::Seathru,
    MethodKind::Reinhard,
];

/// The method spec of the page's options, as `uwnr render` builds it from the same flags with a
/// reference given (Sea-thru then fits its coefficients to the reference): refused when the page
/// does not render the method or the method lacks an option.
pub fn page_spec(o: &MethodOptions) -> Result<MethodSpec> {
    if !PAGE_METHODS.contains(&o.method) {
        return Err(ServeError::BadRequest(format!(
            "method {} is not one the page renders",
            o.method
        )));
    }
    o.spec(true)
        .map_err(|e| ServeError::BadRequest(e.to_string()))
}

/// The depth policy a render of the page's options uses: `uwnr render`'s, with `--depth-scale`
/// as its scene scale in the `f32` metres renders use, checked there by the check every render
/// job's policy gets ([`DepthPolicy::validate`], which bounds it by
/// `uwnr_render::MAX_SCENE_SCALE_M`). So a range that only `f64` holds, or past any water, is
/// refused when it is asked for.
pub fn page_policy(o: &MethodOptions) -> Result<DepthPolicy> {
    let mut policy = DepthPolicy::render();
    let Some((a, b)) = o.depth_scale else {
        return Ok(policy);
    };
    // `as` saturates: past f32's range is infinite, which the check refuses.
    policy.scene_scale_m = (a as f32, b as f32);
    let bad = |why: String| ServeError::BadRequest(format!("--depth-scale {a},{b}: {why}"));
    policy.validate().map_err(|e| bad(e.to_string()))?;
    Ok(policy)
}

/// Whether the render of the page's options reads the reference.
pub fn reads_reference(o: &MethodOptions) -> Result<bool> {
    Ok(page_spec(o)?.reference_use() != ReferenceUse::Ignored)
}

/// A render request with its method and depth policy, read from its options once, when the
/// request arrives: the handler, the command lines it answers with and the pool's worker all use
/// these.
#[derive(Clone, Debug)]
pub struct PageRender {
    /// The request as the page sent it.
    pub view: ViewRequest,
    /// Its method ([`page_spec`]).
    pub spec: MethodSpec,
    /// Its depth policy ([`page_policy`]).
    pub policy: DepthPolicy,
}

impl PageRender {
    /// Reads `view`'s options, refusing what the page does not render.
    pub fn new(view: ViewRequest) -> Result<Self> {
        let spec = page_spec(&view.options)?;
        let policy = page_policy(&view.options)?;
        Ok(Self { view, spec, policy })
    }

    /// Whether the render reads the reference.
    #[must_use]
    pub fn reads_reference(&self) -> bool {
        self.spec.reference_use() != ReferenceUse::Ignored
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
    fn the_page_renders_its_six_methods_with_the_clis_rules() {
        let o = options(r#"{"method":"jerlov","seed":3,"water_type":"3C","depth_scale":[2,6]}"#);
        assert!(matches!(page_spec(&o).unwrap(), MethodSpec::Jerlov(_)));
        assert!(!reads_reference(&options(r#"{"method":"uwgan"}"#)).unwrap());
        assert!(reads_reference(&options(r#"{"method":"seathru"}"#)).unwrap());
        let e = page_spec(&options(r#"{"method":"haze"}"#)).unwrap_err();
        assert!(e.to_string().contains("not one the page renders"), "{e}");
        let e = page_spec(&options(r#"{"method":"uisa","water_type":"I"}"#)).unwrap_err();
        assert_eq!(e.status(), 400);
        assert!(e.to_string().contains("--water-type does not apply"), "{e}");
        assert!(page_spec(&options(r#"{"method":"uwnr","depth_scale":[0,1]}"#)).is_err());
    }

    #[test]
    fn the_scene_scale_is_checked_in_the_f32_metres_renders_use() {
        let policy = |json: &str| page_policy(&options(json));
        let p = policy(r#"{"method":"uwnr","depth_scale":[1.5,8]}"#).unwrap();
        assert_eq!(p.scene_scale_m, (1.5, 8.0));
        assert_eq!(
            policy(r#"{"method":"jerlov"}"#).unwrap(),
            DepthPolicy::render()
        );
        for bad in ["[1,1e300]", "[1e30,1e31]", "[1,1001]", "[0,2]", "[3,2]"] {
            let e = policy(&format!(r#"{{"method":"uwnr","depth_scale":{bad}}}"#)).unwrap_err();
            assert_eq!(e.status(), 400, "{bad}");
            assert!(e.to_string().starts_with("--depth-scale "), "{e}");
        }
    }

    #[test]
    fn words_are_quoted_for_the_shell_only_when_needed() {
        assert_eq!(shell_quote("a/b-c.png"), "a/b-c.png");
        assert_eq!(shell_quote("my photo.jpg"), "'my photo.jpg'");
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
        assert_eq!(shell_quote(""), "''");
    }
}
