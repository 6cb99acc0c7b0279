//! `uwnr._uwnr`: the native half of the `uwnr` Python package (PyO3): the UWNR renderer (the
//! bundled model or any weights), the physical and statistical baselines, the light field map, the
//! built-in depth prior and the field's metrics, computed by the same library calls as the `uwnr`
//! command line, so the same inputs give the same pixels.
//!
//! Pixels cross the boundary as contiguous interleaved bytes with their shape: 8-bit codes
//! (read as `code / 255`, as the image decoder does) or native-endian f32 in [0, 1]. The module
//! therefore needs no NumPy C API and works with any NumPy; the Python half (`uwnr/__init__.py`)
//! checks shapes, dtypes and value ranges and turns arrays, PIL images and torch tensors into
//! those bytes and back.
//!
//! Every computation runs with the GIL released, inside a rayon pool owned by the current
//! process. A pool inherited through `fork` (a PyTorch DataLoader worker) has no threads left, so
//! a forked child builds its own on first use instead of waiting on the parent's forever. Panics
//! are caught and raised as `uwnr.Error`; they never reach the interpreter.

mod convert;
mod metrics;
mod renderer;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::{Arc, Mutex};

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;

create_exception!(
    _uwnr,
    Error,
    PyException,
    "A weights, model or rendering problem in uwnr (bad input raises ValueError instead)."
);

/// A failure inside a computation, sorted by the Python exception it becomes.
#[derive(Debug)]
pub(crate) enum Failure {
    /// Bad input: `ValueError`.
    Value(String),
    /// A model or rendering problem: `uwnr.Error`.
    Model(String),
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> Self {
        match f {
            Failure::Value(m) => PyValueError::new_err(m),
            Failure::Model(m) => Error::new_err(m),
        }
    }
}

pub(crate) fn value(e: impl std::fmt::Display) -> Failure {
    Failure::Value(e.to_string())
}

pub(crate) fn model(e: impl std::fmt::Display) -> Failure {
    Failure::Model(e.to_string())
}

/// The rayon pool of this process (rebuilt in a forked child, whose inherited pool has no
/// threads). `RAYON_NUM_THREADS` sets its size, as for rayon's global pool.
fn process_pool() -> Result<Arc<rayon::ThreadPool>, Failure> {
    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut slot = POOL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some((owner, pool)) = slot.as_ref()
        && *owner == pid
    {
        return Ok(pool.clone());
    }
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .thread_name(|i| format!("uwnr-{i}"))
            .build()
            .map_err(|e| model(format!("starting the thread pool: {e}")))?,
    );
    *slot = Some((pid, pool.clone()));
    Ok(pool)
}

/// Runs `f` without the GIL in this process's pool, turning a panic into `uwnr.Error`.
pub(crate) fn compute<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> Result<T, Failure> + Send,
) -> PyResult<T> {
    py.detach(|| {
        let pool = process_pool()?;
        catch_unwind(AssertUnwindSafe(|| pool.install(f))).unwrap_or_else(|panic| {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown cause");
            Err(Failure::Model(format!("internal error: {what}")))
        })
    })
    .map_err(PyErr::from)
}

/// The native module `uwnr._uwnr`.
#[pymodule]
fn _uwnr(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<renderer::NativeReference>()?;
    m.add_class::<renderer::NativeRenderer>()?;
    m.add_function(wrap_pyfunction!(metrics::builtin_depth, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::metric, m)?)?;
    m.add_function(wrap_pyfunction!(metrics::load_rgb, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BUNDLED_MODEL", uwnr_model::bundled_model_bytes().is_some())?;
    m.add("BUNDLED_GAN", uwnr_gan::bundled_gan_weights().is_some())?;
    m.add("DEVICES", vec![uwnr_render::ComputeDevice::Engine.name()])?;
    m.add(
        "METHODS",
        uwnr_render::MethodKind::ALL
            .map(uwnr_render::MethodKind::name)
            .to_vec(),
    )?;
    Ok(())
}
