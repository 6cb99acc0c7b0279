//! Monocular depth from a user-supplied ONNX model (MiDaS / DPT / Depth-Anything style), run on
//! the CPU with tract.
//!
//! ```text
//! x         = resize(clean RGB, model input size)                 antialiased bilinear
//! x_c       = (x_c - IMAGENET_MEAN[c]) / IMAGENET_STD[c]            NCHW f32, [1, 3, H, W]
//! disparity = model(x)                                              [1, H', W'] or [1, 1, H', W']
//! n         = min-max normalise(resize(disparity, clean size))      in [0, 1]
//! depth     = 1 - n            (models output relative inverse depth: near = large)
//! depth     = n                with `invert` (models that output depth: far = large)
//! ```
//!
//! Input size, in order of precedence:
//! 1. the model's own input shape when its height and width are fixed (the image is stretched
//!    to it, as fixed-size exports expect);
//! 2. `input_size` (width, height) for models with dynamic height and width, e.g. 518x518 for
//!    Depth Anything (whose patch size asks for multiples of 14);
//! 3. otherwise the MiDaS rule (`midas/transforms.py`, `Resize(384, 384, keep_aspect_ratio=True,
//!    ensure_multiple_of=32, resize_method="lower_bound")`): scale so the short side is
//!    [`DEFAULT_SHORT_SIDE`] px, keep the aspect ratio, round each side to a multiple of
//!    [`DEFAULT_MULTIPLE`], never below the short side.
//!
//! The model is loaded and optimised once; a dynamic model is optimised with symbolic height and
//! width, so one plan serves every image size. The plan is shared between threads.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use tract_onnx::prelude::*;
use tract_onnx::tract_hir::infer::{Factoid, ShapeFactoid};
use uwnr_core::Image;
use uwnr_core::resize::resize_bilinear;

use crate::error::{DepthError, Result};
use crate::util::{normalise_min_max, rgb_planes};

/// ImageNet channel means (R, G, B) used to normalise the input, as MiDaS v2.1, DPT-Large and
/// Depth Anything do (torchvision's `Normalize(mean=[0.485, 0.456, 0.406], ...)`).
pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
/// ImageNet channel standard deviations (R, G, B).
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];
/// Short side of the input of a dynamic-size model when no `input_size` is given (MiDaS/DPT's
/// 384).
pub const DEFAULT_SHORT_SIDE: usize = 384;
/// Each side of a default-sized input is a multiple of this (MiDaS/DPT's `ensure_multiple_of=32`).
pub const DEFAULT_MULTIPLE: usize = 32;
/// Value of the map when the model's output is constant: mid-depth.
const FLAT_DEPTH: f32 = 0.5;

/// How the model's input height and width are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum InputSize {
    /// Fixed by the model itself (width, height).
    Model(usize, usize),
    /// Chosen by the user for a dynamic model (width, height).
    User(usize, usize),
    /// Chosen per image by the MiDaS rule.
    PerImage,
}

/// A loaded and optimised ONNX depth model.
#[derive(Debug)]
pub(crate) struct OnnxDepth {
    path: PathBuf,
    plan: Arc<TypedRunnableModel>,
    input: InputSize,
    invert: bool,
    /// Said once per map when the user's `input_size` was overridden by the model's own.
    ignored_input_size: Option<(usize, usize)>,
}

