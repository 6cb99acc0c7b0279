//! The workers of a run: each takes a clean image, decodes and fits it, computes its depth and
//! its labels once, draws its references, and renders and writes its K pairs.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SyncSender;

use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, save_gray16, save_rgb};
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::PreparedDepth;
use uwnr_model::ReferenceStyle;
use uwnr_render::{Camera, JobWorker, MethodRecord, ReferenceError, Rendered};

use super::{Msg, RefCache, Spec, fit, fit_geometry};
use crate::labels::{Fit, Labels, PairLabels};
use crate::manifest::{CLEAN_DIR, DEPTH_DIR, Failure, LIGHTFIELD_DIR, Record, UNDERWATER_DIR};
use crate::plan::{ReferenceOrder, pair_seed};
use crate::renderer::{ReferenceInput, Renderer};
use crate::target::WaterTarget;

/// Shared, read-only state of the workers.
pub(super) struct Context<'a> {
    pub(super) out: &'a Path,
    /// The method's name, recorded in every pair.
    pub(super) method: &'static str,
    pub(super) spec: &'a Spec,
    pub(super) cleans: &'a [PathBuf],
    pub(super) names: &'a [String],
    pub(super) refs: &'a [PathBuf],
    pub(super) ref_cache: RefCache,
    /// Turns references into styles (the network's config decides how).
    pub(super) renderer: &'a Renderer,
    pub(super) depth: &'a PreparedDepth,
    /// Per clean image, its measured map beside it (`X/depth/` next to `X/rgb/`).
    pub(super) beside: &'a [Option<PathBuf>],
    /// The clean images' labels.
    pub(super) labels: &'a Labels,
    /// Per-pair strength calibration of a water-anchored model.
    pub(super) calibration: Option<&'a WaterTarget>,
    pub(super) limits: &'a DecodeLimits,
    pub(super) stop: &'a AtomicBool,
}

