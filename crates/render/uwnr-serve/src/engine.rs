//! The server's state: the two image folders, dropped images, loaded methods, caches within
//! counts and bytes, and what a render reads.
//!
//! Every file of the folders is read through [`Library::read`] (checked where it lies when it is
//! opened) and every image is decoded within the memory [`Budget`]: its header says what
//! decoding will hold (the file, the decoded samples twice, the planar f32 image), and those
//! bytes are taken first. A render takes the bytes of its planes
//! ([`RENDER_BYTES_PER_PIXEL`] a pixel) before it decodes its clean image. Decoded references are
//! kept within [`KEPT_REFERENCE_BYTES`], each render job's prepared ones within
//! [`KEPT_PREPARED_BYTES`].

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use serde_json::{Value, json};
use uwnr_baselines::background::SUID_MIN_REGION_FRACTION;
use uwnr_baselines::{BackgroundPick, quadtree_background};
use uwnr_core::Image;
use uwnr_core::io::{
    DecodeLimits, check_decodes, encode_rgb_png, load_rgb_from_memory, probe_memory,
};
use uwnr_core::resize::fit_within;
use uwnr_dataset::plan::ReferenceOrder;
use uwnr_depth::{Depth, DepthSource, DepthUnit};
use uwnr_render::lru::Lru;
use uwnr_render::{DepthPolicy, MethodSpec, RenderJob, Renderer};

use crate::ServeConfig;
use crate::budget::{Budget, Lease};
use crate::error::{Result, ServeError};
use crate::jobs::Output;
use crate::paths::{Library, read_inside};
use crate::uploads::{Uploads, display_name};
use crate::view::{CleanSource, DepthChoice, PageRender, RenderSize};

/// Longer side of reference thumbnails, pixels.
pub const THUMB_SIDE: usize = 160;
/// Longer side of the copy of a reference its statistics are computed on, pixels.
const STATS_SIDE: usize = 256;
/// Reference thumbnails and statistics kept (about 40 kB each).
const KEPT_THUMBS: usize = 512;
/// Clean previews kept (each at most the preview size squared times 12 bytes).
const KEPT_PREVIEWS: usize = 16;
/// Decoded full-size references kept, at most.
const KEPT_REFERENCES: usize = 8;
/// Bytes of decoded full-size references kept.
pub const KEPT_REFERENCE_BYTES: u64 = 512 * 1024 * 1024;
/// Loaded methods kept (the networks' weights are the large part).
const KEPT_RENDERERS: usize = 12;
/// Render jobs kept (a method with a depth setting), each with the references it prepared.
pub const KEPT_JOBS: usize = 4;
/// References a job keeps prepared.
const KEPT_PREPARED: usize = 2;
/// Bytes of prepared references a job keeps (a baseline's share the decoded image kept above).
pub const KEPT_PREPARED_BYTES: u64 = 128 * 1024 * 1024;
/// How long a request waits for memory before it is answered `503`.
pub(crate) const DECODE_WAIT: Duration = Duration::from_secs(5);
/// How long a render waits for memory (its queue is bounded) before it fails.
const RENDER_WAIT: Duration = Duration::from_secs(120);
/// Bytes a render holds per pixel of its clean image: the input, depth and output planes and the
/// method's own. Measured peak resident memory of `uwnr render` on a 2000x1500 photo with a
/// 1600x1200 reference, less the idle process and the two decodes: 26-37 bytes a pixel over
/// the six methods (reinhard the largest); 64 leaves room.
pub const RENDER_BYTES_PER_PIXEL: u64 = 64;

pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A reference's thumbnail and statistics.
#[derive(Clone)]
pub(crate) struct RefInfo {
    pub thumb: Arc<Vec<u8>>,
    pub mean: [f64; 3],
    pub veil: [f64; 3],
}

/// Bytes an image's pixels take as planar f32.
fn image_bytes(img: &Image) -> u64 {
    std::mem::size_of_val(img.data()) as u64
}

/// A decoder's message without the name it gives images decoded from memory.
pub(crate) fn reason(e: &impl std::fmt::Display) -> String {
    e.to_string().replace("\"<memory>\": ", "")
}

/// Encoded bytes to be decoded, and who they come from.
pub(crate) struct Encoded {
    bytes: Vec<u8>,
    /// What messages call it.
    what: String,
    /// Sent by the client (a dropped file): a failure is the request's (`400`), not the
    /// server's (`500`).
    theirs: bool,
}

impl Encoded {
    fn failed(&self, reason: String) -> ServeError {
        let what = self.what.clone();
        if self.theirs {
            ServeError::BadImage { what, reason }
        } else {
            ServeError::ServerFile { what, reason }
        }
    }
}

