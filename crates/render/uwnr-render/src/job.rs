//! One render job: the sequence every caller runs to render an item (`uwnr render`, `uwnr
//! dataset`, the page, Python), written once:
//!
//! 1. the item's depth (a [`uwnr_depth::Depth`], from whatever source the caller reads) becomes
//!    the network's depth response through the [`DepthPolicy`]: the scene scale drawn from the
//!    item's seed, the trust in the built-in prior;
//! 2. the reference is prepared once per reference and reused by every render of the job
//!    ([`RenderJob::reference`]: the decoded image for the baselines, the style for the
//!    network), within a bound on how many are kept;
//! 3. the item's seed draws every random parameter ([`RenderJob::item_seed`] for a batch's item
//!    `i`, as `uwnr render` numbers them; a dataset passes its pair seeds);
//! 4. the render.

use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use uwnr_core::Image;
use uwnr_core::error::Cause;

use crate::depth_policy::DepthPolicy;
use crate::error::{RenderError, Result};
use crate::lru::Lru;
use crate::renderer::{PreparedReference, ReferenceInput, Rendered, Renderer, Worker};

/// Why a reference could not be prepared: its loading (the caller's error) or its preparation
/// (a [`RenderError`]), shared, so that a bad reference is read once and fails again with the
/// same error.
pub type ReferenceError = Arc<dyn std::error::Error + Send + Sync + 'static>;

/// A prepared reference, or why it could not be prepared.
type Prepared = std::result::Result<Arc<PreparedReference>, ReferenceError>;

/// A render method with its depth policy and its prepared references.
pub struct RenderJob {
    renderer: Arc<Renderer>,
    policy: DepthPolicy,
    seed: u64,
    /// How many prepared references are kept.
    kept: usize,
    /// Prepared references by the caller's key.
    references: Mutex<Lru<String, Arc<OnceLock<Prepared>>>>,
}

impl RenderJob {
    /// A job of `renderer` with `policy` (checked) and the run's `seed`, keeping at most `kept`
    /// prepared references (the least recently used is dropped beyond; at least one).
    pub fn new(
        renderer: Arc<Renderer>,
        policy: DepthPolicy,
        seed: u64,
        kept: usize,
    ) -> Result<Self> {
        policy
            .validate()
            .map_err(|e| RenderError::Invalid(e.to_string()))?;
        Ok(Self {
            renderer,
            policy,
            seed,
            kept: kept.max(1),
            references: Mutex::new(Lru::new(kept.max(1))),
        })
    }

    /// The same job keeping its prepared references within `bytes` as well (their decoded images
    /// and styles, [`PreparedReference::bytes`]); one larger than that alone is prepared for
    /// each render that asks for it.
    #[must_use]
    pub fn with_kept_bytes(self, bytes: u64) -> Self {
        Self {
            references: Mutex::new(Lru::with_bytes(self.kept, bytes)),
            ..self
        }
    }

    /// The method.
    #[must_use]
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// How depth is read.
    #[must_use]
    pub fn policy(&self) -> &DepthPolicy {
        &self.policy
    }

    /// The seed of item `index` of a batch (`uwnr render`'s numbering, and Python's).
    #[must_use]
    pub fn item_seed(&self, index: usize) -> u64 {
        uwnr_core::seed::item_seed(self.seed, index)
    }

    /// The reference called `key`, prepared for this job's method; `load` decodes it, the first
    /// time only. A reference that failed fails again with the same error, unread.
    pub fn reference(
        &self,
        key: &str,
        load: impl FnOnce() -> std::result::Result<Arc<Image>, Cause>,
    ) -> Prepared {
        let cell = {
            let mut refs = self
                .references
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            // A kept reference is now the most recent, with its size; a new one is kept at
            // size 0 until prepared.
            let key = key.to_string();
            refs.get(&key).unwrap_or_else(|| {
                let cell = Arc::default();
                refs.put(key, Arc::clone(&cell));
                cell
            })
        };
        // Prepared outside the lock: other references are prepared meanwhile, and threads
        // asking for this one wait for the first.
        let mut fresh = false;
        let prepared = cell
            .get_or_init(|| {
                fresh = true;
                let image = load().map_err(ReferenceError::from)?;
                self.renderer
                    .prepare_reference(image)
                    .map(Arc::new)
                    .map_err(|e| Arc::new(e) as ReferenceError)
            })
            .clone();
        if fresh {
            let bytes = prepared.as_ref().map_or(0, |p| p.bytes());
            self.references
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .set_size(&key.to_string(), bytes);
        }
        prepared
    }

    /// A per-thread handle.
    #[must_use]
    pub fn worker(&self) -> JobWorker<'_> {
        JobWorker::new(self.renderer.worker(), &self.policy)
    }
}

/// A render job as one thread holds it.
pub struct JobWorker<'a> {
    policy: &'a DepthPolicy,
    worker: Worker<'a>,
}

