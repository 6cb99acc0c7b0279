//! What turns a clean image into its underwater twin in a dataset run: a render method of
//! `uwnr-render` (the UWNR network, the UWGAN-style GAN baseline, the physical and statistical
//! baselines, or plain haze), shared with `uwnr render`, experiments and Python.

pub use uwnr_render::{ReferenceInput, Renderer, Worker, depth_record, fnv1a64};