/// Everything a render or a request reads.
pub struct Engine {
    pub(crate) config: ServeConfig,
    pub(crate) cleans: Library,
    /// The depth map beside each clean image (`X/rgb/NAME` with `X/depth/`), found once.
    beside: Vec<Option<PathBuf>>,
    pub(crate) refs: Library,
    pub(crate) limits: DecodeLimits,
    budget: Arc<Budget>,
    uploads: Uploads,
    renderers: Mutex<Lru<String, Arc<Renderer>>>,
    jobs: Mutex<Lru<String, Arc<RenderJob>>>,
    previews: Mutex<Lru<CleanSource, Arc<Image>>>,
    references: Mutex<Lru<usize, Arc<Image>>>,
    thumbs: Mutex<Lru<usize, std::result::Result<RefInfo, String>>>,
}

impl Engine {
    /// Lists the folders and loads the networks (so the first render does not wait for them);
    /// decodes and renders within `budget`.
    pub fn new(config: ServeConfig, budget: Arc<Budget>) -> Result<Self> {
        let cleans = Library::open(&config.clean, "clean")?;
        let refs = Library::open(&config.references, "reference")?;
        let uploads = Uploads::new()?;
        let limits = DecodeLimits {
            max_pixels: config.max_pixels,
            max_dimension: config.max_dimension,
        };
        let beside = beside_maps(&cleans);
        let engine = Self {
            config,
            cleans,
            beside,
            refs,
            limits,
            budget,
            uploads,
            renderers: Mutex::new(Lru::new(KEPT_RENDERERS)),
            jobs: Mutex::new(Lru::new(KEPT_JOBS)),
            previews: Mutex::new(Lru::new(KEPT_PREVIEWS)),
            references: Mutex::new(Lru::with_bytes(KEPT_REFERENCES, KEPT_REFERENCE_BYTES)),
            thumbs: Mutex::new(Lru::new(KEPT_THUMBS)),
        };
        // The networks load once, now, so that the first renders do not wait for them; a
        // network that cannot load (a build without the bundled models) fails its renders
        // with the reason instead of stopping the server.
        for kind in [
            uwnr_render::MethodKind::Uwnr,
            uwnr_render::MethodKind::Uwgan,
        ] {
            let _ = engine.renderer(&MethodSpec::defaults(kind, true));
        }
        Ok(engine)
    }

    /// The clean and reference folders.
    #[must_use]
    pub fn libraries(&self) -> (&Library, &Library) {
        (&self.cleans, &self.refs)
    }

    /// The memory budget decodes and renders take from.
    #[must_use]
    pub fn budget(&self) -> &Arc<Budget> {
        &self.budget
    }

    /// The folder dropped images are kept in (only its owner may read it; removed when the
    /// server is dropped, and by `uwnr serve` on Ctrl-C and SIGTERM).
    #[must_use]
    pub fn upload_dir(&self) -> &Path {
        self.uploads.dir()
    }

    /// Stores a dropped image, readable by this user only, after checking that it decodes
    /// within the limits (decoded as stored, within the memory budget).
    pub fn store_upload(&self, bytes: &[u8], name: &str, depth: bool) -> Result<Value> {
        let name = display_name(name);
        let bad = |reason: String| ServeError::BadImage {
            what: name.clone(),
            reason,
        };
        let (w, h, bpp) = probe_memory(bytes).map_err(|e| bad(reason(&e)))?;
        let pixels = u64::from(w) * u64::from(h);
        let _lease = if pixels <= self.limits.max_pixels && w.max(h) <= self.limits.max_dimension {
            Some(self.lease(2 * pixels * bpp, &name, DECODE_WAIT)?)
        } else {
            None
        };
        let (width, height) = check_decodes(bytes, &self.limits).map_err(|e| bad(reason(&e)))?;
        let id = self.uploads.keep(bytes, &name, depth)?;
        Ok(json!({ "id": id, "name": name, "width": width, "height": height }))
    }

    /// Removes the folder of dropped images before the process ends (a signal handler's job:
    /// destructors do not run then); a dropped image being written is waited for and removed
    /// with the rest.
    pub fn remove_uploads(&self) -> std::io::Result<()> {
        self.uploads.remove_all()
    }

    fn renderer(&self, spec: &MethodSpec) -> Result<Arc<Renderer>> {
        let key = serde_json::to_string(spec).map_err(|e| ServeError::BadRequest(e.to_string()))?;
        if let Some(r) = lock(&self.renderers).get(&key) {
            return Ok(r);
        }
        let r = Arc::new(Renderer::load(spec.clone())?);
        lock(&self.renderers).put(key, r.clone());
        Ok(r)
    }

