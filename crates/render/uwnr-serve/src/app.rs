//! The page's routes: the JSON API it calls and the files it is made of, behind the local-only
//! guard ([`crate::access`]).

use std::path::Path;
use std::sync::Arc;

use serde_json::{Value, json};
use uwnr_core::Image;
use uwnr_core::io::encode_rgb_png;

use crate::access::Access;
use crate::engine::Engine;
use crate::error::{Result, ServeError};
use crate::http::{Request, Response, Service};
use crate::jobs::Pool;
use crate::view::{
    CleanSource, DepthChoice, PAGE_METHODS, PageRender, RenderSize, ViewRequest, command_line,
};

/// Largest reference page.
const MAX_PAGE: usize = 100;

const INDEX_HTML: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const STYLE_CSS: &str = include_str!("../assets/style.css");

/// Methods of the page's files and of the API's reads.
const READ: &str = "GET, HEAD";
/// Methods of the API's writes.
const WRITE: &str = "POST";

/// The methods the path `segments` answers (`None`: no such path).
fn allowed(segments: &[&str]) -> Option<&'static str> {
    Some(match segments {
        [] | ["index.html" | "app.js" | "style.css"] => READ,
        ["api", "info" | "status" | "references" | "draw"] => READ,
        ["api", "clean" | "reference", "find"] | ["api", "clean", "image" | "depth"] => READ,
        ["api", "reference", _, "thumb"] | ["api", "job", _] | ["api", "job", _, "image"] => READ,
        ["api", "upload" | "render"] => WRITE,
        _ => return None,
    })
}

/// The engine and its pool: what every request handler shares.
pub struct App {
    pub engine: Arc<Engine>,
    pub pool: Arc<Pool<PageRender>>,
    pub access: Access,
}

/// The guard runs on the head alone, before the body is read or counted; `handle` checks again,
/// for callers in the same process.
impl Service for App {
    fn admit(&self, head: &Request) -> std::result::Result<(), Response> {
        self.access
            .check(head)
            .map_err(|e| Response::error(e.status(), &e.to_string()))
    }

