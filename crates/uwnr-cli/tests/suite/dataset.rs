//! `uwnr dataset`: determinism with the network across job and thread counts, a run killed
//! with SIGKILL (several times) resuming to the same folder, shards and merge, verify.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{s, stderr, tree, uwnr, weights};

/// Writes `n_clean` clean images and `n_ref` references (small, textured).
fn inputs(root: &Path, n_clean: usize, n_ref: usize) -> (PathBuf, PathBuf) {
    let (clean, refs) = (root.join("clean-in"), root.join("refs-in"));
    std::fs::create_dir_all(&clean).unwrap();
    std::fs::create_dir_all(&refs).unwrap();
    let img = |w: u32, h: u32, seed: u32, tint: [f32; 3]| {
        image::RgbImage::from_fn(w, h, |x, y| {
            let v = |c: u32| {
                let t = ((x * 7 + y * 3 + seed * 13 + c * 5) % 97) as f32 / 96.0;
                (t * tint[c as usize] * 255.0) as u8
            };
            image::Rgb([v(0), v(1), v(2)])
        })
    };
    for i in 0..n_clean {
        let (w, h) = (48 + 8 * (i as u32 % 3), 40 + 4 * (i as u32 % 2));
        img(w, h, i as u32, [1.0, 0.9, 0.8])
            .save(clean.join(format!("c{i:02}.png")))
            .unwrap();
    }
    for j in 0..n_ref {
        img(40, 30, 50 + j as u32, [0.2, 0.7, 0.8])
            .save(refs.join(format!("r{j:02}.png")))
            .unwrap();
    }
    (clean, refs)
}

fn assert_same_tree(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    assert_eq!(
        ta.keys().collect::<Vec<_>>(),
        tb.keys().collect::<Vec<_>>(),
        "different files"
    );
    for (k, v) in &ta {
        assert!(v == &tb[k], "{k} differs");
    }
}

fn network_args<'a>(clean: &'a Path, refs: &'a Path, out: &'a Path, w: &'a Path) -> Vec<&'a str> {
    vec![
        "dataset",
        "--clean",
        s(clean),
        "--references",
        s(refs),
        "--output",
        s(out),
        "--per-image",
        "2",
        "--weights",
        s(w),
        "--save-depth",
        "--save-lightfield",
    ]
}

#[test]
fn network_datasets_are_identical_across_job_and_thread_counts() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 4, 3);
    let w = weights();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let mut args = network_args(&clean, &refs, &a, &w);
    args.extend(["--jobs", "1"]);
    let o = Command::new(env!("CARGO_BIN_EXE_uwnr"))
        .args(&args)
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("8 rendered, 0 skipped"),
        "{}",
        stderr(&o)
    );
    let mut args = network_args(&clean, &refs, &b, &w);
    args.extend(["--jobs", "2"]);
    let o = uwnr(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_tree(&a, &b);
    let o = uwnr(&["dataset", "verify", s(&a)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("verify: OK: 8 pairs"), "{}", stderr(&o));
}

fn manifest_lines(out: &Path) -> usize {
    std::fs::read(out.join("manifest.jsonl"))
        .map(|b| b.iter().filter(|&&c| c == b'\n').count())
        .unwrap_or(0)
}

#[test]
fn a_run_killed_at_any_moment_resumes_to_the_same_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 12, 4);
    let w = weights();
    let full = tmp.path().join("full");
    let o = uwnr(&network_args(&clean, &refs, &full, &w));
    assert!(o.status.success(), "{}", stderr(&o));
    let total = manifest_lines(&full);
    assert_eq!(total, 24);

    let killed = tmp.path().join("killed");
    let mut mid_run_kills = 0;
    for target in [1, 7, 15] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_uwnr"))
            .args(network_args(&clean, &refs, &killed, &w))
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(120);
        loop {
            if child.try_wait().unwrap().is_some() || Instant::now() > deadline {
                break;
            }
            if manifest_lines(&killed) >= target {
                child.kill().unwrap(); // SIGKILL
                mid_run_kills += 1;
                break;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        child.wait().unwrap();
    }
    assert!(
        mid_run_kills >= 2,
        "the run finished before it could be killed"
    );
    assert!(manifest_lines(&killed) < total);
    let o = uwnr(&network_args(&clean, &refs, &killed, &w));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("skipped (already done)"),
        "{}",
        stderr(&o)
    );
    let o = uwnr(&["dataset", "verify", s(&killed)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_same_tree(&full, &killed);

    // Damage is named by verify, with a non-zero exit.
    std::fs::remove_file(killed.join("depth/c03_1.png")).unwrap();
    let o = uwnr(&["dataset", "verify", s(&killed)]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("depth/c03_1.png (pair c03_1) is missing"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn shards_merge_into_the_unsharded_dataset() {
    shards_merge_into_the_unsharded_dataset_with(&["--method", "jerlov"]);
}

/// The bundled model records its water and strength as floats in every manifest line, which
/// `merge` reads back and writes again: the merged manifest must keep every digit.
#[test]
fn shards_merge_into_the_unsharded_dataset_with_the_bundled_model() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, refs) = inputs(tmp.path(), 0, 3);
    shards_merge_into_the_unsharded_dataset_with(&["--references", s(&refs)]);
}

fn shards_merge_into_the_unsharded_dataset_with(method: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, _) = inputs(tmp.path(), 5, 0);
    let run = |out: &Path, shard: Option<&str>| {
        let mut args = vec![
            "dataset",
            "--clean",
            s(&clean),
            "--output",
            s(out),
            "-k",
            "3",
            "--seed",
            "5",
        ];
        args.extend(method);
        if let Some(sh) = shard {
            args.extend(["--shard", sh]);
        }
        let o = uwnr(&args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    let full = tmp.path().join("full");
    run(&full, None);
    let sharded = tmp.path().join("sharded");
    run(&sharded, Some("1/2"));
    let o = uwnr(&["dataset", "merge", s(&sharded)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("0/2"), "{}", stderr(&o));
    run(&sharded, Some("0/2"));
    let o = uwnr(&["dataset", "merge", s(&sharded)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("merged 15 pairs from 2 shards"),
        "{}",
        stderr(&o)
    );
    assert_same_tree(&full, &sharded);
}

#[test]
fn bad_dataset_requests_fail_with_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 2, 2);
    let out = tmp.path().join("out");
    let o = uwnr(&[
        "dataset",
        "--clean",
        s(&clean),
        "--references",
        s(&refs),
        "--output",
        s(&out),
        "--method",
        "reinhard",
        "-k",
        "3",
    ]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("only 2 references"), "{err}");

    let o = uwnr(&["dataset", "verify", s(tmp.path())]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("dataset.json"), "{}", stderr(&o));

    let w = weights();
    let o = uwnr(&[
        "dataset",
        "--clean",
        s(&clean),
        "--output",
        s(&out),
        "--weights",
        s(&w),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--reference"), "{}", stderr(&o));
}