    /// The render job of `spec` with `policy`: references are prepared once per job.
    fn job(&self, spec: &MethodSpec, policy: DepthPolicy) -> Result<Arc<RenderJob>> {
        let bad = |e: serde_json::Error| ServeError::BadRequest(e.to_string());
        let key = format!(
            "{}|{}",
            serde_json::to_string(spec).map_err(bad)?,
            serde_json::to_string(&policy).map_err(bad)?
        );
        if let Some(j) = lock(&self.jobs).get(&key) {
            return Ok(j);
        }
        let job = RenderJob::new(self.renderer(spec)?, policy, 0, KEPT_PREPARED)
            .map_err(|e| ServeError::BadRequest(e.to_string()))?
            .with_kept_bytes(KEPT_PREPARED_BYTES);
        let job = Arc::new(job);
        lock(&self.jobs).put(key, job.clone());
        Ok(job)
    }

    /// The name commands give a clean source.
    pub(crate) fn clean_name(&self, source: &CleanSource) -> Result<String> {
        match source {
            CleanSource::Index(i) => {
                let shown = self.cleans.dir().join(self.cleans.rel(*i)?);
                Ok(shown.display().to_string())
            }
            CleanSource::Upload(id) => {
                let u = self.uploads.get(id)?;
                if u.depth {
                    return Err(ServeError::BadRequest(format!(
                        "{id} is a depth map, not a photo"
                    )));
                }
                Ok(u.name)
            }
        }
    }

    fn clean_encoded(&self, source: &CleanSource) -> Result<Encoded> {
        match source {
            CleanSource::Index(i) => Ok(Encoded {
                bytes: self.cleans.read(*i)?,
                what: format!("clean image {}", self.cleans.rel(*i)?),
                theirs: false,
            }),
            CleanSource::Upload(id) => {
                self.clean_name(source)?;
                let u = self.uploads.get(id)?;
                Ok(Encoded {
                    bytes: u.read()?,
                    what: u.name,
                    theirs: true,
                })
            }
        }
    }

    /// Bytes that decoding `e` holds at its peak, from its header (the file, the decoded
    /// samples and a rotated copy, the planar f32 image); `None` when the header is unreadable or
    /// beyond the limits (the decoder then refuses it before allocating).
    fn decode_bytes(&self, e: &Encoded) -> Option<u64> {
        let (w, h, bpp) = probe_memory(&e.bytes).ok()?;
        let pixels = u64::from(w) * u64::from(h);
        (pixels <= self.limits.max_pixels && w.max(h) <= self.limits.max_dimension)
            .then(|| e.bytes.len() as u64 + pixels * (2 * bpp + 12))
    }

    pub(crate) fn lease(&self, bytes: u64, what: &str, wait: Duration) -> Result<Lease> {
        self.budget.take(bytes, what, wait)
    }

    /// Decodes `e` within the memory budget.
    fn decode(&self, e: &Encoded) -> Result<Image> {
        let _lease = match self.decode_bytes(e) {
            Some(bytes) => Some(self.lease(bytes, &e.what, DECODE_WAIT)?),
            None => None,
        };
        load_rgb_from_memory(&e.bytes, &self.limits).map_err(|x| e.failed(reason(&x)))
    }

    /// The clean image at `size`.
    pub(crate) fn clean_image(&self, source: &CleanSource, size: RenderSize) -> Result<Arc<Image>> {
        if size == RenderSize::Preview
            && let Some(img) = lock(&self.previews).get(source)
        {
            return Ok(img);
        }
        let encoded = self.clean_encoded(source)?;
        let full = self.decode(&encoded)?;
        if size == RenderSize::Full {
            return Ok(Arc::new(full));
        }
        let preview = Arc::new(
            fit_within(&full, self.config.preview_size).map_err(|x| encoded.failed(reason(&x)))?,
        );
        lock(&self.previews).put(source.clone(), preview.clone());
        Ok(preview)
    }

    /// The map beside clean source `clean`: its resolved path, its path in the folder and the
    /// name commands give it.
    fn beside(&self, clean: &CleanSource) -> Result<(PathBuf, String, String)> {
        let CleanSource::Index(i) = clean else {
            return Err(ServeError::BadRequest(
                "a dropped photo has no depth/ folder beside it: drop its depth map".into(),
            ));
        };
        let map = self.beside_map(*i)?.ok_or_else(|| {
            ServeError::BadRequest(
                "this photo has no map in a depth/ folder beside it (X/rgb/NAME with X/depth/)"
                    .into(),
            )
        })?;
        // Named below the folder as given, as the other paths of the commands are.
        let rel = map.strip_prefix(self.cleans.root()).unwrap_or(&map);
        let shown = self.cleans.dir().join(rel).display().to_string();
        let rel = rel.display().to_string();
        Ok((map, rel, shown))
    }

