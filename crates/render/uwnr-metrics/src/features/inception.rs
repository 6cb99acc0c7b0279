//! InceptionV3 pool3 features from a user-supplied ONNX file (Szegedy et al. 2016; the FID
//! network of Heusel et al. 2017), run with tract-onnx.
//!
//! Preprocessing follows pytorch-fid (`pytorch_fid.inception.InceptionV3.forward` with
//! `resize_input=True, normalize_input=True`): the RGB image in [0, 1] is resized to 299x299 by
//! `F.interpolate(mode="bilinear", align_corners=False)` without antialiasing
//! ([`crate::resize_bilinear_torch`]), then scaled to [-1, 1] by `2 x - 1`, and fed as a
//! `1 x 3 x 299 x 299` f32 tensor. The first output, of `dim` values in any shape
//! (`1 x 2048 x 1 x 1` for pytorch-fid's pool3), is the feature vector.
//!
//! An export that already contains the `2 x - 1` step expects [0, 1] input: choose the range
//! with [`OnnxInceptionOptions::input_range`]. uwnr ships no Inception weights.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use tract_onnx::prelude::*;
use uwnr_core::Image;

use crate::error::{MetricsError, Result, check_rgb};
use crate::features::FeatureExtractor;
use crate::resize::resize_bilinear_torch;

/// Input side of InceptionV3 in pytorch-fid.
pub const INCEPTION_INPUT_SIDE: usize = 299;
/// Length of InceptionV3's pool3 (final average pool) features.
pub const INCEPTION_POOL3_DIM: usize = 2048;

/// Value range the network expects after resizing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InceptionInputRange {
    /// `2 x - 1`, pytorch-fid's `normalize_input` (the default).
    #[default]
    MinusOneToOne,
    /// The [0, 1] image unchanged (an export with the normalisation inside).
    ZeroToOne,
    /// `255 x` (TF-ported graphs such as clean-fid's, which take 0..255).
    ZeroTo255,
}

/// Options of [`OnnxInception::load_with`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct OnnxInceptionOptions {
    /// Square input side the network was exported with.
    pub input_side: usize,
    /// Range of the input tensor.
    pub input_range: InceptionInputRange,
    /// Expected feature length; `None` takes it from the model's output shape.
    pub dim: Option<usize>,
}

impl Default for OnnxInceptionOptions {
    fn default() -> Self {
        Self {
            input_side: INCEPTION_INPUT_SIDE,
            input_range: InceptionInputRange::MinusOneToOne,
            dim: None,
        }
    }
}

/// An InceptionV3-like ONNX network used as a [`FeatureExtractor`].
#[derive(Debug, Clone)]
pub struct OnnxInception {
    path: PathBuf,
    plan: Arc<TypedRunnableModel>,
    dim: usize,
    opts: OnnxInceptionOptions,
}

impl OnnxInception {
    /// Loads a network with pytorch-fid's conventions (299x299 input in [-1, 1]).
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with(path, OnnxInceptionOptions::default())
    }

    /// Loads a network with explicit input conventions.
    pub fn load_with(path: &Path, opts: OnnxInceptionOptions) -> Result<Self> {
        let onnx_err = |e: TractError| MetricsError::Onnx {
            path: path.to_path_buf(),
            reason: format!("{e:#}"),
        };
        let side = opts.input_side;
        if side == 0 {
            return Err(MetricsError::InvalidArgument(
                "Inception input side must be > 0".into(),
            ));
        }
        let model = tract_onnx::onnx()
            .model_for_path(path)
            .and_then(|m| m.with_input_fact(0, f32::fact([1, 3, side, side]).into()))
            .and_then(|m| m.into_optimized())
            .map_err(onnx_err)?;
        let out_shape = model
            .output_fact(0)
            .map_err(onnx_err)?
            .shape
            .as_concrete()
            .map(<[usize]>::to_vec);
        let plan = model.into_runnable().map_err(onnx_err)?;
        let dim = match (out_shape, opts.dim) {
            (Some(shape), want) => {
                let got: usize = shape.iter().product();
                if let Some(expected) = want.filter(|&e| e != got) {
                    return Err(MetricsError::OnnxOutput {
                        path: path.to_path_buf(),
                        expected,
                        got,
                    });
                }
                got
            }
            (None, Some(want)) => want,
            (None, None) => {
                return Err(MetricsError::Onnx {
                    path: path.to_path_buf(),
                    reason: "the output shape is not fixed; give the feature length explicitly"
                        .into(),
                });
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            plan,
            dim,
            opts,
        })
    }

    /// The `1 x 3 x side x side` input tensor for an image (resized and rescaled).
    pub fn preprocess(&self, img: &Image) -> Result<Vec<f32>> {
        check_rgb("Inception features", img)?;
        let side = self.opts.input_side;
        let resized = resize_bilinear_torch(img, side, side)?;
        let map: fn(f32) -> f32 = match self.opts.input_range {
            InceptionInputRange::MinusOneToOne => |v| 2.0 * v - 1.0,
            InceptionInputRange::ZeroToOne => |v| v,
            InceptionInputRange::ZeroTo255 => |v| 255.0 * v,
        };
        Ok(resized.data().iter().map(|&v| map(v)).collect())
    }
}

impl FeatureExtractor for OnnxInception {
    fn dim(&self) -> usize {
        self.dim
    }

    fn name(&self) -> &str {
        "inception-pool3"
    }

    fn extract(&self, img: &Image) -> Result<Vec<f64>> {
        let onnx_err = |e: TractError| MetricsError::Onnx {
            path: self.path.clone(),
            reason: format!("{e:#}"),
        };
        let side = self.opts.input_side;
        let input =
            Tensor::from_shape(&[1, 3, side, side], &self.preprocess(img)?).map_err(onnx_err)?;
        let outputs = self.plan.run(tvec!(input.into())).map_err(onnx_err)?;
        let first = outputs.first().ok_or_else(|| MetricsError::Onnx {
            path: self.path.clone(),
            reason: "the network has no output".into(),
        })?;
        let view = first.to_plain_array_view::<f32>().map_err(onnx_err)?;
        let features: Vec<f64> = view.iter().map(|&v| f64::from(v)).collect();
        if features.len() != self.dim {
            return Err(MetricsError::OnnxOutput {
                path: self.path.clone(),
                expected: self.dim,
                got: features.len(),
            });
        }
        Ok(features)
    }
}
