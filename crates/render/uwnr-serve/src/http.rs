//! A small HTTP/1.1 server on std's `TcpListener`: one request per connection
//! (`Connection: close`), bounded header and body sizes, a fixed set of handler threads fed by a
//! bounded queue of connections. A connection that finds the queue full is answered `503` at
//! once, so a burst of clients costs at most the queue's sockets, never a thread each.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use serde_json::json;

/// Largest request line plus headers, bytes.
pub const MAX_HEADER_BYTES: usize = 16 * 1024;
/// How long a connection may take to send its request or read the answer.
const IO_TIMEOUT: Duration = Duration::from_secs(20);

/// A parsed request.
#[derive(Debug)]
pub struct Request {
    /// `GET`, `POST`, ...
    pub method: String,
    /// The path, percent-decoded, without the query.
    pub path: String,
    /// Query parameters, percent-decoded, in order.
    pub query: Vec<(String, String)>,
    /// The body (empty for requests without one).
    pub body: Vec<u8>,
}

impl Request {
    /// The first query parameter named `name`.
    #[must_use]
    pub fn param(&self, name: &str) -> Option<&str> {
        self.query
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
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
}

/// Why a request could not be read.
#[derive(Debug)]
pub enum ReadError {
    /// Answer with this response (a malformed or oversized request).
    Answer(Response),
    /// The connection failed; nothing can be answered.
    Closed,
}

/// Reads one request, with a body of at most `max_body` bytes for `POST`/`PUT` to paths under
/// `/api/upload` and `small_body` bytes elsewhere.
pub fn read_request(
    stream: &TcpStream,
    max_upload: u64,
    small_body: u64,
) -> Result<Request, ReadError> {
    let mut reader = BufReader::new(stream);
    let mut head = Vec::new();
    loop {
        let before = head.len();
        let n = reader
            .by_ref()
            .take((MAX_HEADER_BYTES + 1 - before) as u64)
            .read_until(b'\n', &mut head)
            .map_err(|_| ReadError::Closed)?;
        if n == 0 {
            return Err(ReadError::Closed);
        }
        if head.len() > MAX_HEADER_BYTES {
            return Err(ReadError::Answer(Response::error(
                431,
                "request headers too large",
            )));
        }
        if head.ends_with(b"\r\n\r\n") || head.ends_with(b"\n\n") {
            break;
        }
    }
    let text = String::from_utf8_lossy(&head);
    let mut lines = text.lines();
    let bad = |m: &str| ReadError::Answer(Response::error(400, m));
    let request_line = lines.next().ok_or_else(|| bad("empty request"))?;
    let mut parts = request_line.split_whitespace();
    let (Some(method), Some(target)) = (parts.next(), parts.next()) else {
        return Err(bad("malformed request line"));
    };
    let mut length: u64 = 0;
    for line in lines {
        if let Some((name, value)) = line.split_once(':')
            && name.trim().eq_ignore_ascii_case("content-length")
        {
            length = value
                .trim()
                .parse()
                .map_err(|_| bad("bad Content-Length"))?;
        }
    }
    let (path, query) = split_target(target);
    let limit = if path.starts_with("/api/upload") {
        max_upload
    } else {
        small_body
    };
    if length > limit {
        let e = crate::error::ServeError::TooLarge {
            got: length,
            max: limit,
        };
        return Err(ReadError::Answer(Response::error(
            e.status(),
            &e.to_string(),
        )));
    }
    let mut body = vec![0; usize::try_from(length).map_err(|_| ReadError::Closed)?];
    reader
        .read_exact(&mut body)
        .map_err(|_| ReadError::Closed)?;
    Ok(Request {
        method: method.to_string(),
        path,
        query,
        body,
    })
}

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

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        404 => "Not Found",
        405 => "Method Not Allowed",
        413 => "Payload Too Large",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Internal Server Error",
    }
}

