//! uwnr-serve: `uwnr serve`, a local page to choose references and compare every render method
//! on one's own photos before generating a dataset.
//!
//! The page (plain HTML, JS and CSS embedded in the binary: nothing is fetched from elsewhere)
//! picks a clean image from the `--clean` folder or a dropped file, its depth (the built-in
//! prior, the map in a `depth/` folder beside it, or a dropped map), and references from the
//! `--references` folder (a paged grid with each one's mean colour and veiling light, or K drawn
//! as `uwnr dataset` draws them); it shows the six methods' renders side by side at a preview
//! size, and the `uwnr render` / `uwnr dataset` commands that reproduce them.
//!
//! Every render goes through [`uwnr_render::RenderJob`], in a pool of worker threads with a
//! bounded queue ([`jobs`]); requests are served by hyper with bounded connections, bodies and
//! deadlines ([`http`]), answered only for this machine's pages ([`access`]: Host, Origin,
//! token); decodes and renders take their bytes from one memory budget ([`budget`]); files are
//! read only inside the two folders, checked when opened ([`paths`]).
//!
//! ```no_run
//! let config = uwnr_serve::ServeConfig::new("photos".into(), "references".into());
//! let server = uwnr_serve::Server::start(config).unwrap();
//! println!("{}", server.url());
//! server.wait();
//! ```

pub mod access;
pub mod app;
pub mod budget;
pub mod engine;
pub mod error;
pub mod http;
pub mod jobs;
pub mod paths;
pub mod uploads;
pub mod view;

use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpListener};
use std::path::PathBuf;
use std::sync::Arc;

pub use error::{Result, ServeError};
pub use view::{MethodOptions, PageRender, ViewRequest};

use crate::access::Access;
use crate::app::App;
use crate::budget::Budget;
pub use crate::engine::Engine;
use crate::http::{HttpLimits, Listener};
use crate::jobs::{Pool, Runner};

/// Default port.
pub const DEFAULT_PORT: u16 = 8787;
/// Default longer side of previews, pixels.
pub const DEFAULT_PREVIEW_SIZE: usize = 384;
/// Default largest upload, bytes (a 24-megapixel JPEG is about 10 MB).
pub const DEFAULT_MAX_UPLOAD_BYTES: u64 = 25 * 1024 * 1024;
/// Default largest image, pixels (a 6000x4000 photo; 288 MB as f32 RGB).
pub const DEFAULT_MAX_PIXELS: u64 = 24_000_000;
/// Default largest side of an image, pixels.
pub const DEFAULT_MAX_DIMENSION: u32 = 8_192;
/// Default render jobs waiting before requests are refused with `503`.
pub const DEFAULT_QUEUE: usize = 32;
/// Default memory budget of decodes and renders in flight, bytes (a render of a 24-megapixel
/// photo at full size needs 1.5 GB of it).
pub const DEFAULT_MEMORY_BYTES: u64 = 1536 * 1024 * 1024;
/// HTTP handler threads.
pub const HTTP_HANDLERS: usize = 8;
/// Admitted connections (their request head passed the guard) open at once; beyond, a request
/// is answered `503` (a slow one costs a task and a socket, not a thread).
pub const HTTP_CONNECTIONS: usize = 256;
/// Connections whose request head has not arrived or not passed the guard; a new one beyond
/// closes the oldest of them (each holds at most a 16 KiB head: 4 MiB in all).
pub const HTTP_WAITING: usize = 256;
/// Largest body of a request other than an upload (a render request is a few hundred bytes).
const SMALL_BODY: u64 = 64 * 1024;

/// How a server runs.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    /// The clean photos folder.
    pub clean: PathBuf,
    /// The references folder.
    pub references: PathBuf,
    /// Address to listen on (default 127.0.0.1: this machine only).
    pub host: IpAddr,
    /// Port (0: any free one).
    pub port: u16,
    /// Longer side of previews.
    pub preview_size: usize,
    /// Largest dropped file, bytes.
    pub max_upload_bytes: u64,
    /// Largest image, pixels (dropped or read from the folders).
    pub max_pixels: u64,
    /// Largest side of an image.
    pub max_dimension: u32,
    /// Render threads.
    pub workers: usize,
    /// Render jobs waiting before requests are refused.
    pub queue: usize,
    /// Bytes that decodes and renders in flight may hold together.
    pub memory_bytes: u64,
    /// Host names answered besides localhost and the server's own addresses (`--allow-host`).
    pub allowed_hosts: Vec<String>,
    /// The token every request must carry; `None`: a new random one when the server listens
    /// beyond loopback, none on loopback.
    pub token: Option<String>,
}

