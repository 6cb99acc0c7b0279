//! `uwnr dataset` with labels (COCO, YOLO, masks) and WebDataset shards: labels scaled and
//! cropped with the pixels, new ids, bad label files refused or listed, resume, shards and merge,
//! verify, deterministic tars.

use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use crate::common::{s, stderr, tree, uwnr};

/// Clean images `a.png` (80x40) and `b.png` (60x60) with a COCO file, YOLO files and masks
/// that all describe the same two rectangles per image; and two references.
struct Set {
    clean: PathBuf,
    refs: PathBuf,
    coco: PathBuf,
    yolo: PathBuf,
    masks: PathBuf,
}

/// An image's name, width and height, and its two rectangles `[x, y, w, h]` (categories 1, 2).
type Objects = (&'static str, u32, u32, [u32; 4], [u32; 4]);

const OBJECTS: [Objects; 2] = [
    ("a", 80, 40, [30, 10, 20, 20], [0, 0, 12, 40]),
    ("b", 60, 60, [10, 20, 30, 16], [44, 40, 16, 20]),
];

fn set(root: &Path) -> Set {
    let dirs = ["clean", "refs", "yolo", "masks"].map(|d| root.join(d));
    for d in &dirs {
        std::fs::create_dir_all(d).unwrap();
    }
    let [clean, refs, yolo, masks] = dirs;
    let mut images = Vec::new();
    let mut annotations = Vec::new();
    for (n, (name, w, h, r1, r2)) in OBJECTS.iter().enumerate() {
        image::RgbImage::from_fn(*w, *h, |x, y| {
            image::Rgb([(x * 3) as u8, (y * 4) as u8, ((x + y) % 200) as u8])
        })
        .save(clean.join(format!("{name}.png")))
        .unwrap();
        images.push(
            json!({"id": 100 + n, "file_name": format!("{name}.png"), "width": w, "height": h}),
        );
        let mut mask = image::GrayImage::new(*w, *h);
        let mut yolo_text = String::new();
        for (k, r) in [r1, r2].iter().enumerate() {
            let [x, y, bw, bh] = **r;
            annotations.push(json!({
                "id": 1000 + 10 * n + k, "image_id": 100 + n, "category_id": k + 1, "iscrowd": 0,
                "bbox": [x, y, bw, bh], "area": bw * bh,
                "segmentation": [[x, y, x + bw, y, x + bw, y + bh, x, y + bh]],
            }));
            for yy in y..y + bh {
                for xx in x..x + bw {
                    mask.put_pixel(xx, yy, image::Luma([k as u8 + 1]));
                }
            }
            yolo_text.push_str(&format!(
                "{k} {} {} {} {}\n",
                (x as f64 + bw as f64 / 2.0) / *w as f64,
                (y as f64 + bh as f64 / 2.0) / *h as f64,
                bw as f64 / *w as f64,
                bh as f64 / *h as f64
            ));
        }
        mask.save(masks.join(format!("{name}.png"))).unwrap();
        std::fs::write(yolo.join(format!("{name}.txt")), yolo_text).unwrap();
    }
    for j in 0..2u32 {
        image::RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([10, (60 + x + j * 30) as u8, (90 + y) as u8])
        })
        .save(refs.join(format!("r{j}.png")))
        .unwrap();
    }
    let coco = root.join("instances.json");
    let file = json!({
        "info": {"description": "test"},
        "images": images,
        "annotations": annotations,
        "categories": [{"id": 1, "name": "fish"}, {"id": 2, "name": "diver"}],
    });
    std::fs::write(&coco, file.to_string()).unwrap();
    Set {
        clean,
        refs,
        coco,
        yolo,
        masks,
    }
}

fn run(set: &Set, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "dataset",
        "--clean",
        s(&set.clean),
        "--references",
        s(&set.refs),
        "--output",
        s(out),
        "--method",
        "reinhard",
        "-k",
        "2",
        "--size",
        "32x32",
        "--no-gallery",
    ];
    args.extend_from_slice(extra);
    uwnr(&args)
}

