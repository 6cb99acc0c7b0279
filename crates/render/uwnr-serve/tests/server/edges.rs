//! The server under attack and at the edges: HTTP as hyper reads it, the local-only guard,
//! slow clients, memory in bytes, files swapped after listing, private uploads, the server's
//! own failures.

use std::io::Write;
use std::net::TcpStream;
use std::time::Duration;

use serde_json::{Value, json};

use crate::common::{Fixture, png_bytes, raw, with_headers};

fn body_json(body: &[u8]) -> Value {
    serde_json::from_slice(body).unwrap_or(Value::Null)
}

#[test]
fn http_methods_versions_and_bodies_are_read_by_the_rules() {
    let f = Fixture::new(1 << 20);
    let addr = f.addr();
    // HEAD: the GET's headers, no body.
    let (status, head, body) = with_headers(addr, "HEAD", "/api/info", &[], &[]);
    assert_eq!(status, 200);
    assert!(body.is_empty(), "HEAD sent {} bytes", body.len());
    let (_, _, get) = with_headers(addr, "GET", "/api/info", &[], &[]);
    assert!(
        head.contains(&format!("content-length: {}", get.len())),
        "{head}"
    );
    // A known path with another method: 405 and what it allows.
    for (method, path, allow) in [
        ("DELETE", "/api/info", "get, head"),
        ("POST", "/api/info", "get, head"),
        ("GET", "/api/render", "post"),
        ("OPTIONS", "/api/upload", "post"),
        ("PUT", "/", "get, head"),
    ] {
        let (status, head, _) = with_headers(addr, method, path, &[], &[]);
        assert_eq!(status, 405, "{method} {path}");
        assert!(
            head.contains(&format!("allow: {allow}")),
            "{method} {path}: {head}"
        );
    }
    assert_eq!(with_headers(addr, "GET", "/nope", &[], &[]).0, 404);
    // Versions other than HTTP/1.0 and 1.1 are not served.
    for line in ["GET / HTTP/3.0", "GET / HTTP/1.2", "GET / FOO/1.1"] {
        let (status, _, _) = raw(
            addr,
            format!("{line}\r\nHost: 127.0.0.1\r\n\r\n").as_bytes(),
        );
        assert_ne!(status, 200, "{line}");
    }
    // A chunked body is read.
    let request = json!({"view": "p|c", "clean": {"index": 0}, "reference": 0,
        "options": {"method": "reinhard"}})
    .to_string();
    let (a, b) = request.split_at(20);
    let chunked = format!(
        "POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n\
         {:x}\r\n{a}\r\n{:x}\r\n{b}\r\n0\r\n\r\n",
        a.len(),
        b.len()
    );
    let (status, _, body) = raw(addr, chunked.as_bytes());
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert!(body_json(&body)["job"].is_u64());
    // Conflicting lengths are refused; a body that ends early gets a status.
    let conflicting = "POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 5\r\n\
                       Content-Length: 7\r\n\r\n{}{}{}{";
    assert_eq!(raw(addr, conflicting.as_bytes()).0, 400);
    let truncated =
        "POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 100\r\n\r\n{\"a\":";
    assert_eq!(raw(addr, truncated.as_bytes()).0, 400);
    // A page number that overflows is refused, not wrapped.
    let (status, _, body) = with_headers(
        addr,
        "GET",
        &format!("/api/references?page={}&per=100", usize::MAX),
        &[],
        &[],
    );
    assert_eq!(status, 400, "{}", String::from_utf8_lossy(&body));
}

#[test]
fn other_hosts_and_other_pages_are_refused() {
    let f = Fixture::new(1 << 20);
    let addr = f.addr();
    // DNS rebinding: another name for this address.
    for host in ["evil.example", &format!("evil.example:{}", addr.port())] {
        for path in [
            "/",
            "/api/info",
            "/api/clean/image?clean=0",
            "/api/reference/0/thumb",
        ] {
            let (status, _, body) =
                with_headers(addr, "GET", path, &[&format!("Host: {host}")], &[]);
            assert_eq!(status, 403, "{host} {path}");
            let text = String::from_utf8_lossy(&body);
            assert!(!text.contains("a.png") && !text.contains("clean"), "{text}");
        }
    }
    // A cross-origin POST without preflight (text/plain) does not run.
    let render = json!({"view": "p|x", "clean": {"index": 0}, "reference": 0,
        "options": {"method": "reinhard"}})
    .to_string();
    let (status, _, _) = with_headers(
        addr,
        "POST",
        "/api/render",
        &["Origin: http://evil.example", "Content-Type: text/plain"],
        render.as_bytes(),
    );
    assert_eq!(status, 403);
    let (status, _, _) = with_headers(
        addr,
        "POST",
        "/api/upload?kind=clean&name=x.png",
        &["Origin: null"],
        &png_bytes(8, 8),
    );
    assert_eq!(status, 403);
    let (status, _, _) = with_headers(
        addr,
        "GET",
        "/api/info",
        &["Sec-Fetch-Site: cross-site"],
        &[],
    );
    assert_eq!(status, 403);
    // This page's own requests pass.
    let origin = format!("Origin: http://127.0.0.1:{}", addr.port());
    let host = format!("Host: 127.0.0.1:{}", addr.port());
    let (status, _, _) = with_headers(
        addr,
        "POST",
        "/api/render",
        &[&host, &origin, "Sec-Fetch-Site: same-origin"],
        render.as_bytes(),
    );
    assert_eq!(status, 200);
}

