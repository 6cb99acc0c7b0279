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
