//! Shards: disjoint slices whose union, merged, is the unsharded run.

use std::collections::HashSet;

use uwnr_dataset::Shard;
use uwnr_dataset::manifest::read_manifest;

use crate::common::{assert_same_tree, inputs, opts, reinhard, run, spec};

#[test]
fn shards_in_one_folder_merge_into_the_unsharded_run() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 7, 4);
    let sp = spec(&clean, &refs, 2);
    let full = tmp.path().join("full");
    run(&full, &sp, &reinhard(), &opts(2));

    let sharded = tmp.path().join("sharded");
    let mut seen = HashSet::new();
    for index in 0..3 {
        let mut o = opts(1);
        o.shard = Some(Shard { index, count: 3 });
        let s = run(&sharded, &sp, &reinhard(), &o);
        assert!(s.complete);
        let m = read_manifest(&sharded.join(format!("manifest.shard-{index}-of-3.jsonl"))).unwrap();
        for (_, r) in m.records {
            assert!(seen.insert(r.id.clone()), "{} rendered by two shards", r.id);
        }
    }
    assert_eq!(seen.len(), 14);
    // Not merged yet: verify says so and finds the pairs.
    let report = uwnr_dataset::verify(&sharded, &|_, _| {}).unwrap();
    assert!(report.ok(), "{:?}", report.problems);
    assert!(report.notes.iter().any(|n| n.contains("merge")));

    let r = uwnr_dataset::merge(&sharded, &[], true).unwrap();
    assert_eq!((r.pairs, r.shards), (14, Some(3)));
    assert_same_tree(&full, &sharded);
}

#[test]
fn shards_in_their_own_folders_merge_by_copying() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 5, 3);
    let sp = spec(&clean, &refs, 1);
    let full = tmp.path().join("full");
    run(&full, &sp, &reinhard(), &opts(1));
    let dirs: Vec<_> = (0..2).map(|i| tmp.path().join(format!("s{i}"))).collect();
    for (index, d) in dirs.iter().enumerate() {
        let mut o = opts(1);
        o.shard = Some(Shard { index, count: 2 });
        run(d, &sp, &reinhard(), &o);
    }
    let merged = tmp.path().join("merged");
    let r = uwnr_dataset::merge(&merged, &dirs, true).unwrap();
    assert_eq!(r.pairs, 5);
    assert!(r.copied > 0);
    assert_same_tree(&full, &merged);
}

#[test]
fn merging_refuses_a_missing_or_unfinished_shard() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 6, 3);
    let sp = spec(&clean, &refs, 1);
    let out = tmp.path().join("out");
    let mut o = opts(1);
    o.shard = Some(Shard { index: 0, count: 2 });
    run(&out, &sp, &reinhard(), &o);
    let err = uwnr_dataset::merge(&out, &[], true).unwrap_err();
    assert!(err.to_string().contains("1/2"), "{err}");

    o.shard = Some(Shard { index: 1, count: 2 });
    run(&out, &sp, &reinhard(), &o);
    // Shard 1 loses a line (as if it were still running): merge names it and writes nothing.
    let name = out.join("manifest.shard-1-of-2.jsonl");
    let text = std::fs::read_to_string(&name).unwrap();
    let cut: String = text.lines().skip(1).map(|l| format!("{l}\n")).collect();
    std::fs::write(&name, cut).unwrap();
    let err = uwnr_dataset::merge(&out, &[], true).unwrap_err();
    assert!(err.to_string().contains("shard 1/2 lacks 1"), "{err}");
    assert!(!out.join("manifest.jsonl").exists());
}

/// Rewrites the first line of a manifest so its underwater file is `path`.
fn craft_first_line(manifest: &std::path::Path, path: &str) {
    let text = std::fs::read_to_string(manifest).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut r: serde_json::Value = serde_json::from_str(&lines[0]).unwrap();
    r["underwater"] = serde_json::Value::String(path.into());
    lines[0] = r.to_string();
    std::fs::write(manifest, lines.join("\n") + "\n").unwrap();
}

#[test]
fn manifest_paths_outside_the_folder_are_refused_by_merge_verify_and_resume() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 4, 2);
    let sp = spec(&clean, &refs, 1);
    std::fs::write(tmp.path().join("secret.txt"), b"not for the dataset").unwrap();
    for crafted in [
        "../secret.txt",
        "underwater/../../../../x.png",
        "/etc/hostname",
    ] {
        let shard = tmp.path().join("shard0");
        let _ = std::fs::remove_dir_all(&shard);
        let mut o = opts(1);
        o.shard = Some(Shard { index: 0, count: 1 });
        run(&shard, &sp, &reinhard(), &o);
        let manifest = shard.join("manifest.shard-0-of-1.jsonl");
        craft_first_line(&manifest, crafted);
        let merged = tmp.path().join("merged");
        let _ = std::fs::remove_dir_all(&merged);
        // Merge (copying from the shard folder) refuses, naming the file and the line.
        let err = uwnr_dataset::merge(&merged, std::slice::from_ref(&shard), true)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("manifest.shard-0-of-1.jsonl") && err.contains("line 1"),
            "{crafted}: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(!tmp.path().join("x.png").exists());
        assert!(!merged.join("manifest.jsonl").exists());
        // Verify reports it.
        let report = uwnr_dataset::verify(&shard, &|_, _| {}).unwrap();
        assert!(!report.ok());
        assert!(
            report
                .problems
                .iter()
                .any(|p| p.contains("line 1") && p.contains(crafted)),
            "{:?}",
            report.problems
        );
        // Resuming the shard refuses it too.
        let err = uwnr_dataset::generate(
            &shard,
            &sp,
            &reinhard(),
            &o,
            &std::sync::atomic::AtomicBool::new(false),
            &mut |_| {},
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("line 1"), "{crafted}: {err}");
    }
}