impl ServeConfig {
    /// The defaults, serving `clean` and `references` on 127.0.0.1:8787.
    #[must_use]
    pub fn new(clean: PathBuf, references: PathBuf) -> Self {
        let workers = std::thread::available_parallelism()
            .map(usize::from)
            .unwrap_or(1)
            .min(4);
        Self {
            clean,
            references,
            host: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: DEFAULT_PORT,
            preview_size: DEFAULT_PREVIEW_SIZE,
            max_upload_bytes: DEFAULT_MAX_UPLOAD_BYTES,
            max_pixels: DEFAULT_MAX_PIXELS,
            max_dimension: DEFAULT_MAX_DIMENSION,
            workers,
            queue: DEFAULT_QUEUE,
            memory_bytes: DEFAULT_MEMORY_BYTES,
            allowed_hosts: Vec::new(),
            token: None,
        }
    }
}

/// A running server.
pub struct Server {
    listener: Listener,
    app: Arc<App>,
}

impl Server {
    /// Lists the folders, loads the networks, binds the address and starts serving.
    pub fn start(config: ServeConfig) -> Result<Self> {
        if config.preview_size < 16 {
            return Err(ServeError::BadRequest(
                "the preview size must be at least 16 pixels".into(),
            ));
        }
        let addr = SocketAddr::new(config.host, config.port);
        let socket =
            TcpListener::bind(addr).map_err(ServeError::io(format!("listening on {addr}")))?;
        let token = match (&config.token, config.host.is_loopback()) {
            (Some(t), _) => Some(t.clone()),
            (None, false) => Some(access::new_token()),
            (None, true) => None,
        };
        let access = Access::new(config.host, &config.allowed_hosts, token);
        let limits = HttpLimits {
            handlers: HTTP_HANDLERS,
            connections: HTTP_CONNECTIONS,
            waiting: HTTP_WAITING,
            max_upload: config.max_upload_bytes,
            small_body: SMALL_BODY,
        };
        let budget = Budget::new(config.memory_bytes);
        let (workers, queue) = (config.workers, config.queue);
        let engine = Arc::new(Engine::new(config, budget.clone())?);
        let runner_engine = engine.clone();
        let runner: Arc<Runner<PageRender>> =
            Arc::new(move |req: &PageRender| runner_engine.render(req).map_err(|e| e.to_string()));
        let pool = Pool::start(workers, queue, runner)?;
        let app = Arc::new(App {
            engine,
            pool,
            access,
        });
        let listener = Listener::start(socket, limits, budget, app.clone())
            .map_err(ServeError::io("starting the HTTP server"))?;
        Ok(Self { listener, app })
    }

    /// The address it listens on.
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.listener.addr()
    }

    /// The page's address, with the token when one is asked. Listening on all interfaces
    /// (`0.0.0.0`, `::`), it names loopback: a browser cannot open the unspecified address, and
    /// the address of another interface depends on where the browser is.
    #[must_use]
    pub fn url(&self) -> String {
        let mut addr = self.addr();
        if addr.ip().is_unspecified() {
            addr.set_ip(match addr.ip() {
                IpAddr::V4(_) => IpAddr::V4(Ipv4Addr::LOCALHOST),
                IpAddr::V6(_) => IpAddr::V6(std::net::Ipv6Addr::LOCALHOST),
            });
        }
        match self.app.access.token() {
            Some(t) => format!("http://{addr}/?token={t}"),
            None => format!("http://{addr}/"),
        }
    }

    /// The token requests must carry, if any.
    #[must_use]
    pub fn token(&self) -> Option<&str> {
        self.app.access.token()
    }

    /// The engine (folders, renders) the server runs.
    #[must_use]
    pub fn engine(&self) -> &Engine {
        &self.app.engine
    }

    /// The engine, shared: for what outlives a borrow of the server (a signal handler that
    /// removes the dropped images, [`Engine::remove_uploads`]).
    #[must_use]
    pub fn shared_engine(&self) -> Arc<Engine> {
        self.app.engine.clone()
    }

    /// Serves until the process ends.
    pub fn wait(self) {
        self.listener.join();
    }

    /// Stops serving and the render threads.
    pub fn stop(self) {
        self.listener.stop();
        self.app.pool.stop();
    }
}
