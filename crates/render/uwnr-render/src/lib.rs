//! uwnr-render: what a render method is, in one place. [`MethodSpec`] is a method with every
//! setting it renders with (one variant per method, tagged `"method"` in JSON); [`Renderer`]
//! loads one and renders with it; [`RenderJob`] is the sequence around a render (the depth
//! policy, references prepared once, the item's seed). `uwnr render`, `uwnr dataset`, `uwnr
//! experiment`, the page and the Python package all go through these types, so a method added
//! here (its module and one variant) is a method everywhere.
//!
//! | method | module | reference | random per render |
//! |---|---|---|---|
//! | `uwnr`, the UWNR network | `uwnr_model` | required | scene scale of relative depth |
//! | `uwgan`, the GAN baseline | `uwnr_gan` | ignored | water code |
//! | `jerlov`, `uisa`, `seathru`, `reinhard` | `uwnr_baselines` | per method | per method |
//! | `revised`, Sea-thru with forward scattering and a medium | [`revised`] | per Sea-thru | Sea-thru's, the medium |
//! | `haze`, a control | [`haze`] | ignored | nothing |
//!
//! ```
//! use uwnr_core::Image;
//! use uwnr_render::{MethodKind, MethodSpec, Renderer};
//!
//! let spec = MethodSpec::defaults(MethodKind::Haze, false);
//! let renderer = Renderer::load(spec).unwrap();
//! let clean = Image::filled(8, 6, 3, 0.5);
//! let depth = Image::filled(8, 6, 1, 0.5);
//! let response = uwnr_model::DepthResponse::default();
//! let out = renderer.worker().render(&clean, &depth, &response, None, 7).unwrap();
//! assert_eq!(out.image.size(), (8, 6));
//! assert_eq!(out.params.to_value()["method"], "haze");
//! ```

pub mod camera;
pub mod depth_policy;
pub mod error;
pub mod haze;
pub mod job;
pub mod lru;
pub mod method;
pub mod options;
pub mod record;
pub mod renderer;
pub mod revised;

pub use camera::{Camera, CleanCamera};
pub use depth_policy::{
    DATASET_PRIOR_TRUST, DATASET_SCENE_SCALE_M, DepthPolicy, MAX_SCENE_SCALE_M,
};
pub use error::{RenderError, Result};
pub use haze::HazeParams;
pub use job::{JobWorker, ReferenceError, RenderJob};
pub use method::{
    CleanSide, ComputeDevice, MethodKind, MethodSpec, Precision, ReferenceUse, UwganSpec, UwnrSpec,
};
pub use options::{MethodOptions, SeathruSource};
pub use record::{MethodRecord, depth_record, fnv1a64};
pub use renderer::{PreparedReference, ReferenceInput, Rendered, Renderer, Worker};
pub use revised::RevisedParams;