impl OnnxDepth {
    /// Loads, checks and optimises the model.
    pub(crate) fn new(
        path: &Path,
        invert: bool,
        input_size: Option<(usize, usize)>,
    ) -> Result<Self> {
        if !path.is_file() {
            return Err(DepthError::ModelNotFound {
                path: path.to_path_buf(),
            });
        }
        let load_err = |e: TractError| DepthError::ModelLoad {
            path: path.to_path_buf(),
            reason: format!("{e:#}"),
        };
        let input_err = |reason: String| DepthError::ModelInput {
            path: path.to_path_buf(),
            reason,
        };
        if let Some((width, height)) = input_size
            && (width == 0 || height == 0)
        {
            return Err(DepthError::InvalidInputSize { width, height });
        }

        let model = tract_onnx::onnx().model_for_path(path).map_err(load_err)?;
        let inputs = model.input_outlets().map_err(load_err)?.len();
        if inputs != 1 {
            return Err(input_err(format!(
                "the model has {inputs} inputs; expected one image"
            )));
        }
        let fact = model.input_fact(0).map_err(load_err)?;
        let fixed = fixed_spatial_size(&fact.shape).map_err(input_err)?;

        let (input, ignored_input_size) = match (fixed, input_size) {
            (Some((w, h)), user) => (InputSize::Model(w, h), user.filter(|&u| u != (w, h))),
            (None, Some((w, h))) => (InputSize::User(w, h), None),
            (None, None) => (InputSize::PerImage, None),
        };
        let input_fact = match input {
            InputSize::Model(w, h) | InputSize::User(w, h) => f32::fact([1, 3, h, w]),
            InputSize::PerImage => {
                let h = model.sym("uwnr_height");
                let w = model.sym("uwnr_width");
                f32::fact([TDim::from(1), TDim::from(3), h.into(), w.into()])
            }
        };
        let model = model
            .with_input_fact(0, input_fact.into())
            .map_err(load_err)?
            .into_optimized()
            .map_err(|e| DepthError::ModelLoad {
                path: path.to_path_buf(),
                // Some graphs only optimise once their height and width are known.
                reason: match input {
                    InputSize::PerImage => {
                        format!("{e:#} (its input size is dynamic: try a fixed input size)")
                    }
                    _ => format!("{e:#}"),
                },
            })?;
        let output = model.output_fact(0).map_err(load_err)?;
        if !output_dims_ok(output.shape.dims().iter().map(TDim::as_i64)) {
            return Err(DepthError::UnexpectedOutputShape {
                path: path.to_path_buf(),
                shape: format!(
                    "[{}]",
                    output
                        .shape
                        .dims()
                        .iter()
                        .map(ToString::to_string)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            });
        }
        let plan = model.into_runnable().map_err(load_err)?;
        Ok(Self {
            path: path.to_path_buf(),
            plan,
            input,
            invert,
            ignored_input_size,
        })
    }

    /// Runs the model on `clean` and returns the depth map at the clean image's size in uwnr's
    /// convention (far = 1), with notes.
    pub(crate) fn depth_for(&self, clean: &Image) -> Result<(Image, Vec<String>)> {
        rgb_planes(clean)?;
        let (width, height) = clean.size();
        let (in_w, in_h) = match self.input {
            InputSize::Model(w, h) | InputSize::User(w, h) => (w, h),
            InputSize::PerImage => default_input_size(width, height),
        };
        let mut notes = vec![format!(
            "depth model {} ran at {in_w}x{in_h}",
            self.path.display()
        )];
        if let Some((w, h)) = self.ignored_input_size {
            notes.push(format!(
                "input size {w}x{h} ignored: the model's input is fixed at {in_w}x{in_h}"
            ));
        }

        let input = imagenet_input(clean, in_w, in_h)?;
        let tensor =
            Tensor::from_shape(&[1, 3, in_h, in_w], &input).map_err(|e| self.inference_err(e))?;
        let outputs = self
            .plan
            .run(tvec![tensor.into()])
            .map_err(|e| self.inference_err(e))?;
        let disparity = self.disparity_image(outputs.first())?;

        let mut depth = resize_bilinear(&disparity, width, height)?;
        let values = depth.plane_mut(0);
        if normalise_min_max(values).is_none() {
            values.fill(FLAT_DEPTH);
            notes.push(format!(
                "depth model {} returned a constant map",
                self.path.display()
            ));
        }
        if !self.invert {
            for v in values.iter_mut() {
                *v = 1.0 - *v;
            }
        }
        Ok((depth, notes))
    }

    /// The model's first output as a 1-channel image, after checking its shape and values.
    fn disparity_image(&self, output: Option<&TValue>) -> Result<Image> {
        let output = output.ok_or_else(|| DepthError::UnexpectedOutputShape {
            path: self.path.clone(),
            shape: "no output".into(),
        })?;
        let shape = output.shape();
        let spatial = match shape {
            [.., h, w] if *h > 0 && *w > 0 => Some((*h, *w)),
            _ => None,
        };
        let (out_h, out_w) = spatial
            .filter(|_| output_dims_ok(shape.iter().map(|&d| i64::try_from(d).ok())))
            .ok_or_else(|| DepthError::UnexpectedOutputShape {
                path: self.path.clone(),
                shape: format!("{shape:?}"),
            })?;
        let values = output.cast_to::<f32>().map_err(|e| self.inference_err(e))?;
        let values: Vec<f32> = values
            .to_plain_array_view::<f32>()
            .map_err(|e| self.inference_err(e))?
            .iter()
            .copied()
            .collect();
        let count = values.iter().filter(|v| !v.is_finite()).count();
        if count > 0 {
            return Err(DepthError::NonFiniteOutput {
                path: self.path.clone(),
                count,
            });
        }
        Ok(Image::from_planar(out_w, out_h, 1, values)?)
    }

    fn inference_err(&self, e: TractError) -> DepthError {
        DepthError::Inference {
            path: self.path.clone(),
            reason: format!("{e:#}"),
        }
    }
}

/// The fixed `(width, height)` of an input shape `[N, 3, H, W]`, or `None` when height or width
/// is dynamic. Fails on a shape that cannot be an RGB image batch.
fn fixed_spatial_size(shape: &ShapeFactoid) -> std::result::Result<Option<(usize, usize)>, String> {
    let dims: Vec<Option<i64>> = shape
        .dims()
        .map(|d| d.concretize().and_then(|d| d.as_i64()))
        .collect();
    if !shape.is_open() && dims.len() != 4 {
        return Err(format!(
            "input of rank {}; expected [1, 3, H, W]",
            dims.len()
        ));
    }
    let dim = |i: usize| dims.get(i).copied().flatten();
    if let Some(n) = dim(0).filter(|&n| n != 1) {
        return Err(format!("batch dimension fixed at {n}; expected 1"));
    }
    if let Some(c) = dim(1).filter(|&c| c != 3) {
        return Err(format!("{c} input channels; expected 3 (RGB)"));
    }
    match (dim(2), dim(3)) {
        (Some(h), Some(w)) if h > 0 && w > 0 => Ok(Some((w as usize, h as usize))),
        _ => Ok(None),
    }
}

/// Accepts `[H, W]`, `[1, H, W]` and `[1, 1, H, W]` (unknown dims pass): every dimension before
/// the last two must be 1.
fn output_dims_ok(dims: impl Iterator<Item = Option<i64>>) -> bool {
    let dims: Vec<Option<i64>> = dims.collect();
    (2..=4).contains(&dims.len())
        && dims[..dims.len() - 2]
            .iter()
            .all(|d| d.is_none_or(|d| d == 1))
}

/// Input size of a dynamic model for a `width x height` image: the MiDaS "lower bound" rule
/// (short side [`DEFAULT_SHORT_SIDE`], aspect kept, sides multiples of [`DEFAULT_MULTIPLE`]).
#[must_use]
pub fn default_input_size(width: usize, height: usize) -> (usize, usize) {
    let scale = DEFAULT_SHORT_SIDE as f64 / width.min(height).max(1) as f64;
    let side = |s: usize| {
        let multiples = (s as f64 * scale / DEFAULT_MULTIPLE as f64).round() as usize;
        (multiples * DEFAULT_MULTIPLE).max(DEFAULT_SHORT_SIDE)
    };
    (side(width), side(height))
}

/// The clean image resized to `width x height` and normalised with the ImageNet statistics, as
/// planar `[3, height, width]` data.
fn imagenet_input(clean: &Image, width: usize, height: usize) -> Result<Vec<f32>> {
    let rgb = if clean.channels() == 1 {
        Image::concat_channels(&[clean, clean, clean])?
    } else {
        clean.clone()
    };
    let mut input = resize_bilinear(&rgb, width, height)?.into_data();
    for (c, plane) in input.chunks_exact_mut(width * height).enumerate() {
        for v in plane {
            *v = (*v - IMAGENET_MEAN[c]) / IMAGENET_STD[c];
        }
    }
    Ok(input)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_size_follows_the_midas_rule() {
        assert_eq!(default_input_size(384, 384), (384, 384));
        assert_eq!(default_input_size(256, 256), (384, 384));
        // 481x321: scale 384/321, 575.4 -> 576.
        assert_eq!(default_input_size(481, 321), (576, 384));
        assert_eq!(default_input_size(480, 640), (384, 512));
        assert_eq!(default_input_size(1242, 375), (1280, 384));
    }

    #[test]
    fn output_shapes() {
        let ok = |d: &[i64]| output_dims_ok(d.iter().map(|&v| Some(v)));
        assert!(ok(&[1, 5, 7]));
        assert!(ok(&[1, 1, 5, 7]));
        assert!(ok(&[5, 7]));
        assert!(!ok(&[1, 3, 5, 7]));
        assert!(!ok(&[2, 5, 7]));
        assert!(!ok(&[7]));
        assert!(!ok(&[1, 1, 1, 5, 7]));
    }
}