fn json_file(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

#[test]
fn coco_and_masks_follow_the_crop_with_new_ids() {
    let tmp = tempfile::tempdir().unwrap();
    let set = set(tmp.path());
    let out = tmp.path().join("out");
    let o = run(
        &set,
        &out,
        &["--coco", s(&set.coco), "--masks", s(&set.masks)],
    );
    assert!(o.status.success(), "{}", stderr(&o));

    let coco = json_file(&out.join("coco.json"));
    assert_eq!(coco["info"]["description"], "test");
    assert_eq!(coco["categories"][1]["name"], "diver");
    let images = coco["images"].as_array().unwrap();
    assert_eq!(images.len(), 4);
    let ids: Vec<u64> = images.iter().map(|i| i["id"].as_u64().unwrap()).collect();
    assert_eq!(ids, [1, 2, 3, 4]);
    assert_eq!(images[2]["file_name"], "underwater/b_0.png");
    assert_eq!(images[2]["source_id"], 101);
    let anns = coco["annotations"].as_array().unwrap();
    let ann_ids: Vec<u64> = anns.iter().map(|a| a["id"].as_u64().unwrap()).collect();
    let mut unique = ann_ids.clone();
    unique.dedup();
    assert_eq!(unique, ann_ids, "annotation ids are unique and in order");

    // a.png, 80x40 -> 32x32: scaled by 0.8 to 64x32, 16 px cropped left and right. Its first
    // rectangle [30, 10, 20, 20] becomes [8, 8, 16, 16]; the second, [0, 0, 12, 40], lies in the
    // cropped strip and is gone.
    let a0: Vec<&Value> = anns.iter().filter(|a| a["image_id"] == 1).collect();
    assert_eq!(a0.len(), 1);
    assert_eq!(a0[0]["bbox"], json!([8.0, 8.0, 16.0, 16.0]));
    assert_eq!(a0[0]["area"], json!(256.0));
    assert_eq!(a0[0]["category_id"], 1);
    // b.png, 60x60 -> 32x32: scale 32/60, no crop; both rectangles kept.
    let b1: Vec<&Value> = anns.iter().filter(|a| a["image_id"] == 4).collect();
    assert_eq!(b1.len(), 2);
    let sc = 32.0 / 60.0;
    let bbox: Vec<f64> = b1[0]["bbox"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    for (got, want) in bbox
        .iter()
        .zip([10.0 * sc, 20.0 * sc, 30.0 * sc, 16.0 * sc])
    {
        assert!((got - want).abs() < 1e-3, "{bbox:?}");
    }

    // Each pair's labels file is its part of coco.json; its mask holds only the source's values,
    // and its object pixels sit where the box says.
    let manifest = std::fs::read_to_string(out.join("manifest.jsonl")).unwrap();
    for line in manifest.lines() {
        let r: Value = serde_json::from_str(line).unwrap();
        let id = r["id"].as_str().unwrap();
        assert_eq!(r["labels"], format!("labels/{id}.json"));
        assert_eq!(r["mask"], format!("masks/{id}.png"));
        let pair = json_file(&out.join(format!("labels/{id}.json")));
        assert_eq!(pair["image"]["width"], 32);
        let mask = image::open(out.join(format!("masks/{id}.png")))
            .unwrap()
            .to_luma8();
        assert_eq!(mask.dimensions(), (32, 32));
        assert!(mask.pixels().all(|p| p.0[0] <= 2));
        for a in pair["annotations"].as_array().unwrap() {
            let b: Vec<f64> = a["bbox"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let (cx, cy) = ((b[0] + b[2] / 2.0) as u32, (b[1] + b[3] / 2.0) as u32);
            let class = a["category_id"].as_u64().unwrap() as u8;
            assert_eq!(mask.get_pixel(cx, cy).0[0], class, "{id}: {b:?}");
        }
    }
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));

    // A lost labels file is made again on resume, to the same bytes.
    let before = tree(&out);
    std::fs::remove_file(out.join("labels/b_1.json")).unwrap();
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("labels/b_1.json"), "{}", stderr(&o));
    let o = run(
        &set,
        &out,
        &["--coco", s(&set.coco), "--masks", s(&set.masks)],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(tree(&out), before);

    // Other labels than the dataset was made with: refused.
    let o = run(&set, &out, &["--coco", s(&set.coco)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("masks"), "{}", stderr(&o));

    // Shards in folders of their own, merged: the same coco.json.
    let (s0, s1, merged) = (
        tmp.path().join("s0"),
        tmp.path().join("s1"),
        tmp.path().join("merged"),
    );
    for (dir, shard) in [(&s0, "0/2"), (&s1, "1/2")] {
        let o = run(
            &set,
            dir,
            &[
                "--coco",
                s(&set.coco),
                "--masks",
                s(&set.masks),
                "--shard",
                shard,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = uwnr(&[
        "dataset",
        "merge",
        s(&merged),
        s(&s0),
        s(&s1),
        "--no-gallery",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(merged.join("coco.json")).unwrap(),
        std::fs::read(out.join("coco.json")).unwrap()
    );
    // Shards made from other label files are refused, naming the image's fingerprint, and the
    // refused merge leaves no folder behind.
    let edited = tmp.path().join("s1-edited");
    std::fs::create_dir_all(&edited).unwrap();
    let mut settings = json_file(&s1.join("dataset.json"));
    settings["labels"]["images"][0] = Value::from("fnv1a64:0000000000000000");
    std::fs::write(edited.join("dataset.json"), settings.to_string()).unwrap();
    let refused = tmp.path().join("refused");
    let o = uwnr(&["dataset", "merge", s(&refused), s(&s0), s(&edited)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("labels.images[0]"), "{}", stderr(&o));
    assert!(!refused.exists());
    // The annotations dropped, counted over the merged pairs as over the unsharded run's.
    let dropped = |dir: &Path| json_file(&dir.join("dataset.json"))["labels_dropped"].clone();
    assert!(dropped(&out).is_object(), "{}", dropped(&out));
    assert_eq!(dropped(&merged), dropped(&out));
    let o = uwnr(&["dataset", "verify", s(&merged)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn yolo_labels_are_renormalised_after_the_crop() {
    let tmp = tempfile::tempdir().unwrap();
    let set = set(tmp.path());
    let out = tmp.path().join("out");
    let o = run(&set, &out, &["--yolo", s(&set.yolo)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // a: the first box [30, 10, 20, 20] of 80x40 becomes [8, 8, 16, 16] of 32x32; the second is
    // cropped off.
    let a = std::fs::read_to_string(out.join("labels/a_1.txt")).unwrap();
    assert_eq!(a, "0 0.500000 0.500000 0.500000 0.500000\n");
    let b = std::fs::read_to_string(out.join("labels/b_0.txt")).unwrap();
    assert_eq!(b.lines().count(), 2);
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // At the native size, the files are copied as they are.
    let native = tmp.path().join("native");
    let o = uwnr(&[
        "dataset",
        "--clean",
        s(&set.clean),
        "--references",
        s(&set.refs),
        "--output",
        s(&native),
        "--method",
        "reinhard",
        "--yolo",
        s(&set.yolo),
        "--no-gallery",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(native.join("labels/b_0.txt")).unwrap(),
        std::fs::read(set.yolo.join("b.txt")).unwrap()
    );
}

#[test]
fn bad_label_files_are_refused_or_listed() {
    let tmp = tempfile::tempdir().unwrap();
    let set = set(tmp.path());

    // A broken file: one line naming it, nothing made.
    let broken = tmp.path().join("broken.json");
    std::fs::write(&broken, "{\"images\": [").unwrap();
    let out = tmp.path().join("o1");
    let o = run(&set, &out, &["--coco", s(&broken)]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("broken.json") && e.contains("not a JSON file"),
        "{e}"
    );
    // The folder the run would have created is not left behind, empty.
    assert!(!out.exists());

    // An annotation of an image the file does not list: refused, naming the annotation.
    let mut coco = json_file(&set.coco);
    coco["annotations"][0]["image_id"] = json!(999);
    let bad = tmp.path().join("unknown-image.json");
    std::fs::write(&bad, coco.to_string()).unwrap();
    let o = run(&set, &tmp.path().join("o2"), &["--coco", s(&bad)]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("annotation id 1000") && e.contains("image 999"),
        "{e}"
    );

    // A malformed annotation (an odd-length polygon): that image's pairs fail, listed with the
    // file, the annotation id and what is wrong; the other image's pairs are made.
    let mut coco = json_file(&set.coco);
    coco["annotations"][2]["segmentation"] = json!([[10, 20, 40, 20, 40]]);
    let bad = tmp.path().join("odd.json");
    std::fs::write(&bad, coco.to_string()).unwrap();
    let out = tmp.path().join("o3");
    let o = run(&set, &out, &["--coco", s(&bad)]);
    assert!(!o.status.success());
    let failed = std::fs::read_to_string(out.join("failed.jsonl")).unwrap();
    assert!(
        failed.contains("odd.json")
            && failed.contains("annotation id 1010")
            && failed.contains("odd number of coordinates (5)"),
        "{failed}"
    );
    assert!(failed.contains("b_0") && failed.contains("b_1"), "{failed}");
    assert!(
        stderr(&o).contains("fix the inputs listed in failed.jsonl"),
        "{}",
        stderr(&o)
    );
    let coco_out = json_file(&out.join("coco.json"));
    assert_eq!(coco_out["images"].as_array().unwrap().len(), 2);
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The label file fixed, the same command finishes the failed pairs.
    std::fs::write(&bad, json_file(&set.coco).to_string()).unwrap();
    let o = run(&set, &out, &["--coco", s(&bad)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!out.join("failed.jsonl").exists());
    let coco_out = json_file(&out.join("coco.json"));
    assert_eq!(coco_out["images"].as_array().unwrap().len(), 4);
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A label changed for pairs already made: refused, naming the file and the image.
    let mut coco = json_file(&set.coco);
    coco["annotations"][0]["bbox"] = json!([31, 10, 20, 20]);
    std::fs::write(&bad, coco.to_string()).unwrap();
    let o = run(&set, &out, &["--coco", s(&bad)]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("odd.json (the entry of a.png)") && e.contains("pair a_0"),
        "{e}"
    );
    // Another COCO file altogether: the message names the field, not two long snippets.
    let o = run(&set, &out, &["--coco", s(&set.coco)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("labels.file"), "{}", stderr(&o));

    // A mask of another size: listed, naming the mask.
    let masks = tmp.path().join("masks-bad");
    std::fs::create_dir_all(&masks).unwrap();
    std::fs::copy(set.masks.join("a.png"), masks.join("a.png")).unwrap();
    image::GrayImage::new(30, 30)
        .save(masks.join("b.png"))
        .unwrap();
    let out = tmp.path().join("o4");
    let o = run(&set, &out, &["--masks", s(&masks)]);
    assert!(!o.status.success());
    let failed = std::fs::read_to_string(out.join("failed.jsonl")).unwrap();
    assert!(
        failed.contains("b.png") && failed.contains("the mask is 30x30, the image is 60x60"),
        "{failed}"
    );

    // A broken YOLO line: listed with its line number.
    let yolo = tmp.path().join("yolo-bad");
    std::fs::create_dir_all(&yolo).unwrap();
    std::fs::copy(set.yolo.join("a.txt"), yolo.join("a.txt")).unwrap();
    std::fs::write(yolo.join("b.txt"), "0 0.5 0.5 0.2 0.2\n1 0.5 0.5\n").unwrap();
    let out = tmp.path().join("o5");
    let o = run(&set, &out, &["--yolo", s(&yolo)]);
    assert!(!o.status.success());
    let failed = std::fs::read_to_string(out.join("failed.jsonl")).unwrap();
    assert!(failed.contains("b.txt: line 2"), "{failed}");

    // Labels that match no clean image: refused at the start.
    let o = run(&set, &tmp.path().join("o6"), &["--yolo", s(&set.refs)]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("no label file matches"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn webdataset_shards_are_deterministic_and_verified() {
    let tmp = tempfile::tempdir().unwrap();
    let set = set(tmp.path());
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    for (out, jobs) in [(&a, "1"), (&b, "2")] {
        let o = run(
            &set,
            out,
            &[
                "--coco",
                s(&set.coco),
                "--masks",
                s(&set.masks),
                "--format",
                "webdataset",
                "--shard-size",
                "64K",
                "-j",
                jobs,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // The same command with other job counts: the same bytes, tars included.
    assert_eq!(tree(&a), tree(&b));
    let index = json_file(&a.join("webdataset/index.json"));
    assert_eq!(index["pairs"], 4);
    let shards = index["shards"].as_array().unwrap();
    let pairs: u64 = shards.iter().map(|s| s["pairs"].as_u64().unwrap()).sum();
    assert_eq!(pairs, 4);
    for sh in shards {
        let bytes = sh["bytes"].as_u64().unwrap();
        assert!(sh["pairs"] == 1 || bytes <= 64 * 1024, "{sh}");
        let file = std::fs::metadata(a.join("webdataset").join(sh["file"].as_str().unwrap()));
        assert_eq!(file.unwrap().len(), bytes);
    }
    let tar = std::fs::read(a.join("webdataset/uwnr-000000.tar")).unwrap();
    // The first member is the first pair's manifest line, named by its key.
    assert_eq!(&tar[..20], b"00000000-a_0.json\0\0\0");
    let o = uwnr(&["dataset", "verify", s(&a)]);
    assert!(o.status.success(), "{}", stderr(&o));

    // An export to elsewhere gives the same shards; a stale pack is a verify problem.
    let elsewhere = tmp.path().join("wds");
    let o = uwnr(&[
        "dataset",
        "export",
        s(&a),
        "--to",
        s(&elsewhere),
        "--shard-size",
        "64K",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(tree(&elsewhere), tree(&a.join("webdataset")));
    std::fs::remove_file(a.join("webdataset/uwnr-000000.tar")).unwrap();
    let o = uwnr(&["dataset", "verify", s(&a)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("uwnr dataset export"), "{}", stderr(&o));
}

#[test]
fn degenerate_and_outside_labels_are_clipped_or_dropped_and_counted() {
    let tmp = tempfile::tempdir().unwrap();
    let set = set(tmp.path());
    // b.png (60x60): a box 19 px past the edge (clipped), a 2-point polygon, a polygon wholly
    // outside and a zero-width box (dropped, counted).
    let mut coco = json_file(&set.coco);
    coco["annotations"][2]["bbox"] = json!([50, 50, 29, 5]);
    coco["annotations"][2]["segmentation"] = json!([]);
    coco["annotations"][2]["area"] = json!(145);
    let extra = [
        json!({"id": 2000, "image_id": 101, "category_id": 1, "segmentation": [[1, 1, 5, 5]]}),
        json!({"id": 2001, "image_id": 101, "category_id": 1,
               "segmentation": [[70, 0, 90, 0, 80, 20]]}),
        json!({"id": 2002, "image_id": 101, "category_id": 1, "bbox": [5, 5, 0, 10]}),
    ];
    coco["annotations"]
        .as_array_mut()
        .unwrap()
        .extend(extra.iter().cloned());
    let edges = tmp.path().join("edges.json");
    std::fs::write(&edges, coco.to_string()).unwrap();
    for (dir, size) in [("native", None), ("sized", Some("32x32"))] {
        let out = tmp.path().join(dir);
        let mut args = vec![
            "dataset",
            "--clean",
            s(&set.clean),
            "--references",
            s(&set.refs),
            "--output",
            s(&out),
            "--method",
            "reinhard",
            "-k",
            "2",
            "--no-gallery",
            "--coco",
            s(&edges),
        ];
        if let Some(size) = size {
            args.extend(["--size", size]);
        }
        let o = uwnr(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("labels: "), "{e}");
        let coco_out = json_file(&out.join("coco.json"));
        let ids: Vec<u64> = coco_out["annotations"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|a| a["id"].as_u64())
            .collect();
        // None of the dropped annotations' copies remain: each pair keeps its image's 2 good
        // ones (at 32x32 the crop removes one of a's).
        assert_eq!(
            ids.len(),
            4 * 2 - usize::from(size.is_some()) * 2,
            "{dir}: {ids:?}"
        );
        let manifest = std::fs::read_to_string(out.join("manifest.jsonl")).unwrap();
        let b0: Value = manifest
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap())
            .find(|r| r["id"] == "b_0")
            .unwrap();
        assert_eq!(
            b0["labels_info"]["dropped"],
            json!({"degenerate_polygon": 1, "empty_box": 1, "outside_image": 1}),
            "{dir}"
        );
        let settings = json_file(&out.join("dataset.json"));
        assert_eq!(settings["labels_dropped"]["outside_image"], 2, "{dir}");
        if size.is_none() {
            // At the native size the clipped box keeps what is inside: [50, 50, 10, 5].
            let b = coco_out["annotations"]
                .as_array()
                .unwrap()
                .iter()
                .find(|a| a["image_id"] == 3 && a["category_id"] == 1)
                .unwrap()
                .clone();
            assert_eq!(b["bbox"], json!([50.0, 50.0, 10.0, 5.0]));
            assert_eq!(b["area"], json!(50.0));
        }
        let o = uwnr(&["dataset", "verify", s(&out)]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
}

#[test]
fn verify_names_label_files_edited_after_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let set = set(tmp.path());
    let out = tmp.path().join("out");
    let o = run(&set, &out, &["--coco", s(&set.coco)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let path = out.join("coco.json");
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(
        &path,
        text.replacen("[8.0,8.0,16.0,16.0]", "[8.0,8.0,16.0,17.0]", 1),
    )
    .unwrap();
    assert_ne!(std::fs::read_to_string(&path).unwrap(), text);
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("coco.json differs"), "{}", stderr(&o));
    std::fs::write(&path, &text).unwrap();
    let pair = out.join("labels/a_0.json");
    let t = std::fs::read_to_string(&pair).unwrap();
    std::fs::write(&pair, t.replacen("16.0", "17.0", 1)).unwrap();
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("labels/a_0.json (pair a_0) was changed"),
        "{}",
        stderr(&o)
    );
}