    /// The name commands give the depth map a choice reads (`None`: the prior).
    pub(crate) fn depth_name(
        &self,
        clean: &CleanSource,
        choice: &DepthChoice,
    ) -> Result<Option<String>> {
        Ok(match choice {
            DepthChoice::Prior => None,
            DepthChoice::Beside => Some(self.beside(clean)?.2),
            DepthChoice::Upload(id) => Some(self.uploads.get(id)?.name),
        })
    }

    /// The depth map a choice reads (`None`: the prior), with the name notes give it.
    fn depth_file(
        &self,
        clean: &CleanSource,
        choice: &DepthChoice,
    ) -> Result<Option<(Encoded, String)>> {
        match choice {
            DepthChoice::Prior => Ok(None),
            DepthChoice::Beside => {
                let (map, rel, shown) = self.beside(clean)?;
                let bytes = read_inside(self.cleans.root(), &map, "depth", &rel)?;
                let what = format!("depth map {rel}");
                let encoded = Encoded {
                    bytes,
                    what,
                    theirs: false,
                };
                Ok(Some((encoded, shown)))
            }
            DepthChoice::Upload(id) => {
                let u = self.uploads.get(id)?;
                let encoded = Encoded {
                    bytes: u.read()?,
                    what: format!("depth map {}", u.name),
                    theirs: true,
                };
                Ok(Some((encoded, u.name)))
            }
        }
    }

    /// The map in `X/depth/` beside clean image `i` (`X/rgb/NAME`), inside the clean folder.
    pub(crate) fn beside_map(&self, i: usize) -> Result<Option<PathBuf>> {
        self.cleans.path(i)?;
        Ok(self.beside.get(i).cloned().flatten())
    }

    /// The depth of `clean` as `uwnr render` computes it (`--depth FILE` for a map).
    pub(crate) fn depth(
        &self,
        clean: &Image,
        source: &CleanSource,
        choice: &DepthChoice,
    ) -> Result<Depth> {
        let Some((encoded, name)) = self.depth_file(source, choice)? else {
            return DepthSource::Builtin
                .prepare()
                .and_then(|d| d.depth_for(clean, None))
                .map_err(|e| ServeError::ServerFile {
                    what: "depth".into(),
                    reason: e.to_string(),
                });
        };
        let _lease = match self.decode_bytes(&encoded) {
            Some(bytes) => {
                self.lease(bytes + image_bytes(clean) / 3, &encoded.what, DECODE_WAIT)?
            }
            None => self.lease(4 * encoded.bytes.len() as u64, &encoded.what, DECODE_WAIT)?,
        };
        let (map, notes, metric_max) = uwnr_depth::read_map_bytes(
            &encoded.bytes,
            Path::new(&name),
            clean.size(),
            DepthUnit::Relative,
            false,
            &self.limits,
        )
        .map_err(|x| encoded.failed(reason(&x)))?;
        Ok(Depth {
            map,
            notes,
            relative: false,
            metric_max,
            prior: false,
        })
    }

    /// Reference `i`, decoded at full size (kept within [`KEPT_REFERENCE_BYTES`]).
    fn reference(&self, i: usize) -> Result<Arc<Image>> {
        if let Some(img) = lock(&self.references).get(&i) {
            return Ok(img);
        }
        let encoded = Encoded {
            bytes: self.refs.read(i)?,
            what: format!("reference {}", self.refs.rel(i)?),
            theirs: false,
        };
        let img = Arc::new(self.decode(&encoded)?);
        lock(&self.references).put_sized(i, img.clone(), image_bytes(&img));
        Ok(img)
    }

