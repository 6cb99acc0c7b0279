//! `uwnr serve` as users run it: the binary on a free localhost port, a burst of concurrent
//! clients, and the renders it serves against `uwnr render`'s output.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use serde_json::{Value, json};

use crate::common::{s, sample, uwnr};

/// Clients of the load test.
const CLIENTS: usize = 32;
/// Render jobs the server lets wait (small, so that the burst overflows it).
const QUEUE: usize = 8;

/// Peak resident memory allowed to the server in the load test, derived from its parts (debug
/// build, previews of 64 pixels, 2 render threads):
/// - the binary with both networks loaded (the bundled UWNR model on the engine, the GAN's
///   generator on burn's flex backend), idle: measured 67 MB VmHWM after start;
/// - each render thread holds one preview render (well under 1 MB of f32 planes at 64 px) and
///   the engine keeps a buffer pool that uwnr-engine trims to 64 MB when shapes change;
/// - the HTTP side is bounded: 8 handler threads, 64 waiting connections, 64 KiB bodies; the
///   render queue holds 8 requests; finished results are PNGs of a few kB here.
///
/// That sums to about 140 MB; 256 MB leaves room for allocator slack. An unbounded server (a
/// thread or a buffered request per client, results never freed) is what this guards against;
/// measured in this test: 82 MB.
const PEAK_RSS_BOUND_KB: u64 = 256 * 1024;

struct Serving {
    child: Child,
    addr: SocketAddr,
}

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `uwnr serve` with `extra` flags and reads its address from stdout.
fn serve(clean: &Path, refs: &Path, extra: &[&str]) -> Serving {
    serve_in(clean, refs, extra, &std::env::temp_dir())
}

/// [`serve`] with `tmp` as its temporary folder (where dropped images go).
fn serve_in(clean: &Path, refs: &Path, extra: &[&str], tmp: &Path) -> Serving {
    let mut child = Command::new(env!("CARGO_BIN_EXE_uwnr"))
        .env("TMPDIR", tmp)
        .args([
            "serve",
            "--clean",
            s(clean),
            "--references",
            s(refs),
            "--port",
            "0",
        ])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starting uwnr serve");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let url = line
        .trim()
        .strip_prefix("serving on http://")
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"));
    let addr = url.trim_end_matches('/').parse().unwrap();
    Serving { child, addr }
}

fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    body: &[u8],
) -> std::io::Result<(u16, Vec<u8>)> {
    let mut s = TcpStream::connect(addr)?;
    s.set_read_timeout(Some(Duration::from_secs(120)))?;
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes())?;
    s.write_all(body)?;
    let mut out = Vec::new();
    s.read_to_end(&mut out)?;
    let split = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| std::io::Error::other("incomplete answer"))?;
    let status = String::from_utf8_lossy(&out[9..12])
        .parse()
        .map_err(std::io::Error::other)?;
    Ok((status, out[split + 4..].to_vec()))
}

fn json_of(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes).unwrap_or(Value::Null)
}