/// Writes `r` and closes the connection (errors ignored: the client may have gone).
pub fn write_response(mut stream: &TcpStream, r: &Response) {
    let mut head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nConnection: close\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n",
        r.status,
        reason(r.status),
        r.content_type,
        r.body.len()
    );
    for (k, v) in &r.headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str("\r\n");
    let _ = stream
        .write_all(head.as_bytes())
        .and_then(|()| stream.write_all(&r.body))
        .and_then(|()| stream.flush());
    let _ = stream.shutdown(std::net::Shutdown::Write);
    // Drain what the client may still send so the close does not reset the connection before
    // it has read the answer.
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    let mut sink = [0_u8; 4096];
    let mut s = stream;
    while matches!(s.read(&mut sink), Ok(n) if n > 0) {}
}

/// Sizes of the connection handling.
#[derive(Clone, Copy, Debug)]
pub struct HttpLimits {
    /// Handler threads.
    pub handlers: usize,
    /// Connections waiting for a handler before new ones are answered `503`.
    pub backlog: usize,
    /// Largest upload body, bytes.
    pub max_upload: u64,
    /// Largest other body, bytes.
    pub small_body: u64,
}

/// A running listener: its threads stop when [`Listener::stop`] is called.
pub struct Listener {
    stop: Arc<AtomicBool>,
    addr: std::net::SocketAddr,
    threads: Vec<JoinHandle<()>>,
}

impl Listener {
    /// Serves `listener` with `handle` on `limits.handlers` threads.
    pub fn start(
        listener: TcpListener,
        limits: HttpLimits,
        handle: Arc<dyn Fn(Request) -> Response + Send + Sync>,
    ) -> std::io::Result<Self> {
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, rx): (SyncSender<TcpStream>, Receiver<TcpStream>) =
            sync_channel(limits.backlog.max(1));
        let rx = Arc::new(Mutex::new(rx));
        let mut threads = Vec::new();
        for i in 0..limits.handlers.max(1) {
            let rx = rx.clone();
            let handle = handle.clone();
            threads.push(
                std::thread::Builder::new()
                    .name(format!("uwnr-serve-http-{i}"))
                    .spawn(move || {
                        loop {
                            let next = rx.lock().unwrap_or_else(PoisonError::into_inner).recv();
                            let Ok(stream) = next else { break };
                            serve_one(&stream, &limits, handle.as_ref());
                        }
                    })?,
            );
        }
        let stop_flag = stop.clone();
        threads.push(
            std::thread::Builder::new()
                .name("uwnr-serve-accept".into())
                .spawn(move || accept_loop(&listener, &tx, &stop_flag))?,
        );
        Ok(Self {
            stop,
            addr,
            threads,
        })
    }

    /// The address it listens on.
    #[must_use]
    pub fn addr(&self) -> std::net::SocketAddr {
        self.addr
    }

    /// Blocks until the listener stops.
    pub fn join(self) {
        for t in self.threads {
            let _ = t.join();
        }
    }

    /// Stops accepting and lets the handlers finish.
    pub fn stop(self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loop.
        let _ = TcpStream::connect(self.addr);
        self.join();
    }
}

fn accept_loop(listener: &TcpListener, tx: &SyncSender<TcpStream>, stop: &AtomicBool) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let Ok(stream) = stream else { continue };
        let _ = stream.set_read_timeout(Some(IO_TIMEOUT));
        let _ = stream.set_write_timeout(Some(IO_TIMEOUT));
        match tx.try_send(stream) {
            Ok(()) => {}
            Err(TrySendError::Full(stream)) => {
                let _ = stream.set_write_timeout(Some(Duration::from_secs(2)));
                write_response(
                    &stream,
                    &Response::error(503, "the server is busy; try again in a moment"),
                );
            }
            Err(TrySendError::Disconnected(_)) => break,
        }
    }
}

fn serve_one(
    stream: &TcpStream,
    limits: &HttpLimits,
    handle: &(dyn Fn(Request) -> Response + Send + Sync),
) {
    match read_request(stream, limits.max_upload, limits.small_body) {
        Ok(request) => {
            let response = handle(request);
            write_response(stream, &response);
        }
        Err(ReadError::Answer(response)) => write_response(stream, &response),
        Err(ReadError::Closed) => {}
    }
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
