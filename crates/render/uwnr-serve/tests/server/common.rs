//! The test server: folders with good, broken and escaping files, and raw HTTP requests.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::time::Duration;

use serde_json::Value;
use uwnr_serve::{ServeConfig, Server};

/// A small clean-looking image.
pub fn write_image(path: &Path, w: u32, h: u32, seed: u8) {
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (x * 255 / w) as u8,
            (y * 255 / h) as u8,
            seed.wrapping_mul(37).wrapping_add((x + y) as u8),
        ])
    });
    img.save(path).unwrap();
}

pub struct Fixture {
    pub dir: tempfile::TempDir,
    pub server: Option<Server>,
    pub outside: std::path::PathBuf,
}

impl Fixture {
    /// clean/ with two photos (one in an RGB-D layout with its depth map) and a symlink to a
    /// file outside; refs/ with two references and a corrupt one.
    pub fn new(max_upload_bytes: u64) -> Self {
        Self::with(|c| c.max_upload_bytes = max_upload_bytes)
    }

    /// The fixture with `change` made to the server's config.
    pub fn with(change: impl FnOnce(&mut ServeConfig)) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let clean = dir.path().join("clean");
        let refs = dir.path().join("refs");
        std::fs::create_dir_all(clean.join("set/rgb")).unwrap();
        std::fs::create_dir_all(clean.join("set/depth")).unwrap();
        std::fs::create_dir_all(&refs).unwrap();
        write_image(&clean.join("a.png"), 48, 32, 1);
        write_image(&clean.join("set/rgb/b.png"), 40, 40, 2);
        image::GrayImage::from_fn(40, 40, |_, y| image::Luma([(y * 6) as u8]))
            .save(clean.join("set/depth/b.png"))
            .unwrap();
        write_image(&refs.join("r1.png"), 64, 48, 3);
        write_image(&refs.join("r2.png"), 64, 48, 4);
        std::fs::write(
            refs.join("r3-broken.jpg"),
            b"\xff\xd8\xff not really a jpeg",
        )
        .unwrap();
        let outside = dir.path().join("secret.png");
        write_image(&outside, 8, 8, 9);
        #[cfg(unix)]
        std::os::unix::fs::symlink(&outside, clean.join("z-escape.png")).unwrap();
        let mut config = ServeConfig::new(clean, refs);
        config.port = 0;
        config.preview_size = 32;
        config.max_dimension = 256;
        config.workers = 1;
        config.queue = 4;
        change(&mut config);
        let server = Server::start(config).unwrap();
        Self {
            dir,
            server: Some(server),
            outside,
        }
    }

    pub fn addr(&self) -> SocketAddr {
        self.server.as_ref().unwrap().addr()
    }

    pub fn get(&self, path: &str) -> (u16, Vec<u8>) {
        request(self.addr(), "GET", path, &[])
    }

    pub fn json(&self, method: &str, path: &str, body: &[u8]) -> (u16, Value) {
        let (status, bytes) = request(self.addr(), method, path, body);
        (
            status,
            serde_json::from_slice(&bytes).unwrap_or(Value::Null),
        )
    }

    /// Submits a render and polls it to its end.
    pub fn render(&self, request: &Value) -> (Value, Value) {
        let (status, answer) = self.json("POST", "/api/render", request.to_string().as_bytes());
        assert_eq!(status, 200, "{answer}");
        let job = answer["job"].as_u64().unwrap();
        for _ in 0..6000 {
            let (_, s) = self.json("GET", &format!("/api/job/{job}"), &[]);
            if !matches!(s["state"].as_str(), Some("queued" | "running")) {
                return (answer, s);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("job {job} never ended");
    }
}

impl Drop for Fixture {
    fn drop(&mut self) {
        if let Some(s) = self.server.take() {
            s.stop();
        }
    }
}

pub fn request(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    // The server may answer (413) before reading a body it refuses.
    let _ = s.write_all(body);
    let mut out = Vec::new();
    s.read_to_end(&mut out).unwrap();
    let split = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a complete answer");
    let status: u16 = String::from_utf8_lossy(&out[9..12]).parse().unwrap();
    (status, out[split + 4..].to_vec())
}

/// Sends `bytes` as they are (then closes the sending side) and reads the whole answer:
/// `(status, head, body)`, status 0 when the server closed without answering.
pub fn raw(addr: SocketAddr, bytes: &[u8]) -> (u16, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let _ = s.write_all(bytes);
    let _ = s.shutdown(std::net::Shutdown::Write);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let Some(split) = out.windows(4).position(|w| w == b"\r\n\r\n") else {
        return (0, String::new(), out);
    };
    let head = String::from_utf8_lossy(&out[..split]).to_ascii_lowercase();
    let status = head.get(9..12).and_then(|s| s.parse().ok()).unwrap_or(0);
    (status, head, out[split + 4..].to_vec())
}

/// A request with extra header lines (`"Name: value"`) and a body.
pub fn with_headers(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &[u8],
) -> (u16, String, Vec<u8>) {
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nContent-Length: {}\r\n",
        body.len()
    );
    if !headers
        .iter()
        .any(|h| h.to_ascii_lowercase().starts_with("host:"))
    {
        head.push_str("Host: 127.0.0.1\r\n");
    }
    for h in headers {
        head.push_str(h);
        head.push_str("\r\n");
    }
    head.push_str("\r\n");
    let mut bytes = head.into_bytes();
    bytes.extend_from_slice(body);
    raw(addr, &bytes)
}

/// A PNG of `w` x `h` in memory.
pub fn png_bytes(w: u32, h: u32) -> Vec<u8> {
    let mut out = Vec::new();
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(x % 256) as u8, (y % 256) as u8, 90])
    })
    .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
    .unwrap();
    out
}