/// Submits `req` and polls the job to its end: (job id, final status).
fn render(addr: SocketAddr, req: &Value) -> (u64, Value) {
    let (status, body) = request(addr, "POST", "/api/render", req.to_string().as_bytes()).unwrap();
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let job = json_of(&body)["job"].as_u64().unwrap();
    loop {
        let (_, b) = request(addr, "GET", &format!("/api/job/{job}"), &[]).unwrap();
        let st = json_of(&b);
        if !matches!(st["state"].as_str(), Some("queued" | "running")) {
            return (job, st);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn vm_hwm_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

/// The bundled samples as `uwnr serve` folders: clean/ with the two photos, refs/ with the two
/// references.
fn sample_folders(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let clean = dir.join("clean");
    let refs = dir.join("refs");
    std::fs::create_dir_all(&clean).unwrap();
    std::fs::create_dir_all(&refs).unwrap();
    for name in ["clean-room.jpg", "clean-statues.jpg"] {
        std::fs::copy(sample(name), clean.join(name)).unwrap();
    }
    for name in ["ref-blue.jpg", "ref-green.png"] {
        std::fs::copy(sample(name), refs.join(name)).unwrap();
    }
    (clean, refs)
}

#[test]
#[cfg(target_os = "linux")]
fn a_burst_of_clients_is_answered_within_a_memory_bound() {
    let dir = tempfile::tempdir().unwrap();
    let (clean, refs) = sample_folders(dir.path());
    let server = serve(
        &clean,
        &refs,
        &[
            "--preview-size",
            "64",
            "--queue",
            &QUEUE.to_string(),
            "--workers",
            "2",
        ],
    );
    let addr = server.addr;
    let methods = ["uwnr", "uwgan", "jerlov", "uisa", "seathru", "reinhard"];
    let threads: Vec<_> = (0..CLIENTS)
        .map(|i| {
            std::thread::spawn(move || {
                let method = methods[i % methods.len()];
                let req = json!({
                    "view": format!("client-{i}"),
                    "clean": {"index": i % 2},
                    "reference": i % 2,
                    "options": {"method": method, "seed": i},
                });
                let (status, body) =
                    request(addr, "POST", "/api/render", req.to_string().as_bytes())?;
                if status != 200 {
                    return Ok((
                        status,
                        json_of(&body)["error"].as_str().map(String::from),
                        None,
                    ));
                }
                let job = json_of(&body)["job"].as_u64().unwrap();
                loop {
                    let (_, b) = request(addr, "GET", &format!("/api/job/{job}"), &[])?;
                    let st = json_of(&b);
                    match st["state"].as_str() {
                        Some("queued" | "running") => std::thread::sleep(Duration::from_millis(20)),
                        _ => return Ok((status, None, Some(st))),
                    }
                }
            })
        })
        .collect();
    let mut done = 0;
    let mut refused = 0;
    for t in threads {
        let answer: std::io::Result<(u16, Option<String>, Option<Value>)> = t.join().unwrap();
        let (status, error, final_state) = answer.expect("every client gets an answer");
        match status {
            200 => {
                let st = final_state.unwrap();
                assert_eq!(st["state"], "done", "{st}");
                done += 1;
            }
            503 => {
                let e = error.unwrap();
                assert!(e.contains("try again"), "{e}");
                refused += 1;
            }
            other => panic!("status {other}: {error:?}"),
        }
    }
    assert_eq!(done + refused, CLIENTS);
    assert!(done >= QUEUE, "at least a queue's worth rendered ({done})");
    // Still serving after the burst.
    let (status, _) = request(addr, "GET", "/api/status", &[]).unwrap();
    assert_eq!(status, 200);
    let peak = vm_hwm_kb(server.child.id());
    eprintln!(
        "load test: {CLIENTS} clients, {done} rendered, {refused} refused with 503, peak RSS {} MB",
        peak / 1024
    );
    assert!(
        peak < PEAK_RSS_BOUND_KB,
        "peak RSS {} MB over the bound {} MB",
        peak / 1024,
        PEAK_RSS_BOUND_KB / 1024
    );
}

#[test]
fn the_full_resolution_download_equals_the_shown_render_command() {
    let dir = tempfile::tempdir().unwrap();
    let (clean, refs) = sample_folders(dir.path());
    let server = serve(&clean, &refs, &["--preview-size", "64"]);
    for (i, options) in [
        json!({"method": "jerlov", "seed": 3, "water_type": "5C", "depth_scale": [2.0, 6.0]}),
        json!({"method": "reinhard", "reinhard_space": "lab", "mean_only": true}),
        json!({"method": "seathru", "seed": 11}),
    ]
    .into_iter()
    .enumerate()
    {
        let req = json!({
            "view": format!("full-{i}"), "clean": {"index": 1}, "reference": 0,
            "options": options, "size": "full",
        });
        let (status, body) = request(
            server.addr,
            "POST",
            "/api/render",
            req.to_string().as_bytes(),
        )
        .unwrap();
        assert_eq!(status, 200);
        let command = json_of(&body)["render_command"]
            .as_str()
            .unwrap()
            .to_string();
        let (job, st) = render(server.addr, &req);
        assert_eq!(st["state"], "done", "{st}");
        let (status, png) =
            request(server.addr, "GET", &format!("/api/job/{job}/image"), &[]).unwrap();
        assert_eq!(status, 200);
        // The command's words (no quoting needed for these paths), output into the tempdir.
        let mut words: Vec<String> = command.split(' ').map(String::from).collect();
        assert_eq!(&words[..2], ["uwnr", "render"], "{command}");
        let out = dir.path().join(words.last().unwrap());
        *words.last_mut().unwrap() = s(&out).to_string();
        let args: Vec<&str> = words[1..].iter().map(String::as_str).collect();
        let o = uwnr(&args);
        assert!(
            o.status.success(),
            "{command}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(std::fs::read(&out).unwrap(), png, "{command}");
    }
}

/// A worst case for an upload: a PNG of all-zero pixels at the largest size the defaults
/// accept (8192x2929, 24.0 megapixels) is 70 kB on the wire and 72 MB decoded.
fn zero_png() -> Vec<u8> {
    let mut out = Vec::new();
    image::RgbImage::new(8192, 2929)
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// Memory budget of the upload test, MiB.
const UPLOAD_BUDGET_MB: u64 = 512;
/// Peak resident memory allowed in the upload test: the idle server (about 70 MB, see
/// [`PEAK_RSS_BOUND_KB`]) plus the memory budget, which bounds every decode in flight, plus
/// 128 MB of allocator slack and request bodies.
const UPLOAD_RSS_BOUND_KB: u64 = (70 + UPLOAD_BUDGET_MB + 128) * 1024;

#[test]
#[cfg(target_os = "linux")]
fn concurrent_worst_case_uploads_stay_within_the_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let (clean, refs) = sample_folders(dir.path());
    let budget = UPLOAD_BUDGET_MB.to_string();
    let server = serve(&clean, &refs, &["--memory-mb", &budget]);
    let addr = server.addr;
    let png = std::sync::Arc::new(zero_png());
    let threads: Vec<_> = (0..8)
        .map(|i| {
            let png = png.clone();
            std::thread::spawn(move || {
                request(
                    addr,
                    "POST",
                    &format!("/api/upload?kind=clean&name=z{i}.png"),
                    &png,
                )
            })
        })
        .collect();
    let mut stored = 0;
    for t in threads {
        let (status, body) = t.join().unwrap().expect("every upload is answered");
        match status {
            200 => stored += 1,
            503 => assert!(String::from_utf8_lossy(&body).contains("try again")),
            other => panic!("status {other}: {}", String::from_utf8_lossy(&body)),
        }
    }
    let peak = vm_hwm_kb(server.child.id());
    eprintln!(
        "8 uploads of 8192x2929 zeros, --memory-mb {UPLOAD_BUDGET_MB}: {stored} stored, peak RSS {} MB",
        peak / 1024
    );
    assert!(stored >= 1);
    assert!(
        peak < UPLOAD_RSS_BOUND_KB,
        "peak RSS {} MB over the bound {} MB",
        peak / 1024,
        UPLOAD_RSS_BOUND_KB / 1024
    );
}

/// Sends SIGTERM to the server and waits for it: it stops, reporting that it was stopped.
#[cfg(unix)]
fn sigterm(child: &mut std::process::Child) {
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let exit = child.wait().unwrap();
    assert!(!exit.success());
}

#[test]
#[cfg(unix)]
fn sigterm_removes_the_dropped_images_as_ctrl_c_does() {
    let dir = tempfile::tempdir().unwrap();
    let (clean, refs) = sample_folders(dir.path());
    let tmp = dir.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mut server = serve_in(&clean, &refs, &[], &tmp);
    let photo = std::fs::read(sample("clean-room.jpg")).unwrap();
    let (status, _) = request(
        server.addr,
        "POST",
        "/api/upload?kind=clean&name=mine.jpg",
        &photo,
    )
    .unwrap();
    assert_eq!(status, 200);
    let folders = || -> Vec<std::path::PathBuf> {
        std::fs::read_dir(&tmp)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect()
    };
    assert_eq!(folders().len(), 1, "the server's folder of dropped images");
    sigterm(&mut server.child);
    assert_eq!(folders(), Vec::<std::path::PathBuf>::new(), "left behind");
}

#[test]
#[cfg(unix)]
fn sigterm_while_uploads_are_being_written_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let (clean, refs) = sample_folders(dir.path());
    let tmp = dir.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mut server = serve_in(&clean, &refs, &[], &tmp);
    let addr = server.addr;
    let photo = std::sync::Arc::new(std::fs::read(sample("clean-room.jpg")).unwrap());
    let stored = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    // Uploaders that keep the handler threads writing until the server stops answering 200.
    let uploaders: Vec<_> = (0..6)
        .map(|i| {
            let (photo, stored) = (photo.clone(), stored.clone());
            std::thread::spawn(move || {
                for n in 0..10_000 {
                    let path = format!("/api/upload?kind=clean&name=t{i}-{n}.jpg");
                    match request(addr, "POST", &path, &photo) {
                        Ok((200, _)) => {
                            stored.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                        }
                        _ => return,
                    }
                }
            })
        })
        .collect();
    // Hang guard of 120 s while the first uploads are stored (not a timing assertion).
    for _ in 0..12_000 {
        if stored.load(std::sync::atomic::Ordering::SeqCst) >= 12 {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(stored.load(std::sync::atomic::Ordering::SeqCst) >= 12);
    sigterm(&mut server.child);
    for u in uploaders {
        u.join().unwrap();
    }
    let left: Vec<_> = std::fs::read_dir(&tmp)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let inside: Vec<_> = left
        .iter()
        .filter(|p| p.is_dir())
        .flat_map(|p| {
            std::fs::read_dir(p)
                .unwrap()
                .map(|e| e.unwrap().file_name())
        })
        .collect();
    assert!(left.is_empty(), "left behind: {left:?} holding {inside:?}");
}
