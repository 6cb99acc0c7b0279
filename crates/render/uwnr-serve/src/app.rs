//! The server's state and routes: the two image folders, dropped images, loaded methods, caches
//! and the render pool, and the JSON API the page calls.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use serde_json::{Value, json};
use uwnr_baselines::background::SUID_MIN_REGION_FRACTION;
use uwnr_baselines::{BackgroundPick, quadtree_background};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, encode_rgb_png, load_rgb, load_rgb_from_memory};
use uwnr_core::resize::fit_within;
use uwnr_dataset::DepthPolicy;
use uwnr_dataset::plan::ReferenceOrder;
use uwnr_depth::{DepthSource, DepthUnit};
use uwnr_render::lru::Lru;
use uwnr_render::{MethodSpec, RenderJob, Renderer};

use crate::ServeConfig;
use crate::error::{Result, ServeError};
use crate::http::{Request, Response};
use crate::jobs::{Output, Pool};
use crate::paths::Library;
use crate::view::{CleanSource, DepthChoice, PAGE_METHODS, RenderSize, ViewRequest, command_line};

/// Longer side of reference thumbnails, pixels.
pub const THUMB_SIDE: usize = 160;
/// Longer side of the copy of a reference its statistics are computed on, pixels.
const STATS_SIDE: usize = 256;
/// Reference thumbnails and statistics kept (about 40 kB each).
const KEPT_THUMBS: usize = 512;
/// Decoded images kept (clean previews, references at full size).
const KEPT_IMAGES: usize = 8;
/// Dropped images kept on disk (older ones are deleted).
const KEPT_UPLOADS: usize = 16;
/// Loaded methods kept (the networks' weights are the large part).
const KEPT_RENDERERS: usize = 12;
/// Render jobs kept (a method with a depth setting), each with the references it prepared.
const KEPT_JOBS: usize = 4;
/// References a job keeps prepared (a baseline's share the decoded image with the decoded
/// references kept above: at most `KEPT_IMAGES + KEPT_JOBS * KEPT_PREPARED` full-size images).
const KEPT_PREPARED: usize = 2;
/// Largest reference page.
const MAX_PAGE: usize = 100;

const INDEX_HTML: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const STYLE_CSS: &str = include_str!("../assets/style.css");

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// An image dropped into the page, kept as a file in the server's temporary folder.
#[derive(Clone, Debug)]
struct Upload {
    path: PathBuf,
    /// The name the user's file had (what commands name).
    name: String,
    depth: bool,
}

/// A reference's thumbnail and statistics.
#[derive(Clone)]
struct RefInfo {
    thumb: Arc<Vec<u8>>,
    mean: [f64; 3],
    veil: [f64; 3],
}

/// Everything a render or a request reads.
pub struct Engine {
    config: ServeConfig,
    cleans: Library,
    /// The depth map beside each clean image (`X/rgb/NAME` with `X/depth/`), found once.
    beside: Vec<Option<PathBuf>>,
    refs: Library,
    limits: DecodeLimits,
    upload_dir: tempfile::TempDir,
    uploads: Mutex<(u64, VecDeque<(String, Upload)>)>,
    renderers: Mutex<Lru<String, Arc<Renderer>>>,
    jobs: Mutex<Lru<String, Arc<RenderJob>>>,
    previews: Mutex<Lru<CleanSource, Arc<Image>>>,
    references: Mutex<Lru<usize, Arc<Image>>>,
    thumbs: Mutex<Lru<usize, std::result::Result<RefInfo, String>>>,
}

impl Engine {
    /// Lists the folders and loads the networks (so the first render does not wait for them).
    pub fn new(config: ServeConfig) -> Result<Self> {
        let cleans = Library::open(&config.clean, "clean")?;
        let refs = Library::open(&config.references, "reference")?;
        let upload_dir = tempfile::Builder::new()
            .prefix("uwnr-serve-")
            .tempdir()
            .map_err(ServeError::io("creating the folder for dropped images"))?;
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
            upload_dir,
            uploads: Mutex::new((1, VecDeque::new())),
            renderers: Mutex::new(Lru::new(KEPT_RENDERERS)),
            jobs: Mutex::new(Lru::new(KEPT_JOBS)),
            previews: Mutex::new(Lru::new(KEPT_IMAGES)),
            references: Mutex::new(Lru::new(KEPT_IMAGES)),
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
            .map_err(|e| ServeError::BadRequest(e.to_string()))?;
        let job = Arc::new(job);
        lock(&self.jobs).put(key, job.clone());
        Ok(job)
    }

