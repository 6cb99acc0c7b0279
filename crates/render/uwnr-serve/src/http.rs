//! The page's HTTP/1.1 server: hyper on a one-thread tokio runtime for the connections, the
//! handlers on a fixed number of blocking threads.
//!
//! hyper reads and checks requests (methods, versions, `Content-Length` and chunked bodies,
//! conflicting lengths refused, `HEAD` answered without a body) and writes responses; this
//! module adds the limits:
//! - connections: until its request head has arrived and passed [`Service::admit`], a connection
//!   is *waiting*: at most [`HttpLimits::waiting`] wait, and a new connection beyond closes the
//!   oldest waiting one, so clients that never finish their head cannot keep out one that sends
//!   it at once (to push it out they must open that many connections in the moment its head
//!   takes to arrive). An admitted connection holds one of [`HttpLimits::connections`] slots
//!   until it ends; beyond, it is answered `503`. The accept loop never waits on a client;
//! - time: the request head must arrive within [`HEADER_DEADLINE`], the body within
//!   [`BODY_DEADLINE`], the whole exchange within [`CONNECTION_DEADLINE`]; a slow or idle client
//!   costs a task and a socket until then, never a handler thread;
//! - admission: a request's head goes to [`Service::admit`] (the local-only guard) as soon as it
//!   has arrived; a request refused there is answered at once, before any byte of its body is
//!   read or counted, so a client the guard refuses takes no memory from the ones it lets in;
//! - bodies: at most [`HttpLimits::max_upload`] bytes to `/api/upload`, [`HttpLimits::small_body`]
//!   elsewhere (`413`, before reading when the length is declared); an admitted upload's bytes
//!   are taken from the server's memory [`Budget`] before it is read (`503` when they are in use);
//! - handlers: at most [`HttpLimits::handlers`] run at once; a request that waits
//!   [`HANDLER_WAIT`] for one is answered `503`.
//!
//! Every answer closes its connection (`Connection: close`).

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::net::{SocketAddr, TcpListener};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use bytes::Bytes;
use http_body_util::{BodyExt, Full, LengthLimitError, Limited};
use hyper::body::{Body as _, Incoming};
use hyper::header::{HeaderMap, HeaderValue};
use hyper::server::conn::http1;
use hyper::service::service_fn;
use hyper_util::rt::{TokioIo, TokioTimer};
use serde_json::json;
use tokio::sync::{Notify, OwnedSemaphorePermit, Semaphore};
use tokio::task::AbortHandle;

use crate::budget::{Budget, Lease};

/// Largest request head (request line and headers), bytes: hyper's read buffer.
pub const MAX_HEADER_BYTES: usize = 16 * 1024;
/// How long a client may take to send the request head.
pub const HEADER_DEADLINE: Duration = Duration::from_secs(10);
/// How long a client may take to send the body (25 MB at 1 MB/s fits).
pub const BODY_DEADLINE: Duration = Duration::from_secs(60);
/// How long a whole exchange may take, reading the answer included.
pub const CONNECTION_DEADLINE: Duration = Duration::from_secs(180);
/// How long a request waits for a free handler before it is answered `503`.
pub const HANDLER_WAIT: Duration = Duration::from_secs(10);

/// A request as the routes see it.
#[derive(Debug)]
pub struct Request {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path, percent-decoded, without the query.
    pub path: String,
    /// Query parameters, percent-decoded, in order.
    pub query: Vec<(String, String)>,
    /// The headers as sent.
    pub headers: HeaderMap,
    /// The body (empty for requests without one).
    pub body: Bytes,
}

impl Request {
    /// A request without headers or body (tests and in-process callers).
    #[must_use]
    pub fn new(method: &str, target: &str) -> Self {
        let (path, query) = split_target(target);
        Self {
            method: method.to_string(),
            path,
            query,
            headers: HeaderMap::new(),
            body: Bytes::new(),
        }
    }

    /// The path's segments, empty ones left out (`//api//info/` is `["api", "info"]`): the one
    /// reading of the path that the guard, the body limits and the routes all use.
    #[must_use]
    pub fn segments(&self) -> Vec<&str> {
        self.path.split('/').filter(|s| !s.is_empty()).collect()
    }

    /// The first query parameter named `name`.
    #[must_use]
    pub fn param(&self, name: &str) -> Option<&str> {
        self.query
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }

