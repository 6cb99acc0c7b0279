//! End-to-end tests of the `uwnr` binary: outputs, batches, and bad input.
//!
//! The network weights used here are the small width-8 parity fixture of uwnr-model (random
//! weights): these tests check the tool's behaviour, not the rendering's look.

use crate::common::{files_in, s, sample, stderr, uwnr, weights};

#[test]
fn renders_one_file_at_the_clean_images_size() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let o = uwnr(&[
        "render",
        s(&sample("clean-statues.jpg")),
        "--reference",
        s(&sample("ref-blue.jpg")),
        "--weights",
        s(&weights()),
        "--output",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    // 321x481 is not a multiple of 16: padded for the network, cropped back.
    assert_eq!((img.width(), img.height()), (321, 481));
    assert_eq!(files_in(dir.path()), vec!["out.png"]);
}

#[test]
fn batch_renders_the_rest_and_lists_failures() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir(&inputs).unwrap();
    std::fs::copy(sample("clean-statues.jpg"), inputs.join("a.jpg")).unwrap();
    std::fs::write(inputs.join("b.png"), b"this is not a png").unwrap();
    std::fs::copy(sample("ref-green.png"), inputs.join("c.png")).unwrap();
    let out = dir.path().join("out");
    let o = uwnr(&[
        "render",
        s(&inputs),
        "--reference",
        s(&sample("ref-green.png")),
        "--weights",
        s(&weights()),
        "--output",
        s(&out),
        "--format",
        "jpg",
    ]);
    let err = stderr(&o);
    assert!(
        !o.status.success(),
        "a failed item must make the exit non-zero"
    );
    assert!(err.contains("b.png"), "failure not listed: {err}");
    assert_eq!(files_in(&out), vec!["a.jpg", "c.jpg"]);
}

#[test]
fn pairing_all_renders_every_combination() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = uwnr(&[
        "render",
        s(&sample("clean-statues.jpg")),
        s(&sample("clean-room.jpg")),
        "--reference",
        s(&sample("ref-blue.jpg")),
        s(&sample("ref-green.png")),
        "--pairing",
        "all",
        "--weights",
        s(&weights()),
        "--output",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        files_in(&out),
        vec![
            "clean-room__ref-blue.png",
            "clean-room__ref-green.png",
            "clean-statues__ref-blue.png",
            "clean-statues__ref-green.png"
        ]
    );
}

#[test]
fn bad_inputs_give_one_clear_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.jpg");
    std::fs::write(&empty, b"").unwrap();
    let truncated = dir.path().join("truncated.jpg");
    let bytes = std::fs::read(sample("clean-statues.jpg")).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 3]).unwrap();
    let text = dir.path().join("notes.png");
    std::fs::write(&text, b"hello").unwrap();
    // A PNG header claiming 100000 x 100000 pixels, and nothing after it.
    let huge = dir.path().join("huge.png");
    let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR".to_vec();
    png.extend_from_slice(&100_000u32.to_be_bytes());
    png.extend_from_slice(&100_000u32.to_be_bytes());
    png.extend_from_slice(&[8, 2, 0, 0, 0, 0, 0, 0, 0]);
    std::fs::write(&huge, &png).unwrap();

    for bad in [&empty, &truncated, &text, &huge] {
        let out = dir.path().join("out.png");
        let o = uwnr(&[
            "render",
            s(bad),
            "--reference",
            s(&sample("ref-blue.jpg")),
            "--weights",
            s(&weights()),
            "--output",
            s(&out),
        ]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{bad:?} accepted");
        assert!(err.contains("uwnr:"), "{bad:?}: {err}");
        assert!(!out.exists(), "{bad:?} left an output");
    }
}

#[test]
fn missing_or_wrong_weights_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let not_weights = sample("ref-blue.jpg");
    for w in [dir.path().join("nope.safetensors"), not_weights] {
        let o = uwnr(&[
            "render",
            s(&sample("clean-statues.jpg")),
            "--reference",
            s(&sample("ref-blue.jpg")),
            "--weights",
            s(&w),
            "--output",
            s(&out),
        ]);
        let err = stderr(&o);
        assert!(!o.status.success());
        assert!(err.contains("weights"), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
        assert!(!out.exists());
    }
}

#[test]
fn unwritable_output_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("no/such/dir/out.png");
    let o = uwnr(&[
        "render",
        s(&sample("clean-statues.jpg")),
        "--reference",
        s(&sample("ref-blue.jpg")),
        "--weights",
        s(&weights()),
        "--output",
        s(&out),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("out.png"), "{}", stderr(&o));
    // The cause is said once: an error's message includes its cause, which it also keeps as its
    // source, and the line leaves out what the message already said.
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let o = uwnr(&[
        "render",
        s(&sample("clean-statues.jpg")),
        "--reference",
        s(&sample("ref-blue.jpg")),
        "--output",
        s(&file.join("out.png")),
    ]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert_eq!(err.matches("Not a directory").count(), 1, "{err}");
}

#[test]
fn lightfield_and_depth_commands_write_maps() {
    let dir = tempfile::tempdir().unwrap();
    let lf = dir.path().join("lf.png");
    let o = uwnr(&[
        "lightfield",
        s(&sample("ref-green.png")),
        "--output",
        s(&lf),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&lf).unwrap();
    assert_eq!((img.width(), img.height()), (256, 256));

    let d = dir.path().join("d.png");
    let o = uwnr(&["depth", s(&sample("clean-room.jpg")), "--output", s(&d)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&d).unwrap();
    assert_eq!((img.width(), img.height()), (640, 480));

    // A 16-bit millimetre map with normalisation, resized and noted.
    let d2 = dir.path().join("d2.png");
    let o = uwnr(&[
        "depth",
        s(&sample("clean-statues.jpg")),
        "--depth",
        s(&sample("clean-room-depth.png")),
        "--depth-normalize",
        "--output",
        s(&d2),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resized"), "{}", stderr(&o));
    let img = image::open(&d2).unwrap();
    assert_eq!((img.width(), img.height()), (321, 481));
}

#[test]
fn a_closed_stdout_stops_quietly_without_a_panic() {
    // The reader has closed the pipe before uwnr prints, as in `uwnr info | head -0`: the print
    // fails with EPIPE. (The read end is closed before uwnr starts: closed after, the race with a
    // `uwnr info` that prints within a millisecond was sometimes lost.)
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_uwnr"))
        .arg("info")
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("running uwnr");
    let o = child.wait_with_output().expect("waiting for uwnr");
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(o.status.code(), Some(141), "{err}");
}

#[test]
fn info_reports_the_bundled_model_and_the_variant() {
    let o = uwnr(&["info"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    // The bundled model: a config whose correction is none, so info says no network runs and
    // names what does (no parameter count or GMac of a network that is not there).
    assert!(text.contains("correction:  none"), "{text}");
    assert!(text.contains("no network is loaded or run"), "{text}");
    assert!(
        text.contains("fine detail") && text.contains("particles"),
        "{text}"
    );
    assert!(
        !text.contains("GMac") && !text.contains("MHB-Unet"),
        "{text}"
    );
    // A file of the paper's generator (the parity fixture, width 8) is the paper's variant.
    let w = weights();
    let o = uwnr(&["info", "--weights", s(&w)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("variant:     paper"), "{text}");
    assert!(!text.contains("detail retention"), "{text}");
}