impl Context<'_> {
    /// Makes the pairs `ks` of clean image `i`. Returns false when the receiver is gone.
    pub(super) fn make_clean(
        &self,
        worker: &JobWorker<'_>,
        i: usize,
        ks: &[usize],
        tx: &SyncSender<Msg>,
    ) -> bool {
        let source = &self.cleans[i];
        let ids: Vec<String> = ks
            .iter()
            .map(|&k| crate::plan::pair_id(&self.names[i], k))
            .collect();
        let fail = |ids: Vec<String>, reason: String| {
            tx.send(Msg::Failed(Failure {
                source: source.to_string_lossy().into_owned(),
                ids,
                reason,
            }))
            .is_ok()
        };
        let (clean, depth, labels) =
            match self.clean_and_depth(i).and_then(|(clean, depth, fit)| {
                Ok((clean, depth, self.labels.for_clean(i, &fit, self.limits)?))
            }) {
                Ok(c) => c,
                Err(reason) => return fail(ids, reason),
            };
        let references = if self.refs.is_empty() {
            Vec::new()
        } else {
            match self.draw(i, tx) {
                Some(r) => r,
                None => return false,
            }
        };
        let lf_dir_needed = self.spec.save_lightfield;
        for (&k, id) in ks.iter().zip(ids) {
            if self.stop.load(Ordering::Relaxed) {
                return true;
            }
            let index = (i * self.spec.per_image + k) as u64;
            let seed = pair_seed(self.spec.seed, index);
            let reference = if self.refs.is_empty() {
                None
            } else {
                match references.get(k) {
                    Some(r) => Some(r),
                    None => {
                        if !fail(
                            vec![id],
                            format!(
                                "only {} readable references left to draw from",
                                references.len()
                            ),
                        ) {
                            return false;
                        }
                        continue;
                    }
                }
            };
            let pair_labels = labels.pair(&id, index, k, clean.size());
            let result = self.make_pair(
                worker,
                &clean,
                &depth,
                reference,
                seed,
                &id,
                lf_dir_needed,
                &pair_labels,
            );
            let labels_info = pair_labels.info();
            let msg = match result {
                Ok((params, reference_source, strength_db)) => Msg::Pair(Box::new(Record {
                    id: id.clone(),
                    index,
                    clean_source: source.to_string_lossy().into_owned(),
                    reference_source,
                    method: self.method.into(),
                    params,
                    seed,
                    width: clean.width(),
                    height: clean.height(),
                    underwater: format!("{UNDERWATER_DIR}/{id}.png"),
                    clean: format!("{CLEAN_DIR}/{id}.png"),
                    depth: self
                        .spec
                        .save_depth
                        .then(|| format!("{DEPTH_DIR}/{id}.png")),
                    lightfield: self
                        .spec
                        .save_lightfield
                        .then(|| format!("{LIGHTFIELD_DIR}/{id}.png")),
                    labels: pair_labels.labels.map(|(f, _)| f),
                    mask: pair_labels.mask.map(|(f, _)| f),
                    strength_db,
                    labels_info,
                })),
                Err(reason) => Msg::Failed(Failure {
                    source: source.to_string_lossy().into_owned(),
                    ids: vec![id],
                    reason,
                }),
            };
            if tx.send(msg).is_err() {
                return false;
            }
        }
        true
    }

    /// Clean image `i` fitted to the pair size, its depth, and the fit (which carries its labels
    /// too). Maps from files are read at the image's own size and fitted as it is (cover and
    /// centre-crop), so that they stay aligned; the prior and depth models see the fitted image.
    fn clean_and_depth(
        &self,
        i: usize,
    ) -> std::result::Result<(Image, uwnr_depth::Depth, Fit), String> {
        let source = &self.cleans[i];
        let img = load_rgb(source, self.limits).map_err(|e| e.to_string())?;
        let geometry = Fit::new(img.size(), self.spec.size);
        let clean = fit(&img, self.spec.size).map_err(|e| e.to_string())?;
        let depth = if let Some(map) = &self.beside[i] {
            uwnr_depth::Depth::from_file(map, img.size(), self.spec.depth_policy.unit, self.limits)
                .map_err(|e| format!("depth: {e}"))?
        } else if self.depth.reads_files() {
            self.depth
                .depth_for(&img, Some(source))
                .map_err(|e| format!("depth: {e}"))?
        } else {
            return self
                .depth
                .depth_for(&clean, Some(source))
                .map(|d| (clean, d, geometry))
                .map_err(|e| format!("depth: {e}"));
        };
        let map = fit_geometry(&depth.map, self.spec.size).map_err(|e| format!("depth: {e}"))?;
        Ok((clean, uwnr_depth::Depth { map, ..depth }, geometry))
    }

    /// The references of clean image `i`, in draw order: the first K readable ones of its
    /// seeded permutation. `None` when the receiver is gone.
    fn draw(&self, i: usize, tx: &SyncSender<Msg>) -> Option<Vec<(usize, Arc<ReferenceStyle>)>> {
        let mut chosen = Vec::with_capacity(self.spec.per_image);
        for r in ReferenceOrder::new(self.spec.seed, i, self.refs.len()) {
            if chosen.len() == self.spec.per_image {
                break;
            }
            let mut first_failure = None;
            let entry = self.ref_cache[r].get_or_init(|| {
                let path = &self.refs[r];
                let lf = load_rgb(path, self.limits)
                    .map_err(|e| Arc::new(e) as ReferenceError)
                    .and_then(|img| {
                        self.renderer
                            .reference_style(&img, self.spec.save_lightfield)
                            .map_err(|e| Arc::new(e) as ReferenceError)
                    });
                if let Err(e) = &lf {
                    first_failure = Some(e.to_string());
                }
                lf.map(Arc::new)
            });
            match entry {
                Ok(lf) => chosen.push((r, Arc::clone(lf))),
                Err(_) => {
                    // Reported once, by the thread that found it; the draw moves on.
                    if let Some(reason) = first_failure {
                        let f = Failure {
                            source: self.refs[r].to_string_lossy().into_owned(),
                            ids: Vec::new(),
                            reason: format!("unreadable reference, skipped: {reason}"),
                        };
                        tx.send(Msg::Failed(f)).ok()?;
                    }
                }
            }
        }
        Some(chosen)
    }

    /// Renders one pair and writes its files. Returns the recorded parameters and the
    /// reference's path.
    #[allow(clippy::too_many_arguments)]
    fn make_pair(
        &self,
        worker: &JobWorker<'_>,
        clean: &Image,
        depth: &uwnr_depth::Depth,
        reference: Option<&(usize, Arc<ReferenceStyle>)>,
        seed: u64,
        id: &str,
        save_lightfield: bool,
        labels: &PairLabels,
    ) -> std::result::Result<(MethodRecord, Option<String>, Option<f32>), String> {
        // A calibrated water: the reference's style with the pair's own water in it, the water's
        // scale corrected on the render itself until its strength is the target's, measured
        // from the clean photo at the method's clean balance (the white point real pairs'
        // strengths are measured from; `uwnr_model::water::CleanBalance`).
        let style = reference.map(|(_, style)| style.as_ref());
        let balanced = self
            .renderer
            .balanced(clean, style)
            .map_err(|e| e.to_string())?;
        // The pair's clean side: the photo, or the balanced photo when the method says so.
        let stored = self
            .renderer
            .clean_side(clean, &balanced)
            .map_err(|e| e.to_string())?;
        let mut calibration = match (self.calibration, reference) {
            (Some(target), Some((_, style))) => match style.water.as_ref() {
                Some(water) => Some(
                    target
                        .water_for(water.affine, &balanced, seed)
                        .map_err(|e| e.to_string())?,
                ),
                None => None,
            },
            _ => None,
        };
        let reference_image = match reference {
            Some((r, _)) if self.renderer.wants_reference_image() => {
                let path = &self.refs[*r];
                Some(
                    load_rgb(path, self.limits)
                        .map_err(|e| format!("reading reference {}: {e}", path.display()))?,
                )
            }
            _ => None,
        };
        let reference_source = reference.map(|(r, _)| self.refs[*r].to_string_lossy().into_owned());
        // Cloned once (the light field is 192 KiB); its water is put back before each render.
        let mut calibrated = calibration
            .as_ref()
            .and(reference)
            .map(|(_, style)| ReferenceStyle::clone(style));
        let camera = self.spec.camera;
        let Rendered {
            image: underwater,
            mut params,
        } = loop {
            // The reference's own water each time, scaled with the pair's.
            if let (Some(pw), Some((_, original)), Some(style)) =
                (&calibration, reference, calibrated.as_mut())
            {
                style.water.clone_from(&original.water);
                if let Some(water) = style.water.as_mut() {
                    uwnr_model::style::set_scaled_water(water, pw.base, pw.scale);
                }
            }
            let input = reference.map(|(_, lf)| ReferenceInput {
                image: reference_image.as_ref(),
                style: Some(calibrated.as_ref().unwrap_or(lf)),
            });
            let rendered = worker
                .render(clean, depth, input, seed)
                .map_err(|e| e.to_string())?;
            let Some(pw) = calibration.as_mut() else {
                break rendered;
            };
            let db = uwnr_model::water::pair_psnr(&rendered.image.quantised(), &balanced)
                .map_err(|e| e.to_string())?;
            if !pw.corrected(db) {
                break rendered;
            }
        };
        // The camera once, after the calibration (which measured the render before it: the
        // camera's noise moves a pair by a tenth of a dB or so, and applying it in every
        // calibration round cost a third of a dataset's time); the pair records its strength as
        // stored.
        let underwater = if camera.is_none() {
            underwater
        } else {
            camera
                .apply(&underwater, Camera::seed(seed))
                .map_err(|e| e.to_string())?
        };
        // The clean side through the camera as it says (a real pair's clean side is made from
        // the photo the camera took), with the underwater side's noise draws.
        let stored = if camera.touches_clean() {
            Cow::Owned(
                camera
                    .clean_side(&stored, Camera::seed(seed))
                    .map_err(|e| e.to_string())?
                    .into_owned(),
            )
        } else {
            stored
        };
        let lf = reference.and_then(|(_, style)| style.light_field.as_ref());
        let name = format!("{id}.png");
        let write = |dir: &str, f: &dyn Fn(&Path) -> uwnr_core::Result<()>| {
            let p = self.out.join(dir).join(&name);
            f(&p).map_err(|e| format!("writing {}: {e}", p.display()))
        };
        // The underwater image last: a pair is only recorded once all of it is on disk anyway,
        // but a half-made pair then never has a render without its clean image.
        write(CLEAN_DIR, &|p| save_rgb(p, &stored))?;
        if self.spec.save_depth {
            write(DEPTH_DIR, &|p| save_gray16(p, &depth.map))?;
        }
        if save_lightfield {
            let Some(lf) = lf else {
                return Err("--save-lightfield needs a reference for every pair".into());
            };
            let at_size =
                resize_bilinear(lf, clean.width(), clean.height()).map_err(|e| e.to_string())?;
            write(LIGHTFIELD_DIR, &|p| save_rgb(p, &at_size))?;
        }
        for (file, bytes) in [&labels.labels, &labels.mask].into_iter().flatten() {
            let p = self.out.join(file);
            uwnr_core::io::write_atomic_bytes(&p, bytes)
                .map_err(|e| format!("writing {}: {e}", p.display()))?;
        }
        write(UNDERWATER_DIR, &|p| save_rgb(p, &underwater))?;
        // Only the UWNR model's renders are calibrated (the water is its own).
        if let (Some(pw), MethodRecord::Uwnr(record)) = (&calibration, &mut params) {
            record.strength = Some(pw.record());
        }
        // The pair as stored: both sides 8-bit (a calibrated pair's last render was measured,
        // from the photo as stored when nothing was balanced).
        let unbalanced = matches!((&balanced, &stored), (Cow::Borrowed(_), Cow::Borrowed(_)));
        let strength_db = match calibration.as_ref().and_then(|pw| pw.rendered_db.last()) {
            Some(&db) if camera.is_none() && unbalanced => Some(db),
            _ => uwnr_model::water::pair_psnr(&underwater.quantised(), &stored.quantised()).ok(),
        }
        .filter(|v| v.is_finite());
        Ok((params, reference_source, strength_db))
    }
}