    /// The header `name` as text (absent, or not visible ASCII: `None`).
    #[must_use]
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.get(name).and_then(|v| v.to_str().ok())
    }
}

/// A response.
#[derive(Debug)]
pub struct Response {
    pub status: u16,
    pub content_type: &'static str,
    pub body: Vec<u8>,
    /// Extra headers (name, value).
    pub headers: Vec<(&'static str, String)>,
}

impl Response {
    /// A JSON response.
    #[must_use]
    pub fn json(status: u16, value: &serde_json::Value) -> Self {
        Self {
            status,
            content_type: "application/json",
            body: value.to_string().into_bytes(),
            headers: Vec::new(),
        }
    }

    /// `{"error": message}` with `status`.
    #[must_use]
    pub fn error(status: u16, message: &str) -> Self {
        Self::json(status, &json!({ "error": message }))
    }

    /// Bytes of a given type.
    #[must_use]
    pub fn bytes(content_type: &'static str, body: Vec<u8>) -> Self {
        Self {
            status: 200,
            content_type,
            body,
            headers: Vec::new(),
        }
    }

    /// Adds a header.
    #[must_use]
    pub fn with_header(mut self, name: &'static str, value: String) -> Self {
        self.headers.push((name, value));
        self
    }

    fn into_hyper(self) -> hyper::Response<Full<Bytes>> {
        let mut r = hyper::Response::new(Full::new(Bytes::from(self.body)));
        *r.status_mut() = hyper::StatusCode::from_u16(self.status)
            .unwrap_or(hyper::StatusCode::INTERNAL_SERVER_ERROR);
        let h = r.headers_mut();
        h.insert("content-type", HeaderValue::from_static(self.content_type));
        for (k, v) in STANDARD_HEADERS {
            h.insert(*k, HeaderValue::from_static(v));
        }
        for (k, v) in self.headers {
            if let Ok(v) = HeaderValue::from_str(&v) {
                h.append(k, v);
            }
        }
        r
    }
}

/// Headers of every answer: nothing cached, no type sniffing, no framing by other sites, no
/// embedding by other origins, no `Referer` (a token in the address stays on this page).
const STANDARD_HEADERS: &[(&str, &str)] = &[
    ("cache-control", "no-store"),
    ("x-content-type-options", "nosniff"),
    ("x-frame-options", "DENY"),
    ("content-security-policy", "frame-ancestors 'none'"),
    ("cross-origin-resource-policy", "same-origin"),
    ("referrer-policy", "no-referrer"),
];

/// A request target's path, `%XX`-decoded, and its query as `application/x-www-form-urlencoded`
/// pairs (`+` is a space; empty pairs are skipped). Invalid escapes are kept as they are.
#[must_use]
pub fn split_target(target: &str) -> (String, Vec<(String, String)>) {
    let (raw_path, raw_query) = target.split_once('?').unwrap_or((target, ""));
    let path = percent_encoding::percent_decode_str(raw_path)
        .decode_utf8_lossy()
        .into_owned();
    let query = form_urlencoded::parse(raw_query.as_bytes())
        .map(|(k, v)| (k.into_owned(), v.into_owned()))
        .collect();
    (path, query)
}

/// Sizes of the connection handling.
#[derive(Clone, Copy, Debug)]
pub struct HttpLimits {
    /// Handler threads.
    pub handlers: usize,
    /// Admitted connections open at once; beyond, a request is answered `503`.
    pub connections: usize,
    /// Connections whose request head has not arrived or not been admitted yet.
    pub waiting: usize,
    /// Largest upload body, bytes.
    pub max_upload: u64,
    /// Largest other body, bytes.
    pub small_body: u64,
}

/// What answers requests.
pub trait Service: Send + Sync {
    /// Whether a request is answered at all, from its head alone (`Err`: the answer that refuses
    /// it). Called on the connection's task as soon as the head has arrived, before any byte of
    /// the body is read or counted; it must not block.
    fn admit(&self, head: &Request) -> std::result::Result<(), Response>;