impl<'a> JobWorker<'a> {
    /// A renderer's worker with `policy`, for callers that keep their references themselves (a
    /// dataset keeps the style of thousands of references and decodes a baseline's reference
    /// per pair, not the decoded images).
    #[must_use]
    pub fn new(worker: Worker<'a>, policy: &'a DepthPolicy) -> Self {
        Self { policy, worker }
    }

    /// Renders `clean` with its `depth` (the map at the clean image's size, and what it is)
    /// after `reference`, drawing every random parameter from `seed`.
    pub fn render(
        &self,
        clean: &Image,
        depth: &uwnr_depth::Depth,
        reference: Option<ReferenceInput<'_>>,
        seed: u64,
    ) -> Result<Rendered> {
        let response = self.policy.response(depth, seed);
        self.worker
            .render(clean, &depth.map, &response, reference, seed)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;
    use crate::{MethodKind, MethodSpec};

    fn job(kind: MethodKind, kept: usize) -> RenderJob {
        let renderer = Renderer::load(MethodSpec::defaults(kind, true)).unwrap();
        RenderJob::new(Arc::new(renderer), DepthPolicy::render(), 7, kept).unwrap()
    }

    #[test]
    fn a_reference_is_prepared_once_and_a_failure_is_kept() {
        let job = job(MethodKind::Reinhard, 4);
        let loads = AtomicUsize::new(0);
        let load = || {
            loads.fetch_add(1, Ordering::SeqCst);
            Ok(Arc::new(Image::filled(20, 10, 3, 0.3)))
        };
        let a = job.reference("a", load).unwrap();
        let b = job.reference("a", load).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(loads.load(Ordering::SeqCst), 1);
        let bad = job.reference("bad", || Err("truncated file".into()));
        assert_eq!(bad.err().unwrap().to_string(), "truncated file");
        let again = job.reference("bad", || panic!("a failed reference is not read again"));
        assert_eq!(again.err().unwrap().to_string(), "truncated file");
    }

    #[test]
    fn references_beyond_the_bound_are_prepared_again() {
        let job = job(MethodKind::Reinhard, 2);
        let loads = AtomicUsize::new(0);
        let load = || {
            loads.fetch_add(1, Ordering::SeqCst);
            Ok(Arc::new(Image::filled(8, 8, 3, 0.3)))
        };
        for key in ["a", "b", "a", "c", "a", "b"] {
            job.reference(key, load).unwrap();
        }
        // a, b; a kept (recent); c drops b; a kept; b again: 4 loads.
        assert_eq!(loads.load(Ordering::SeqCst), 4);
    }

    #[test]
    fn prepared_references_are_kept_within_their_bytes() {
        // Reinhard keeps the decoded image: 8x8x3 f32 = 768 bytes each.
        let job = job(MethodKind::Reinhard, 10).with_kept_bytes(1600);
        let loads = AtomicUsize::new(0);
        let load = |side: usize| {
            let loads = &loads;
            move || {
                loads.fetch_add(1, Ordering::SeqCst);
                Ok(Arc::new(Image::filled(side, side, 3, 0.3)))
            }
        };
        assert_eq!(job.reference("a", load(8)).unwrap().bytes(), 768);
        job.reference("b", load(8)).unwrap();
        job.reference("a", load(8)).unwrap();
        assert_eq!(loads.load(Ordering::SeqCst), 2, "two fit");
        job.reference("c", load(8)).unwrap();
        job.reference("b", load(8)).unwrap();
        assert_eq!(
            loads.load(Ordering::SeqCst),
            4,
            "the third drops the least recent (b)"
        );
        // 16x16x3 f32 = 3 kB: larger than the bound, prepared again each time, and the others
        // stay.
        job.reference("big", load(16)).unwrap();
        job.reference("big", load(16)).unwrap();
        job.reference("b", load(8)).unwrap();
        assert_eq!(loads.load(Ordering::SeqCst), 6);
    }

    #[test]
    fn the_job_renders_with_the_policy_and_the_item_seed() {
        let job = job(MethodKind::Uisa, 4);
        let clean = Image::filled(24, 16, 3, 0.6);
        let depth = uwnr_depth::Depth {
            map: Image::filled(24, 16, 1, 0.5),
            notes: Vec::new(),
            relative: true,
            metric_max: None,
            prior: true,
        };
        let reference = job
            .reference("r", || Ok(Arc::new(Image::filled(30, 20, 3, 0.2))))
            .unwrap();
        let worker = job.worker();
        let seed = job.item_seed(3);
        assert_eq!(seed, uwnr_core::seed::item_seed(7, 3));
        let a = worker
            .render(&clean, &depth, Some(reference.input()), seed)
            .unwrap();
        // What the steps give when written out by hand.
        let response = job.policy().response(&depth, seed);
        let b = job
            .renderer()
            .worker()
            .render(&clean, &depth.map, &response, Some(reference.input()), seed)
            .unwrap();
        assert_eq!(a.image, b.image);
        assert_eq!(a.params, b.params);
    }
}