    fn upload(&self, id: &str) -> Result<Upload> {
        lock(&self.uploads)
            .1
            .iter()
            .find(|(k, _)| k == id)
            .map(|(_, u)| u.clone())
            .ok_or_else(|| {
                ServeError::Missing(format!(
                    "no dropped image {id:?} (the server keeps the last {KEPT_UPLOADS}); drop it again"
                ))
            })
    }

    /// The file of a clean source and the name commands give it.
    fn clean_file(&self, source: &CleanSource) -> Result<(PathBuf, String)> {
        match source {
            CleanSource::Index(i) => {
                let path = self.cleans.path(*i)?.to_path_buf();
                let shown = self.cleans.dir().join(self.cleans.rel(*i)?);
                Ok((path, shown.display().to_string()))
            }
            CleanSource::Upload(id) => {
                let u = self.upload(id)?;
                if u.depth {
                    return Err(ServeError::BadRequest(format!(
                        "{id} is a depth map, not a photo"
                    )));
                }
                Ok((u.path, u.name))
            }
        }
    }

    fn decode(&self, path: &Path, what: &str) -> Result<Image> {
        load_rgb(path, &self.limits).map_err(|e| ServeError::BadImage {
            what: what.to_string(),
            reason: e.to_string(),
        })
    }

    /// The clean image at `size`.
    fn clean_image(&self, source: &CleanSource, size: RenderSize) -> Result<Arc<Image>> {
        if size == RenderSize::Preview
            && let Some(img) = lock(&self.previews).get(source)
        {
            return Ok(img);
        }
        let (path, name) = self.clean_file(source)?;
        let full = self.decode(&path, &format!("clean image {name}"))?;
        if size == RenderSize::Full {
            return Ok(Arc::new(full));
        }
        let preview = Arc::new(fit_within(&full, self.config.preview_size).map_err(|e| {
            ServeError::BadImage {
                what: name,
                reason: e.to_string(),
            }
        })?);
        lock(&self.previews).put(source.clone(), preview.clone());
        Ok(preview)
    }

    /// The depth map file a choice reads (`None`: the prior).
    fn depth_file(
        &self,
        clean: &CleanSource,
        choice: &DepthChoice,
    ) -> Result<Option<(PathBuf, String)>> {
        match choice {
            DepthChoice::Prior => Ok(None),
            DepthChoice::Beside => {
                let CleanSource::Index(i) = clean else {
                    return Err(ServeError::BadRequest(
                        "a dropped photo has no depth/ folder beside it: drop its depth map".into(),
                    ));
                };
                let map = self.beside_map(*i)?.ok_or_else(|| {
                    ServeError::BadRequest(
                        "this photo has no map in a depth/ folder beside it (X/rgb/NAME with X/depth/)".into(),
                    )
                })?;
                // Named below the folder as given, as the other paths of the commands are.
                let shown = self
                    .cleans
                    .dir()
                    .join(map.strip_prefix(self.cleans.root()).unwrap_or(&map));
                Ok(Some((map.clone(), shown.display().to_string())))
            }
            DepthChoice::Upload(id) => {
                let u = self.upload(id)?;
                Ok(Some((u.path, u.name)))
            }
        }
    }

    /// The map in `X/depth/` beside clean image `i` (`X/rgb/NAME`), inside the clean folder.
    fn beside_map(&self, i: usize) -> Result<Option<PathBuf>> {
        self.cleans.path(i)?;
        Ok(self.beside.get(i).cloned().flatten())
    }

    /// The folder dropped images are kept in (removed when the server is dropped).
    #[must_use]
    pub fn upload_dir(&self) -> &Path {
        self.upload_dir.path()
    }