    /// Answers an admitted request, its body read (runs on a handler thread).
    fn handle(&self, request: Request) -> Response;
}

struct Shared {
    limits: HttpLimits,
    service: Arc<dyn Service>,
    handlers: Arc<Semaphore>,
    budget: Arc<Budget>,
    /// Slots of admitted connections.
    admitted: Arc<Semaphore>,
    /// Waiting connections by id (ids grow: the first is the oldest), to close to make room.
    waiting: Mutex<BTreeMap<u64, AbortHandle>>,
}

impl Shared {
    fn waiting(&self) -> MutexGuard<'_, BTreeMap<u64, AbortHandle>> {
        self.waiting.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Takes a connection off the waiting ones when it is admitted or ends (however it ends: its
/// task dropped by a deadline or closed to make room).
struct NoLongerWaiting {
    shared: Arc<Shared>,
    id: u64,
}

impl Drop for NoLongerWaiting {
    fn drop(&mut self) {
        self.shared.waiting().remove(&self.id);
    }
}

/// A running listener: it stops when [`Listener::stop`] is called.
pub struct Listener {
    stop: Arc<Notify>,
    addr: SocketAddr,
    thread: JoinHandle<()>,
}

impl Listener {
    /// Serves `listener` with `service`, within `limits`, taking upload bodies from `budget`.
    pub fn start(
        listener: TcpListener,
        limits: HttpLimits,
        budget: Arc<Budget>,
        service: Arc<dyn Service>,
    ) -> std::io::Result<Self> {
        let addr = listener.local_addr()?;
        listener.set_nonblocking(true)?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .enable_time()
            .max_blocking_threads(limits.handlers.max(1))
            .thread_name("uwnr-serve-handler")
            .build()?;
        let stop = Arc::new(Notify::new());
        let shared = Arc::new(Shared {
            limits,
            service,
            handlers: Arc::new(Semaphore::new(limits.handlers.max(1))),
            budget,
            admitted: Arc::new(Semaphore::new(limits.connections.max(1))),
            waiting: Mutex::new(BTreeMap::new()),
        });
        let stop_flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("uwnr-serve-http".into())
            .spawn(move || {
                runtime.block_on(async move {
                    match tokio::net::TcpListener::from_std(listener) {
                        Ok(l) => {
                            let accepting = tokio::spawn(accept_loop(l, shared));
                            stop_flag.notified().await;
                            accepting.abort();
                        }
                        Err(e) => eprintln!("uwnr serve: cannot listen: {e}"),
                    }
                });
                runtime.shutdown_timeout(Duration::from_secs(1));
            })?;
        Ok(Self { stop, addr, thread })
    }

    /// The address it listens on.
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Blocks until the listener stops.
    pub fn join(self) {
        let _ = self.thread.join();
    }

    /// Stops accepting, gives running exchanges a second, and returns.
    pub fn stop(self) {
        self.stop.notify_one();
        self.join();
    }
}

async fn accept_loop(listener: tokio::net::TcpListener, shared: Arc<Shared>) {
    let mut next_id: u64 = 0;
    loop {
        let Ok((stream, _)) = listener.accept().await else {
            // Out of descriptors or a connection reset while queued: let a moment pass.
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        next_id += 1;
        let task = tokio::spawn(serve_connection(stream, shared.clone(), next_id));
        let closed: Vec<AbortHandle> = {
            let mut waiting = shared.waiting();
            let mut closed = Vec::new();
            while waiting.len() >= shared.limits.waiting.max(1) {
                match waiting.pop_first() {
                    Some((_, oldest)) => closed.push(oldest),
                    None => break,
                }
            }
            // The task has not run yet (this runtime has one thread and the loop has not
            // yielded since the spawn), so it cannot have left the waiting ones already.
            waiting.insert(next_id, task.abort_handle());
            closed
        };
        // Outside the lock: a task's end takes the lock (`NoLongerWaiting`).
        for task in closed {
            task.abort();
        }
    }
}

async fn serve_connection(stream: tokio::net::TcpStream, shared: Arc<Shared>, id: u64) {
    let _ = stream.set_nodelay(true);
    let waiting = Arc::new(Mutex::new(Some(NoLongerWaiting {
        shared: shared.clone(),
        id,
    })));
    // The admitted connection's slot, held until the connection ends (the service, which owns
    // it, is dropped with the connection).
    let slot: Arc<Mutex<Option<OwnedSemaphorePermit>>> = Arc::default();
    let service = service_fn(move |req| {
        let (shared, waiting, slot) = (shared.clone(), waiting.clone(), slot.clone());
        async move {
            let response = answer(req, &shared, &waiting, &slot).await;
            Ok::<_, Infallible>(response.into_hyper())
        }
    });
    let mut builder = http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(HEADER_DEADLINE)
        .keep_alive(false)
        // A client that closes its sending side after the request still gets the answer.
        .half_close(true)
        .max_buf_size(MAX_HEADER_BYTES);
    let connection = builder.serve_connection(TokioIo::new(stream), service);
    let _ = tokio::time::timeout(CONNECTION_DEADLINE, connection).await;
}

fn take<T>(m: &Mutex<Option<T>>) -> Option<T> {
    m.lock().unwrap_or_else(PoisonError::into_inner).take()
}

/// Reads the body within its limits and deadline, then runs the handler on a handler thread.
async fn answer(
    req: hyper::Request<Incoming>,
    shared: &Shared,
    waiting: &Mutex<Option<NoLongerWaiting>>,
    slot: &Mutex<Option<OwnedSemaphorePermit>>,
) -> Response {
    let (parts, body) = req.into_parts();
    let target = parts
        .uri
        .path_and_query()
        .map_or_else(|| parts.uri.path().to_string(), |p| p.as_str().to_string());
    let (path, query) = split_target(&target);
    let mut request = Request {
        method: parts.method.as_str().to_string(),
        path,
        query,
        headers: parts.headers,
        body: Bytes::new(),
    };
    if let Err(refused) = shared.service.admit(&request) {
        return refused;
    }
    // Admitted: no longer closed to make room, and counted among the admitted.
    drop(take(waiting));
    match shared.admitted.clone().try_acquire_owned() {
        Ok(permit) => *slot.lock().unwrap_or_else(PoisonError::into_inner) = Some(permit),
        Err(_) => return Response::error(503, "the server is busy; try again in a moment"),
    }
    let upload = request.segments() == ["api", "upload"];
    let limit = if upload {
        shared.limits.max_upload
    } else {
        shared.limits.small_body
    };
    let declared = body.size_hint().exact();
    if declared.is_some_and(|n| n > limit) {
        return too_large(upload, declared.unwrap_or(limit), limit);
    }
    // An upload's bytes are counted before they are read (the declared length, or the most
    // that may come).
    let lease: Option<Lease> = if upload {
        match shared
            .budget
            .try_take(declared.unwrap_or(limit), "the upload")
        {
            Ok(l) => Some(l),
            Err(e) => return Response::error(e.status(), &e.to_string()),
        }
    } else {
        None
    };
    let body = match tokio::time::timeout(
        BODY_DEADLINE,
        Limited::new(body, usize::try_from(limit).unwrap_or(usize::MAX)).collect(),
    )
    .await
    {
        Err(_) => {
            return Response::error(
                408,
                &format!(
                    "the request body took longer than {} s",
                    BODY_DEADLINE.as_secs()
                ),
            );
        }
        Ok(Err(e)) if e.is::<LengthLimitError>() => return too_large(upload, limit + 1, limit),
        Ok(Err(_)) => return Response::error(400, "the request body ended early or is malformed"),
        Ok(Ok(collected)) => collected.to_bytes(),
    };
    request.body = body;
    let Ok(Ok(permit)) =
        tokio::time::timeout(HANDLER_WAIT, shared.handlers.clone().acquire_owned()).await
    else {
        return Response::error(503, "the server is busy; try again in a moment");
    };
    let service = shared.service.clone();
    tokio::task::spawn_blocking(move || {
        let response = service.handle(request);
        drop(lease);
        drop(permit);
        response
    })
    .await
    .unwrap_or_else(|_| Response::error(500, "the request's handler failed"))
}

/// `413` naming the limit the body is over.
fn too_large(upload: bool, got: u64, max: u64) -> Response {
    let e = if upload {
        crate::error::ServeError::TooLarge {
            what: "the upload",
            got,
            max,
            limit: "this server accepts (--max-upload-mb)",
        }
    } else {
        crate::error::ServeError::TooLarge {
            what: "the request body",
            got,
            max,
            limit: "a request other than an upload may send",
        }
    };
    Response::error(e.status(), &e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode_and_bad_ones_stay() {
        let (path, query) = split_target("/api/%2e%2E/x?a=1%202+3&&b&c=100%&d=%zz");
        assert_eq!(path, "/api/../x");
        let pairs = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect()
        };
        assert_eq!(
            query,
            pairs(&[("a", "1 2 3"), ("b", ""), ("c", "100%"), ("d", "%zz")])
        );
        // A `+` in the path is a `+`; in the query a space.
        assert_eq!(split_target("/a+b").0, "/a+b");
    }
}