    fn handle(&self, request: Request) -> Response {
        App::handle(self, &request)
    }
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

/// A failure of the server's own (encoding, a shape it made).
fn internal(e: impl std::fmt::Display) -> ServeError {
    ServeError::ServerFile {
        what: "the server".into(),
        reason: e.to_string(),
    }
}

fn grey_to_rgb(map: &Image) -> Result<Image> {
    Image::concat_channels(&[map, map, map]).map_err(internal)
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
    /// Answers one request: the local-only guard first, then the route; errors become
    /// `{"error": ...}` with their status (`405` with `Allow`).
    pub fn handle(&self, req: &Request) -> Response {
        if let Err(e) = self.access.check(req) {
            return Response::error(e.status(), &e.to_string());
        }
        match self.route(req) {
            Ok(r) => r,
            Err(e @ ServeError::MethodNotAllowed { allow, .. }) => {
                Response::error(e.status(), &e.to_string()).with_header("allow", allow.into())
            }
            Err(e) => Response::error(e.status(), &e.to_string()),
        }
    }

    fn route(&self, req: &Request) -> Result<Response> {
        let e = &self.engine;
        let segments = req.segments();
        let allow = allowed(&segments)
            .ok_or_else(|| ServeError::Missing(format!("no such page: {}", req.path)))?;
        if !allow.split(", ").any(|m| m == req.method) {
            return Err(ServeError::MethodNotAllowed {
                method: req.method.clone(),
                allow,
            });
        }
        Ok(match segments.as_slice() {
            [] | ["index.html"] => {
                Response::bytes("text/html; charset=utf-8", INDEX_HTML.as_bytes().to_vec())
            }
            ["app.js"] => {
                Response::bytes("text/javascript; charset=utf-8", APP_JS.as_bytes().to_vec())
            }
            ["style.css"] => {
                Response::bytes("text/css; charset=utf-8", STYLE_CSS.as_bytes().to_vec())
            }
            ["api", "info"] => Response::json(200, &self.info()?),
            ["api", "status"] => {
                let (queued, running, kept) = self.pool.counts();
                Response::json(
                    200,
                    &json!({ "queued": queued, "running": running, "kept": kept, "capacity": self.pool.capacity() }),
                )
            }
            ["api", "clean", "find"] => {
                let rel = req.param("path").unwrap_or("");
                Response::json(200, &json!({ "index": e.cleans.find(rel)? }))
            }
            ["api", "reference", "find"] => {
                let rel = req.param("path").unwrap_or("");
                Response::json(200, &json!({ "index": e.refs.find(rel)? }))
            }
            ["api", "clean", "image"] => {
                let source = parse_clean(req.param("clean"))?;
                let img = e.clean_image(&source, RenderSize::Preview)?;
                png(encode_rgb_png(&img).map_err(internal)?)
            }
            ["api", "clean", "depth"] => {
                let source = parse_clean(req.param("clean"))?;
                let choice = match req.param("depth").unwrap_or("prior") {
                    "prior" => DepthChoice::Prior,
                    "beside" => DepthChoice::Beside,
                    id => DepthChoice::Upload(id.to_string()),
                };
                let img = e.clean_image(&source, RenderSize::Preview)?;
                let depth = e.depth(&img, &source, &choice)?;
                png(encode_rgb_png(&grey_to_rgb(&stretched(&depth.map))?).map_err(internal)?)
            }
            ["api", "references"] => {
                let per = parse_num(req, "per", 24_usize)?.clamp(1, MAX_PAGE);
                let page = parse_num(req, "page", 0_usize)?;
                let start = page.checked_mul(per).ok_or_else(|| {
                    ServeError::BadRequest(format!("page {page} is past any folder's end"))
                })?;
                let items: Vec<Value> = (start..start.saturating_add(per).min(e.refs.len()))
                    .map(|i| self.reference_json(i))
                    .collect::<Result<_>>()?;
                Response::json(
                    200,
                    &json!({ "total": e.refs.len(), "page": page, "per": per, "items": items }),
                )
            }
            ["api", "reference", i, "thumb"] => {
                let i: usize = i
                    .parse()
                    .map_err(|_| ServeError::BadRequest(format!("bad reference {i:?}")))?;
                match e.ref_info(i)? {
                    Ok(info) => png((*info.thumb).clone()),
                    Err(m) => {
                        return Err(ServeError::ServerFile {
                            what: format!("reference {}", e.refs.rel(i)?),
                            reason: m,
                        });
                    }
                }
            }
            ["api", "draw"] => {
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
            ["api", "upload"] => {
                let depth = req.param("kind") == Some("depth");
                let name = req.param("name").unwrap_or("dropped.png");
                Response::json(200, &e.store_upload(&req.body, name, depth)?)
            }
            ["api", "render"] => {
                let view: ViewRequest = serde_json::from_slice(&req.body)
                    .map_err(|x| ServeError::BadRequest(format!("bad render request: {x}")))?;
                let page = PageRender::new(view)?;
                let (render, dataset, notes) = commands(e, &page)?;
                let id = self.pool.submit(&page.view.view.clone(), page)?;
                Response::json(
                    200,
                    &json!({ "job": id, "render_command": render, "dataset_command": dataset, "notes": notes }),
                )
            }
            ["api", "job", id] => {
                let id = parse_job(id)?;
                let status = self.pool.status_json(id).ok_or_else(|| {
                    ServeError::Missing(format!(
                        "no job {id} (results are kept for the latest renders only)"
                    ))
                })?;
                Response::json(200, &status)
            }
            ["api", "job", id, "image"] => {
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

/// The `uwnr render` and `uwnr dataset` commands of a request, and notes on what they
/// cannot say.
pub fn commands(e: &Engine, page: &PageRender) -> Result<(String, String, Vec<String>)> {
    let req = &page.view;
    let mut notes = Vec::new();
    let clean_name = e.clean_name(&req.clean)?;
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
    if page.reads_reference() {
        let i = req
            .reference
            .ok_or_else(|| ServeError::BadRequest("select a reference".into()))?;
        let rel = e.refs.rel(i)?;
        render.push("--reference".into());
        render.push(e.refs.dir().join(rel).display().to_string());
        out_name.push_str(&format!("-{}", stem(rel)));
    }
    render.extend(o.flags());
    if let Some(name) = e.depth_name(&req.clean, &req.depth)? {
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
        e.cleans.dir().display().to_string(),
        "--references".into(),
        e.refs.dir().display().to_string(),
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