    /// The depth of `clean` as `uwnr render` computes it (`--depth FILE` for a map).
    fn depth(
        &self,
        clean: &Image,
        source: &CleanSource,
        choice: &DepthChoice,
    ) -> Result<uwnr_depth::Depth> {
        let (clean_path, _) = self.clean_file(source)?;
        let src = match self.depth_file(source, choice)? {
            None => DepthSource::Builtin,
            Some((path, _)) => DepthSource::Maps {
                path,
                invert: false,
                normalize: false,
                unit: DepthUnit::Relative,
            },
        };
        let bad = |e: uwnr_depth::DepthError| ServeError::BadImage {
            what: "depth".into(),
            reason: e.to_string(),
        };
        src.prepare_with_limits(self.limits)
            .map_err(bad)?
            .depth_for(clean, Some(&clean_path))
            .map_err(bad)
    }

    /// Reference `i`, decoded at full size.
    fn reference(&self, i: usize) -> Result<Arc<Image>> {
        if let Some(img) = lock(&self.references).get(&i) {
            return Ok(img);
        }
        let path = self.refs.path(i)?;
        let img = Arc::new(self.decode(path, &format!("reference {}", self.refs.rel(i)?))?);
        lock(&self.references).put(i, img.clone());
        Ok(img)
    }

    /// Renders a request (what the pool's workers run).
    pub fn render(&self, req: &ViewRequest) -> Result<Output> {
        let spec = req.options.spec()?;
        let mut policy = DepthPolicy::render();
        if let Some((a, b)) = req.options.depth_scale {
            policy.scene_scale_m = (a as f32, b as f32);
        }
        let job = self.job(&spec, policy)?;
        let clean = self.clean_image(&req.clean, req.size)?;
        let depth = self.depth(&clean, &req.clean, &req.depth)?;
        // `uwnr render` with one clean image renders item 0 of its batch.
        let seed = uwnr_baselines::item_seed(req.options.seed, 0);
        let prepared = if job.renderer().uses_reference() {
            let i = req.reference.ok_or_else(|| {
                ServeError::BadRequest(format!(
                    "method {} needs a reference: select one",
                    spec.name()
                ))
            })?;
            // Decoding errors keep their own kind; the decoded image is shared, not copied.
            let image = self.reference(i)?;
            let prepared = job
                .reference(&i.to_string(), || Ok(image))
                .map_err(ServeError::BadRequest)?;
            Some(prepared)
        } else {
            None
        };
        let out = job.worker()?.render(
            &clean,
            &depth,
            prepared
                .as_deref()
                .map(uwnr_render::PreparedReference::input),
            seed,
        )?;
        let png = encode_rgb_png(&out.image).map_err(|e| ServeError::BadRequest(e.to_string()))?;
        Ok(Output {
            png: Arc::new(png),
            width: out.image.width(),
            height: out.image.height(),
            params: out.params,
        })
    }

    /// The `uwnr render` and `uwnr dataset` commands of a request, and notes on what they
    /// cannot say.
    pub fn commands(&self, req: &ViewRequest) -> Result<(String, String, Vec<String>)> {
        let mut notes = Vec::new();
        let (_, clean_name) = self.clean_file(&req.clean)?;
        if matches!(req.clean, CleanSource::Upload(_)) {
            notes.push(format!(
                "{clean_name} was dropped into the page: run the command where that file is"
            ));
        }
        let o = &req.options;
        let stem = |s: &str| {
            Path::new(s)
                .file_stem()
                .map(|x| x.to_string_lossy().into_owned())
                .unwrap_or_default()
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect::<String>()
        };
        let mut render = vec!["uwnr".to_string(), "render".to_string(), clean_name.clone()];
        let mut out_name = format!("uwnr-{}", stem(&clean_name));
        if o.reads_reference()? {
            let i = req
                .reference
                .ok_or_else(|| ServeError::BadRequest("select a reference".into()))?;
            let rel = self.refs.rel(i)?;
            render.push("--reference".into());
            render.push(self.refs.dir().join(rel).display().to_string());
            out_name.push_str(&format!("-{}", stem(rel)));
        }
        render.extend(o.flags());
        if let Some((_, name)) = self.depth_file(&req.clean, &req.depth)? {
            render.push("--depth".into());
            render.push(name);
            if matches!(req.depth, DepthChoice::Upload(_)) {
                notes.push(
                    "the depth map was dropped into the page: run the command where that file is"
                        .into(),
                );
            }
        }
        render.push("--seed".into());
        render.push(o.seed.to_string());
        render.push("--output".into());
        render.push(format!("{out_name}-{}.png", o.method));

        let draw = req
            .dataset
            .unwrap_or(crate::view::DatasetDraw { k: 1, seed: 0 });
        let mut dataset = vec![
            "uwnr".to_string(),
            "dataset".to_string(),
            "--clean".into(),
            self.cleans.dir().display().to_string(),
            "--references".into(),
            self.refs.dir().display().to_string(),
            "-k".into(),
            draw.k.max(1).to_string(),
            "--seed".into(),
            draw.seed.to_string(),
        ];
        dataset.extend(o.flags());
        dataset.push("--output".into());
        dataset.push(format!("uwnr-dataset-{}", o.method));
        Ok((command_line(&render), command_line(&dataset), notes))
    }