    /// Renders a request (what the pool's workers run).
    pub fn render(&self, page: &PageRender) -> Result<Output> {
        let req = &page.view;
        let job = self.job(&page.spec, page.policy)?;
        // The render's planes are counted before the clean image is decoded.
        let pixels = match req.size {
            RenderSize::Preview => (self.config.preview_size * self.config.preview_size) as u64,
            RenderSize::Full => {
                let (w, h, _) = probe_memory(&self.clean_encoded(&req.clean)?.bytes)
                    .map_err(|e| ServeError::BadRequest(reason(&e)))?;
                u64::from(w) * u64::from(h)
            }
        };
        let _lease = self.lease(pixels * RENDER_BYTES_PER_PIXEL, "the render", RENDER_WAIT)?;
        let clean = self.clean_image(&req.clean, req.size)?;
        let depth = self.depth(&clean, &req.clean, &req.depth)?;
        // `uwnr render` with one clean image renders item 0 of its batch.
        let seed = uwnr_core::seed::item_seed(req.options.seed, 0);
        let prepared = if job.renderer().uses_reference() {
            let i = req.reference.ok_or_else(|| {
                ServeError::BadRequest(format!(
                    "method {} needs a reference: select one",
                    page.spec.name()
                ))
            })?;
            // Decoding errors keep their own kind; the decoded image is shared, not copied.
            let image = self.reference(i)?;
            let prepared = job
                .reference(&i.to_string(), || Ok(image))
                .map_err(|e| ServeError::BadRequest(e.to_string()))?;
            Some(prepared)
        } else {
            None
        };
        let out = job.worker().render(
            &clean,
            &depth,
            prepared
                .as_deref()
                .map(uwnr_render::PreparedReference::input),
            seed,
        )?;
        let png = encode_rgb_png(&out.image).map_err(|e| ServeError::ServerFile {
            what: "the render".into(),
            reason: e.to_string(),
        })?;
        Ok(Output {
            png: Arc::new(png),
            width: out.image.width(),
            height: out.image.height(),
            params: out.params.to_value(),
        })
    }

    /// The first `k` references clean image `clean` draws in `uwnr dataset --seed seed`.
    pub fn draw(&self, clean: usize, k: usize, seed: u64) -> Vec<usize> {
        ReferenceOrder::new(seed, clean, self.refs.len())
            .take(k)
            .collect()
    }

    /// Reference `i`'s thumbnail and statistics (a reference that cannot be read: why).
    pub(crate) fn ref_info(&self, i: usize) -> Result<std::result::Result<RefInfo, String>> {
        if let Some(info) = lock(&self.thumbs).get(&i) {
            return Ok(info);
        }
        let what = format!("reference {}", self.refs.rel(i)?);
        let encoded = match self.refs.read(i) {
            Ok(bytes) => Encoded {
                bytes,
                what,
                theirs: false,
            },
            Err(e @ ServeError::OutsideRoot { .. }) => return Err(e),
            Err(e) => return Ok(Err(e.to_string())),
        };
        let img = match self.decode(&encoded) {
            Ok(img) => img,
            // Memory in use by others: answered 503, not remembered as a bad reference.
            Err(e @ (ServeError::NoMemory { .. } | ServeError::TooBig { .. })) => return Err(e),
            Err(e) => {
                let m = e.to_string();
                lock(&self.thumbs).put(i, Err(m.clone()));
                return Ok(Err(m));
            }
        };
        let info = (|| -> std::result::Result<RefInfo, String> {
            let small = fit_within(&img, STATS_SIDE).map_err(|e| e.to_string())?;
            let thumb = fit_within(&small, THUMB_SIDE).map_err(|e| e.to_string())?;
            let mean = [0, 1, 2].map(|c| {
                let p = small.plane(c);
                p.iter().map(|&v| f64::from(v)).sum::<f64>() / p.len().max(1) as f64
            });
            let veil = quadtree_background(&small, SUID_MIN_REGION_FRACTION, BackgroundPick::Mean)
                .map_err(|e| e.to_string())?;
            Ok(RefInfo {
                thumb: Arc::new(encode_rgb_png(&thumb).map_err(|e| e.to_string())?),
                mean,
                veil,
            })
        })();
        lock(&self.thumbs).put(i, info.clone());
        Ok(info)
    }
}

/// The depth map beside each clean image, resolved inside the clean folder (each `depth/`
/// folder listed once).
fn beside_maps(cleans: &Library) -> Vec<Option<PathBuf>> {
    let inside: Vec<(usize, PathBuf)> = (0..cleans.len())
        .filter_map(|i| Some((i, cleans.path(i).ok()?.to_path_buf())))
        .collect();
    let paths: Vec<PathBuf> = inside.iter().map(|(_, p)| p.clone()).collect();
    let found = uwnr_depth::beside_maps(&paths).unwrap_or_else(|_| vec![None; paths.len()]);
    let mut out = vec![None; cleans.len()];
    for ((i, _), map) in inside.into_iter().zip(found) {
        out[i] = map
            .and_then(|m| m.canonicalize().ok())
            .filter(|m| m.starts_with(cleans.root()));
    }
    out
}
