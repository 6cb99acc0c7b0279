//! The routes through real HTTP requests: path checks, upload caps, failing renders, and a
//! render that the CLI's flags describe.

use serde_json::json;

use crate::common::Fixture;

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
            .contains("--water-type does not apply"),
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

#[test]
fn the_scene_scale_is_checked_in_the_f32_metres_renders_use() {
    let f = Fixture::new(1 << 20);
    // A range past f32 (then infinite) or past any water is refused when asked, not failed (or
    // rendered) later.
    for range in [json!([1.0, 1e300]), json!([1e30, 1e31]), json!([0.0, 2.0])] {
        let (status, body) = f.json(
            "POST",
            "/api/render",
            json!({"view": "d", "clean": {"index": 0}, "reference": 0,
                "options": {"method": "uwnr", "depth_scale": range}})
            .to_string()
            .as_bytes(),
        );
        assert_eq!(status, 400, "{range}: {body}");
        let e = body["error"].as_str().unwrap();
        assert!(e.starts_with("--depth-scale "), "{e}");
    }
    let (_, s) = f.render(&json!({"view": "d", "clean": {"index": 0}, "reference": 0,
        "options": {"method": "jerlov", "depth_scale": [1.5, 8.0]}}));
    assert_eq!(s["state"], "done", "{s}");
}

#[test]
fn a_render_body_over_its_limit_names_that_limit() {
    let f = Fixture::new(1 << 20);
    let (status, body) = f.json("POST", "/api/render", &vec![b' '; 66 * 1024]);
    assert_eq!(status, 413, "{body}");
    let e = body["error"].as_str().unwrap();
    assert!(!e.contains("--max-upload-mb") && e.contains("65536"), "{e}");
}