    /// The first `k` references clean image `clean` draws in `uwnr dataset --seed seed`.
    pub fn draw(&self, clean: usize, k: usize, seed: u64) -> Vec<usize> {
        ReferenceOrder::new(seed, clean, self.refs.len())
            .take(k)
            .collect()
    }

    fn ref_info(&self, i: usize) -> Result<std::result::Result<RefInfo, String>> {
        if let Some(info) = lock(&self.thumbs).get(&i) {
            return Ok(info);
        }
        let path = self.refs.path(i)?;
        let info = (|| -> std::result::Result<RefInfo, String> {
            let img = load_rgb(path, &self.limits).map_err(|e| e.to_string())?;
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

    /// Stores a dropped image after checking that it decodes within the limits.
    pub fn store_upload(&self, bytes: &[u8], name: &str, depth: bool) -> Result<Value> {
        let name: String = Path::new(name)
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "dropped.png".into());
        let img = load_rgb_from_memory(bytes, &self.limits).map_err(|e| ServeError::BadImage {
            what: name.clone(),
            reason: e.to_string(),
        })?;
        let mut g = lock(&self.uploads);
        let id = format!("u{}", g.0);
        g.0 += 1;
        let ext = Path::new(&name)
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .filter(|e| uwnr_core::io::IMAGE_EXTENSIONS.contains(&e.as_str()))
            .unwrap_or_else(|| "png".into());
        let path = self.upload_dir.path().join(format!("{id}.{ext}"));
        std::fs::write(&path, bytes).map_err(ServeError::io("saving a dropped image"))?;
        g.1.push_back((
            id.clone(),
            Upload {
                path,
                name: name.clone(),
                depth,
            },
        ));
        while g.1.len() > KEPT_UPLOADS {
            if let Some((_, old)) = g.1.pop_front() {
                let _ = std::fs::remove_file(old.path);
            }
        }
        Ok(json!({ "id": id, "name": name, "width": img.width(), "height": img.height() }))
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

/// The engine and its pool: what every request handler shares.
pub struct App {
    pub engine: Arc<Engine>,
    pub pool: Arc<Pool<ViewRequest>>,
}

fn png(bytes: Vec<u8>) -> Response {
    Response::bytes("image/png", bytes)
}

/// A depth map min-max stretched for display (a metric or dark map is otherwise near black);
/// renders read the map itself.
fn stretched(map: &Image) -> Image {
    let mut out = map.clone();
    let (lo, hi) = map
        .data()
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if hi > lo {
        for v in out.data_mut() {
            *v = (*v - lo) / (hi - lo);
        }
    }
    out
}

fn grey_to_rgb(map: &Image) -> Result<Image> {
    Image::concat_channels(&[map, map, map]).map_err(|e| ServeError::BadRequest(e.to_string()))
}

fn parse_clean(s: Option<&str>) -> Result<CleanSource> {
    let s = s.ok_or_else(|| ServeError::BadRequest("missing clean=".into()))?;
    if let Some(id) = s.strip_prefix('u') {
        return Ok(CleanSource::Upload(format!("u{id}")));
    }
    s.parse()
        .map(CleanSource::Index)
        .map_err(|_| ServeError::BadRequest(format!("bad clean image {s:?}")))
}

fn parse_num<T: std::str::FromStr>(req: &Request, name: &str, default: T) -> Result<T> {
    match req.param(name) {
        None => Ok(default),
        Some(v) => v
            .parse()
            .map_err(|_| ServeError::BadRequest(format!("bad {name}={v:?}"))),
    }
}

impl App {
    /// Answers one request; errors become `{"error": ...}` with their status.
    pub fn handle(&self, req: &Request) -> Response {
        match self.route(req) {
            Ok(r) => r,
            Err(e) => Response::error(e.status(), &e.to_string()),
        }
    }

    fn route(&self, req: &Request) -> Result<Response> {
        let e = &self.engine;
        let segments: Vec<&str> = req.path.trim_matches('/').split('/').collect();
        let get = req.method == "GET" || req.method == "HEAD";
        let post = req.method == "POST";
        Ok(match (segments.as_slice(), get, post) {
            ([""], true, _) | (["index.html"], true, _) => {
                Response::bytes("text/html; charset=utf-8", INDEX_HTML.as_bytes().to_vec())
            }
            (["app.js"], true, _) => {
                Response::bytes("text/javascript; charset=utf-8", APP_JS.as_bytes().to_vec())
            }
            (["style.css"], true, _) => {
                Response::bytes("text/css; charset=utf-8", STYLE_CSS.as_bytes().to_vec())
            }
            (["api", "info"], true, _) => Response::json(200, &self.info()?),
            (["api", "status"], true, _) => {
                let (queued, running, kept) = self.pool.counts();
                Response::json(
                    200,
                    &json!({ "queued": queued, "running": running, "kept": kept, "capacity": self.pool.capacity() }),
                )
            }
            (["api", "clean", "find"], true, _) => {
                let rel = req.param("path").unwrap_or("");
                Response::json(200, &json!({ "index": e.cleans.find(rel)? }))
            }
            (["api", "reference", "find"], true, _) => {
                let rel = req.param("path").unwrap_or("");
                Response::json(200, &json!({ "index": e.refs.find(rel)? }))
            }
            (["api", "clean", "image"], true, _) => {
                let source = parse_clean(req.param("clean"))?;
                let img = e.clean_image(&source, RenderSize::Preview)?;
                png(encode_rgb_png(&img).map_err(|x| ServeError::BadRequest(x.to_string()))?)
            }
            (["api", "clean", "depth"], true, _) => {
                let source = parse_clean(req.param("clean"))?;
                let choice = match req.param("depth").unwrap_or("prior") {
                    "prior" => DepthChoice::Prior,
                    "beside" => DepthChoice::Beside,
                    id => DepthChoice::Upload(id.to_string()),
                };
                let img = e.clean_image(&source, RenderSize::Preview)?;
                let depth = e.depth(&img, &source, &choice)?;
                png(encode_rgb_png(&grey_to_rgb(&stretched(&depth.map))?)
                    .map_err(|x| ServeError::BadRequest(x.to_string()))?)
            }
            (["api", "references"], true, _) => {
                let per = parse_num(req, "per", 24_usize)?.clamp(1, MAX_PAGE);
                let page = parse_num(req, "page", 0_usize)?;
                let items: Vec<Value> = (page * per..((page + 1) * per).min(e.refs.len()))
                    .map(|i| self.reference_json(i))
                    .collect::<Result<_>>()?;
                Response::json(
                    200,
                    &json!({ "total": e.refs.len(), "page": page, "per": per, "items": items }),
                )
            }
            (["api", "reference", i, "thumb"], true, _) => {
                let i: usize = i
                    .parse()
                    .map_err(|_| ServeError::BadRequest(format!("bad reference {i:?}")))?;
                match e.ref_info(i)? {
                    Ok(info) => png((*info.thumb).clone()),
                    Err(m) => {
                        return Err(ServeError::BadImage {
                            what: format!("reference {}", e.refs.rel(i)?),
                            reason: m,
                        });
                    }
                }
            }
            (["api", "draw"], true, _) => {
                let clean = parse_clean(req.param("clean"))?;
                let k = parse_num(req, "k", 1_usize)?.min(e.refs.len());
                let seed = parse_num(req, "seed", 0_u64)?;
                // A dropped photo is drawn for as the first clean image.
                let index = match clean {
                    CleanSource::Index(i) => i,
                    CleanSource::Upload(_) => 0,
                };
                Response::json(200, &json!({ "references": e.draw(index, k, seed) }))
            }
            (["api", "upload"], _, true) => {
                let depth = req.param("kind") == Some("depth");
                let name = req.param("name").unwrap_or("dropped.png");
                Response::json(200, &e.store_upload(&req.body, name, depth)?)
            }
            (["api", "render"], _, true) => {
                let view: ViewRequest = serde_json::from_slice(&req.body)
                    .map_err(|x| ServeError::BadRequest(format!("bad render request: {x}")))?;
                view.options.check()?;
                let (render, dataset, notes) = e.commands(&view)?;
                let id = self.pool.submit(&view.view.clone(), view)?;
                Response::json(
                    200,
                    &json!({ "job": id, "render_command": render, "dataset_command": dataset, "notes": notes }),
                )
            }
            (["api", "job", id], true, _) => {
                let id = parse_job(id)?;
                let status = self.pool.status_json(id).ok_or_else(|| {
                    ServeError::Missing(format!(
                        "no job {id} (results are kept for the latest renders only)"
                    ))
                })?;
                Response::json(200, &status)
            }
            (["api", "job", id, "image"], true, _) => {
                let id = parse_job(id)?;
                let out = self.pool.output(id).ok_or_else(|| {
                    ServeError::Missing(format!(
                        "job {id} has no image (not done, failed, stale or forgotten)"
                    ))
                })?;
                let r = png((*out.png).clone());
                match req.param("download") {
                    Some(name) => {
                        let safe: String = name
                            .chars()
                            .filter(|c| c.is_ascii_alphanumeric() || "-_.".contains(*c))
                            .collect();
                        r.with_header(
                            "Content-Disposition",
                            format!("attachment; filename=\"{safe}\""),
                        )
                    }
                    None => r,
                }
            }
            (_, false, false) => Response::error(405, "method not allowed"),
            _ => return Err(ServeError::Missing(format!("no such page: {}", req.path))),
        })
    }

    fn reference_json(&self, i: usize) -> Result<Value> {
        let e = &self.engine;
        let rel = e.refs.rel(i)?;
        Ok(
            match e.refs.path(i).map(|_| ()).and_then(|()| e.ref_info(i)) {
                Ok(Ok(info)) => {
                    json!({ "index": i, "rel": rel, "mean": info.mean, "veil": info.veil })
                }
                Ok(Err(m)) => json!({ "index": i, "rel": rel, "error": m }),
                Err(x) => json!({ "index": i, "rel": rel, "error": x.to_string() }),
            },
        )
    }

    fn info(&self) -> Result<Value> {
        let e = &self.engine;
        let cleans: Vec<Value> = (0..e.cleans.len())
            .map(|i| {
                Ok(json!({
                    "index": i,
                    "rel": e.cleans.rel(i)?,
                    "depth_beside": e.beside_map(i).ok().flatten().is_some(),
                }))
            })
            .collect::<Result<_>>()?;
        Ok(json!({
            "version": env!("CARGO_PKG_VERSION"),
            "cleans": cleans,
            "references": e.refs.len(),
            "clean_dir": e.cleans.dir().display().to_string(),
            "references_dir": e.refs.dir().display().to_string(),
            "methods": PAGE_METHODS.map(|m| m.name()),
            "preview_size": e.config.preview_size,
            "max_upload_bytes": e.config.max_upload_bytes,
            "max_pixels": e.config.max_pixels,
            "max_dimension": e.config.max_dimension,
            "queue": self.pool.capacity(),
        }))
    }
}

fn parse_job(s: &str) -> Result<u64> {
    s.parse()
        .map_err(|_| ServeError::BadRequest(format!("bad job id {s:?}")))
}