#[test]
fn beyond_loopback_every_request_needs_the_token() {
    let f = Fixture::with(|c| c.host = std::net::IpAddr::V4(std::net::Ipv4Addr::UNSPECIFIED));
    let server = f.server.as_ref().unwrap();
    let token = server.token().expect("a token beyond loopback").to_string();
    assert!(
        server.url().ends_with(&format!("/?token={token}")),
        "{}",
        server.url()
    );
    let addr = std::net::SocketAddr::from(([127, 0, 0, 1], f.addr().port()));
    assert_eq!(with_headers(addr, "GET", "/api/info", &[], &[]).0, 403);
    assert_eq!(with_headers(addr, "GET", "/?token=wrong", &[], &[]).0, 403);
    let (status, _, _) = with_headers(addr, "GET", &format!("/?token={token}"), &[], &[]);
    assert_eq!(status, 200);
    let (status, _, _) = with_headers(addr, "GET", &format!("/api/info?token={token}"), &[], &[]);
    assert_eq!(status, 200);
    let auth = format!("Authorization: token {token}");
    assert_eq!(with_headers(addr, "GET", "/api/info", &[&auth], &[]).0, 200);
    // On loopback (the other tests' fixture) no token is asked.
    assert!(Fixture::new(1).server.as_ref().unwrap().token().is_none());
}

#[test]
fn slow_clients_hold_neither_handlers_nor_the_accept_loop() {
    let f = Fixture::new(1 << 20);
    let addr = f.addr();
    // 70 connections that send their request a byte at a time and never finish it.
    let mut slow: Vec<TcpStream> = (0..70)
        .map(|_| {
            let mut s = TcpStream::connect(addr).unwrap();
            s.write_all(b"GET /api/info HTTP/1.1\r\nHo").unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    for s in &mut slow {
        let _ = s.write_all(b"s");
    }
    // A normal client is served meanwhile (a slow client costs a task, not a handler), well
    // before the slow ones are cut off at the header deadline (10 s) and free anything.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(8))).unwrap();
    s.write_all(b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        .unwrap();
    let mut answer = [0_u8; 12];
    std::io::Read::read_exact(&mut s, &mut answer).expect("an answer while 70 clients dawdle");
    assert_eq!(&answer, b"HTTP/1.1 200");
    drop(slow);
}

#[test]
fn memory_is_counted_in_bytes() {
    // 1 MB: a 600x600 upload needs 2 x 600 x 600 x 3 bytes = 2.2 MB to check.
    let f = Fixture::with(|c| {
        c.memory_bytes = 1 << 20;
        c.max_dimension = 1024;
    });
    let big = png_bytes(600, 600);
    let (status, body) = f.json("POST", "/api/upload?kind=clean&name=big.png", &big);
    assert_eq!(status, 413, "{body}");
    let e = body["error"].as_str().unwrap();
    assert!(e.contains("memory budget") && e.contains("big.png"), "{e}");
    // A small one fits, and renders within the budget (32 x 32 preview: 64 kB of planes).
    let (status, up) = f.json(
        "POST",
        "/api/upload?kind=clean&name=small.png",
        &png_bytes(40, 30),
    );
    assert_eq!(status, 200, "{up}");
    let (_, s) = f.render(
        &json!({"view": "p|m", "clean": {"upload": up["id"]}, "reference": 0,
        "options": {"method": "reinhard"}}),
    );
    assert_eq!(s["state"], "done", "{s}");
    // Nothing stays counted once the requests are answered.
    let server = f.server.as_ref().unwrap();
    assert_eq!(server.engine().budget().used(), 0);
}

#[cfg(unix)]
#[test]
fn files_swapped_for_symlinks_after_start_are_not_read() {
    let f = Fixture::new(1 << 20);
    let clean = f.dir.path().join("clean");
    let refs = f.dir.path().join("refs");
    // Swapped after listing, before anything was read (nothing is cached yet).
    for file in [
        clean.join("a.png"),
        refs.join("r1.png"),
        clean.join("set/depth/b.png"),
    ] {
        std::fs::remove_file(&file).unwrap();
        std::os::unix::fs::symlink(&f.outside, &file).unwrap();
    }
    for path in [
        "/api/clean/image?clean=0",
        "/api/reference/0/thumb",
        "/api/clean/depth?clean=1&depth=beside",
    ] {
        let (status, body) = f.json("GET", path, &[]);
        assert_eq!(status, 403, "{path}: {body}");
    }
}

#[cfg(unix)]
#[test]
fn uploads_are_private_and_the_servers_failures_are_5xx_without_paths() {
    use std::os::unix::fs::PermissionsExt;
    let f = Fixture::new(1 << 20);
    let (status, up) = f.json(
        "POST",
        "/api/upload?kind=clean&name=mine.png",
        &png_bytes(20, 10),
    );
    assert_eq!(status, 200, "{up}");
    let dir = f
        .server
        .as_ref()
        .unwrap()
        .engine()
        .upload_dir()
        .to_path_buf();
    let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&dir), 0o700);
    let files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 1);
    assert_eq!(mode(&files[0]), 0o600);
    // The operator's own undecodable file: the server's failure, named as listed.
    let (status, body) = f.json("GET", "/api/reference/2/thumb", &[]);
    assert_eq!(status, 500, "{body}");
    let e = body["error"].as_str().unwrap();
    assert!(e.starts_with("reference r3-broken.jpg: "), "{e}");
    // A dropped file the server lost: 500, named as the user named it, no temporary path.
    std::fs::remove_file(&files[0]).unwrap();
    let id = up["id"].as_str().unwrap();
    let (status, body) = f.json("GET", &format!("/api/clean/image?clean={id}"), &[]);
    assert_eq!(status, 500, "{body}");
    let e = body["error"].as_str().unwrap();
    assert!(
        e.contains("mine.png") && !e.contains(dir.to_str().unwrap()) && !e.contains("/u1"),
        "{e}"
    );
}
