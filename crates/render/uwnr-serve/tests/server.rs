//! The server in-process on a free localhost port, through real HTTP requests: path checks,
//! upload caps, failing renders, and a render that the CLI's flags describe.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::time::Duration;

use serde_json::{Value, json};
use uwnr_serve::{ServeConfig, Server};

/// A small clean-looking image.
fn write_image(path: &Path, w: u32, h: u32, seed: u8) {
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([
            (x * 255 / w) as u8,
            (y * 255 / h) as u8,
            seed.wrapping_mul(37).wrapping_add((x + y) as u8),
        ])
    });
    img.save(path).unwrap();
}

struct Fixture {
    _dir: tempfile::TempDir,
    server: Option<Server>,
    outside: std::path::PathBuf,
}

impl Fixture {
    /// clean/ with two photos (one in an RGB-D layout with its depth map) and a symlink to a
    /// file outside; refs/ with two references and a corrupt one.
    fn new(max_upload_bytes: u64) -> Self {
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
        config.max_upload_bytes = max_upload_bytes;
        config.max_dimension = 256;
        config.workers = 1;
        config.queue = 4;
        let server = Server::start(config).unwrap();
        Self {
            _dir: dir,
            server: Some(server),
            outside,
        }
    }

    fn addr(&self) -> SocketAddr {
        self.server.as_ref().unwrap().addr()
    }

    fn get(&self, path: &str) -> (u16, Vec<u8>) {
        request(self.addr(), "GET", path, &[])
    }

    fn json(&self, method: &str, path: &str, body: &[u8]) -> (u16, Value) {
        let (status, bytes) = request(self.addr(), method, path, body);
        (
            status,
            serde_json::from_slice(&bytes).unwrap_or(Value::Null),
        )
    }

