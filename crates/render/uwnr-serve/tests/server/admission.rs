//! Who is let in, and before what: a request refused by the guard (Host, Origin, token) takes no
//! memory and no connection slot from the clients it lets in; the guard and the router read one
//! path; the token stays on this server.

use std::io::{Read, Write};
use std::net::{IpAddr, Ipv4Addr, SocketAddr, TcpStream};
use std::time::Duration;

use uwnr_serve::{HTTP_CONNECTIONS, HTTP_WAITING};

use crate::common::{Fixture, png_bytes, with_headers};

/// A server beyond loopback (a token is asked), changed by `change`; the loopback address to
/// reach it and the `Authorization` header of the token holder.
fn token_server(
    change: impl FnOnce(&mut uwnr_serve::ServeConfig),
) -> (Fixture, SocketAddr, String) {
    let f = Fixture::with(|c| {
        c.host = IpAddr::V4(Ipv4Addr::UNSPECIFIED);
        change(c);
    });
    let token = f.server.as_ref().unwrap().token().unwrap().to_string();
    let addr = SocketAddr::from(([127, 0, 0, 1], f.addr().port()));
    (f, addr, format!("Authorization: token {token}"))
}

/// Polls `ready` every 10 ms until it holds (a hang guard of 60 s, not a timing assertion).
fn wait_for(what: &str, mut ready: impl FnMut() -> bool) {
    for _ in 0..6000 {
        if ready() {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("never happened: {what}");
}

/// Connections whose answers are read without waiting.
struct Clients {
    streams: Vec<TcpStream>,
    got: Vec<Vec<u8>>,
    closed: Vec<bool>,
}

impl Clients {
    /// `n` connections to `addr`, each sending `head(i)` and nothing more.
    fn open(addr: SocketAddr, n: usize, head: impl Fn(usize) -> String) -> Self {
        let streams: Vec<TcpStream> = (0..n)
            .map(|i| {
                let mut s = TcpStream::connect(addr).unwrap();
                s.write_all(head(i).as_bytes()).unwrap();
                s.set_nonblocking(true).unwrap();
                s
            })
            .collect();
        Self {
            got: vec![Vec::new(); n],
            closed: vec![false; n],
            streams,
        }
    }

    /// Reads what has arrived; how many connections got an answer or were closed.
    fn poll(&mut self) -> usize {
        let mut buf = [0_u8; 4096];
        for (i, s) in self.streams.iter_mut().enumerate() {
            while !self.closed[i] {
                match s.read(&mut buf) {
                    Ok(0) => self.closed[i] = true,
                    Ok(n) => self.got[i].extend_from_slice(&buf[..n]),
                    Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                    Err(_) => self.closed[i] = true,
                }
            }
        }
        (0..self.streams.len())
            .filter(|&i| self.closed[i] || !self.got[i].is_empty())
            .count()
    }

    /// The status each connection was answered with (0: none, or closed unanswered).
    fn statuses(&self) -> Vec<u16> {
        self.got
            .iter()
            .map(|g| {
                String::from_utf8_lossy(g.get(9..12).unwrap_or_default())
                    .parse()
                    .unwrap_or(0)
            })
            .collect()
    }
}

#[test]
fn uploads_the_guard_refuses_take_no_memory_from_the_token_holder() {
    const BUDGET: u64 = 8 << 20;
    const MAX_UPLOAD: u64 = 4 << 20;
    let (f, addr, auth) = token_server(|c| {
        c.memory_bytes = BUDGET;
        c.max_upload_bytes = MAX_UPLOAD;
    });
    let budget = f.server.as_ref().unwrap().engine().budget().clone();
    // A flood of uploads with another page's Host or without the token, each declaring the
    // largest upload and sending one byte of it: together three times the budget.
    let mut flood = Clients::open(addr, 6, |i| {
        let host = if i % 2 == 0 {
            "evil.example"
        } else {
            "127.0.0.1"
        };
        format!(
            "POST /api/upload?kind=clean&name=x.png HTTP/1.1\r\nHost: {host}\r\n\
             Content-Length: {MAX_UPLOAD}\r\n\r\nx"
        )
    });
    // Every head has been dealt with once each is answered, or once the budget is full.
    wait_for("the flood's heads are read", || {
        flood.poll() == 6 || budget.used() >= BUDGET
    });
    // The token holder uploads and decodes meanwhile.
    let (status, _, body) = with_headers(
        addr,
        "POST",
        "/api/upload?kind=clean&name=mine.png",
        &[&auth],
        &png_bytes(40, 30),
    );
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let (status, _, body) = with_headers(addr, "GET", "/api/clean/image?clean=0", &[&auth], &[]);
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    wait_for("the flood is answered", || flood.poll() == 6);
    assert_eq!(flood.statuses(), vec![403; 6]);
    assert_eq!(budget.used(), 0);
}

#[test]
fn clients_that_never_finish_their_head_do_not_lock_out_the_token_holder() {
    let (_f, addr, auth) = token_server(|_| {});
    // More connections than the server holds, each sending part of a head and no token.
    let extra = 14;
    let held = HTTP_CONNECTIONS.max(HTTP_WAITING);
    let mut idle = Clients::open(addr, held + extra, |_| {
        "GET /api/info HTTP/1.1\r\nHo".to_string()
    });
    // The server has taken them all in once the ones over its limit are answered or closed.
    wait_for("the idle connections are taken in", || idle.poll() >= extra);
    let (status, _, body) = with_headers(addr, "GET", "/api/info", &[&auth], &[]);
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    drop(idle);
}

#[test]
fn the_guard_and_the_router_read_the_same_path() {
    let f = Fixture::new(1 << 20);
    let addr = f.addr();
    for path in ["//api/info", "///api/info", "/%2Fapi/info", "//api//info/"] {
        let (status, _, _) = with_headers(addr, "GET", path, &["Sec-Fetch-Site: cross-site"], &[]);
        assert_eq!(status, 403, "{path}");
        let (status, _, _) = with_headers(addr, "GET", path, &["Sec-Fetch-Site: same-origin"], &[]);
        assert_eq!(status, 200, "{path}");
    }
}

#[test]
fn listening_on_all_interfaces_the_printed_address_opens_here() {
    let (f, addr, _) = token_server(|_| {});
    let server = f.server.as_ref().unwrap();
    let token = server.token().unwrap();
    // A browser cannot open http://0.0.0.0:PORT/; this machine's loopback it can.
    assert_eq!(
        server.url(),
        format!("http://127.0.0.1:{}/?token={token}", addr.port())
    );
}

#[test]
fn the_token_is_carried_by_the_page_never_set_as_a_cookie() {
    let (f, addr, _) = token_server(|_| {});
    let token = f.server.as_ref().unwrap().token().unwrap().to_string();
    // A browser sends a host's cookies to every port of it: another server on this machine
    // would receive the token.
    let (status, head, _) = with_headers(addr, "GET", &format!("/?token={token}"), &[], &[]);
    assert_eq!(status, 200);
    assert!(!head.contains("set-cookie"), "{head}");
    // The page adds the token to its requests instead; its own script and style are the same
    // in every copy of uwnr and load without it.
    let (_, _, js) = with_headers(addr, "GET", "/app.js", &[], &[]);
    assert!(
        String::from_utf8_lossy(&js).contains("withToken("),
        "the page sends the token with its requests"
    );
    for path in ["/app.js", "/style.css"] {
        assert_eq!(with_headers(addr, "GET", path, &[], &[]).0, 200, "{path}");
    }
    let (status, _, _) = with_headers(addr, "GET", &format!("/api/info?token={token}"), &[], &[]);
    assert_eq!(status, 200);
    assert_eq!(with_headers(addr, "GET", "/", &[], &[]).0, 403);
    assert_eq!(with_headers(addr, "GET", "/api/info", &[], &[]).0, 403);
}
