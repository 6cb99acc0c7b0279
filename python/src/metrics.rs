//! The field's metrics, the built-in depth prior and uwnr's image decoder, for Python.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::convert::{Dtype, Pixels, image_bytes};
use crate::{Failure, compute, model, value};

/// The built-in depth prior of an RGB image: f32 bytes, height x width, bright = far.
#[pyfunction]
pub(crate) fn builtin_depth<'py>(
    py: Python<'py>,
    clean: Pixels<'py>,
) -> PyResult<Bound<'py, PyBytes>> {
    let view = clean.view()?;
    let depth = compute(py, || {
        uwnr_depth::builtin_depth(&view.rgb()?).map_err(model)
    })?;
    Ok(image_bytes(py, &depth, Dtype::F32))
}

/// Decodes an image file with uwnr's decoder (as `uwnr render` reads its inputs): f32 RGB bytes,
/// height, width. An unreadable file is a `ValueError`.
#[pyfunction]
pub(crate) fn load_rgb(
    py: Python<'_>,
    path: PathBuf,
) -> PyResult<(Bound<'_, PyBytes>, usize, usize)> {
    let img = compute(py, || {
        uwnr_core::io::load_rgb(&path, &uwnr_core::io::DecodeLimits::default()).map_err(value)
    })?;
    Ok((image_bytes(py, &img, Dtype::F32), img.height(), img.width()))
}

/// The metric `name` of `pred` against `target` (full-reference) or of `pred` alone.
#[pyfunction]
#[pyo3(signature = (name, pred, target, gray))]
pub(crate) fn metric<'py>(
    py: Python<'py>,
    name: &str,
    pred: Pixels<'py>,
    target: Option<Pixels<'py>>,
    gray: bool,
) -> PyResult<f64> {
    let pred = pred.view()?;
    let target = target.as_ref().map(Pixels::view).transpose()?;
    let name = name.to_string();
    compute(py, move || {
        let a = pred.rgb()?;
        let b = target.as_ref().map(|t| t.rgb()).transpose()?;
        let range = uwnr_metrics::DEFAULT_DATA_RANGE;
        let score = match (name.as_str(), &b, gray) {
            ("psnr", Some(b), false) => uwnr_metrics::psnr(&a, b, range),
            ("psnr", Some(b), true) => uwnr_metrics::psnr_gray(&a, b, range),
            ("ssim", Some(b), false) => uwnr_metrics::ssim(&a, b, range),
            ("ssim", Some(b), true) => uwnr_metrics::ssim_gray(&a, b, range),
            ("uiqm", None, _) => uwnr_metrics::uiqm(&a),
            ("uciqe", None, _) => uwnr_metrics::uciqe(&a),
            _ => return Err(Failure::Value(format!("unknown metric call {name:?}"))),
        };
        score.map_err(value)
    })
}