    /// Submits a render and polls it to its end.
    fn render(&self, request: &Value) -> (Value, Value) {
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

fn request(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
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

#[test]
fn paths_outside_the_folders_and_unknown_indices_are_refused() {
    let f = Fixture::new(1 << 20);
    let (status, info) = f.json("GET", "/api/info", &[]);
    assert_eq!(status, 200);
    let cleans = info["cleans"].as_array().unwrap();
    let rels: Vec<&str> = cleans.iter().map(|c| c["rel"].as_str().unwrap()).collect();
    assert_eq!(rels, ["a.png", "set/rgb/b.png", "z-escape.png"]);
    assert_eq!(cleans[1]["depth_beside"], true);
    assert_eq!(info["references"], 3);

    for bad in [
        "../secret.png",
        "set/../../secret.png",
        "%2e%2e/secret.png",
        "/etc/passwd",
        f.outside.to_str().unwrap(),
    ] {
        let (status, body) = f.json("GET", &format!("/api/clean/find?path={bad}"), &[]);
        assert_eq!(status, 403, "{bad}: {body}");
        assert!(
            body["error"].as_str().unwrap().contains("not inside"),
            "{body}"
        );
    }
    // A symlink inside the folder whose target is outside: listed (the dataset's indices), never
    // read, by path or by index.
    let (status, body) = f.json("GET", "/api/clean/find?path=z-escape.png", &[]);
    assert_eq!(status, 403, "{body}");
    let (status, _) = f.get("/api/clean/image?clean=2");
    assert_eq!(status, 403);
    // Unknown indices and names.
    let (status, body) = f.json("GET", "/api/clean/image?clean=7", &[]);
    assert_eq!(status, 404);
    assert_eq!(body["error"], "no clean number 7 (there are 3)");
    let (status, _) = f.get("/api/reference/99/thumb");
    assert_eq!(status, 404);
    let (status, _) = f.get("/api/clean/find?path=nope.png");
    assert_eq!(status, 404);
    // Inside paths resolve.
    let (status, body) = f.json("GET", "/api/clean/find?path=set/rgb/b.png", &[]);
    assert_eq!((status, body["index"].as_u64()), (200, Some(1)));
    let (status, png) = f.get("/api/clean/image?clean=0");
    assert_eq!(status, 200);
    assert_eq!(&png[1..4], b"PNG");
    // The depth beside an RGB-D photo, and none beside the other.
    let (status, _) = f.get("/api/clean/depth?clean=1&depth=beside");
    assert_eq!(status, 200);
    let (status, body) = f.json("GET", "/api/clean/depth?clean=0&depth=beside", &[]);
    assert_eq!(status, 400);
    assert!(body["error"].as_str().unwrap().contains("depth/"), "{body}");
}

#[test]
fn uploads_are_capped_and_bad_images_are_answered_with_a_message() {
    let f = Fixture::new(4096);
    // Larger than --max-upload-mb: refused before it is read.
    let (status, body) = f.json(
        "POST",
        "/api/upload?kind=clean&name=big.png",
        &vec![0; 5000],
    );
    assert_eq!(status, 413, "{body}");
    assert!(
        body["error"]
            .as_str()
            .unwrap()
            .contains("more than the 4096 bytes"),
        "{body}"
    );
    // Corrupt bytes.
    let (status, body) = f.json("POST", "/api/upload?kind=clean&name=bad.jpg", b"garbage");
    assert_eq!(status, 400);
    assert!(
        body["error"].as_str().unwrap().starts_with("bad.jpg: "),
        "{body}"
    );
    // Over the dimension cap (256): a 300x1 PNG is small in bytes.
    let mut wide = Vec::new();
    image::RgbImage::new(300, 1)
        .write_to(
            &mut std::io::Cursor::new(&mut wide),
            image::ImageFormat::Png,
        )
        .unwrap();
    let (status, body) = f.json("POST", "/api/upload?kind=clean&name=wide.png", &wide);
    assert_eq!(status, 400, "{body}");
    assert!(body["error"].as_str().unwrap().contains("300"), "{body}");
    // A good one is kept and renders.
    let mut ok = Vec::new();
    image::RgbImage::from_pixel(20, 10, image::Rgb([90, 120, 150]))
        .write_to(&mut std::io::Cursor::new(&mut ok), image::ImageFormat::Png)
        .unwrap();
    let (status, up) = f.json("POST", "/api/upload?kind=clean&name=my%20photo.png", &ok);
    assert_eq!(status, 200, "{up}");
    assert_eq!(
        (up["width"].as_u64(), up["height"].as_u64()),
        (Some(20), Some(10))
    );
    let (answer, s) = f.render(&json!({
        "view": "v", "clean": {"upload": up["id"]}, "reference": 0,
        "options": {"method": "reinhard"}
    }));
    assert_eq!(s["state"], "done", "{s}");
    let cmd = answer["render_command"].as_str().unwrap();
    assert!(
        cmd.starts_with("uwnr render 'my photo.png' --reference "),
        "{cmd}"
    );
    // A dropped depth map: shown, rendered with, named in the command; not a photo.
    let mut map = Vec::new();
    image::GrayImage::from_fn(20, 10, |x, _| image::Luma([(x * 12) as u8]))
        .write_to(&mut std::io::Cursor::new(&mut map), image::ImageFormat::Png)
        .unwrap();
    let (status, d) = f.json("POST", "/api/upload?kind=depth&name=far.png", &map);
    assert_eq!(status, 200, "{d}");
    let id = d["id"].as_str().unwrap();
    let (status, _) = f.get(&format!(
        "/api/clean/depth?clean={}&depth={id}",
        up["id"].as_str().unwrap()
    ));
    assert_eq!(status, 200);
    let (answer, s) = f.render(&json!({
        "view": "v", "clean": {"upload": up["id"]}, "depth": {"upload": id}, "reference": 1,
        "options": {"method": "jerlov", "depth_scale": [2.0, 2.0]}
    }));
    assert_eq!(s["state"], "done", "{s}");
    let cmd = answer["render_command"].as_str().unwrap();
    assert!(
        cmd.contains(" --depth-scale 2 --depth far.png --seed 0 "),
        "{cmd}"
    );
    let (status, body) = f.json(
        "POST",
        "/api/render",
        json!({"view": "w", "clean": {"upload": id}, "reference": 0, "options": {"method": "reinhard"}})
            .to_string()
            .as_bytes(),
    );
    assert_eq!(status, 400);
    assert!(
        body["error"].as_str().unwrap().contains("is a depth map"),
        "{body}"
    );
    // The server still answers.
    assert_eq!(f.get("/api/info").0, 200);
}

#[test]
fn a_failing_render_is_a_message_and_the_server_keeps_serving() {
    let f = Fixture::new(1 << 20);
    // Reference 2 is the corrupt file.
    let (_, s) = f.render(&json!({
        "view": "cell", "clean": {"index": 0}, "reference": 2, "options": {"method": "uisa"}
    }));
    assert_eq!(s["state"], "failed");
    let e = s["error"].as_str().unwrap();
    assert!(e.starts_with("reference r3-broken.jpg: "), "{e}");
    let (status, page) = f.json("GET", "/api/references?page=0&per=10", &[]);
    assert_eq!(status, 200);
    assert!(page["items"][2]["error"].is_string(), "{page}");
    assert!(page["items"][0]["mean"].is_array() && page["items"][0]["veil"].is_array());
    // Bad requests are messages too.
    let (status, body) = f.json(
        "POST",
        "/api/render",
        br#"{"view":"x","clean":{"index":0},"options":{"method":"uisa","water_type":"3C"}}"#,
    );
    assert_eq!(status, 400);
    assert!(
        body["error"]
            .as_str()
            .unwrap()
            .contains("water_type does not apply"),
        "{body}"
    );
    // And the next render works.
    let (answer, s) = f.render(&json!({
        "view": "cell", "clean": {"index": 1}, "depth": "beside", "reference": 0,
        "options": {"method": "jerlov", "seed": 4, "water_type": "3C"}
    }));
    assert_eq!(s["state"], "done", "{s}");
    let cmd = answer["render_command"].as_str().unwrap();
    assert!(
        cmd.contains(" --method jerlov --water-type 3C --depth ")
            && cmd.ends_with(" --seed 4 --output uwnr-b-jerlov.png"),
        "{cmd}"
    );
    assert!(
        !cmd.contains("--reference"),
        "jerlov reads no reference: {cmd}"
    );
    let (status, png) = f.get(&format!("/api/job/{}/image", answer["job"]));
    assert_eq!(status, 200);
    let img = image::load_from_memory(&png).unwrap();
    assert_eq!((img.width(), img.height()), (32, 32), "the preview size");
}

#[test]
fn the_reference_draw_is_the_datasets() {
    let f = Fixture::new(1 << 20);
    let (status, d) = f.json("GET", "/api/draw?clean=1&k=2&seed=5", &[]);
    assert_eq!(status, 200);
    let want: Vec<usize> = uwnr_dataset::plan::ReferenceOrder::new(5, 1, 3)
        .take(2)
        .collect();
    let got: Vec<usize> = d["references"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();
    assert_eq!(got, want);
}
