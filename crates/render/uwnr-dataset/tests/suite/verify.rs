//! `verify` passes a sound dataset and names each kind of damage.

use std::path::Path;

use crate::common::{inputs, opts, reinhard, run, spec};

fn problems(out: &Path) -> Vec<String> {
    uwnr_dataset::verify(out, &|_, _| {}).unwrap().problems
}

fn dataset(root: &Path, name: &str) -> std::path::PathBuf {
    let (clean, refs) = inputs(root, 4, 3);
    let out = root.join(name);
    run(&out, &spec(&clean, &refs, 2), &reinhard(), &opts(2));
    out
}

#[test]
fn a_sound_dataset_passes() {
    let tmp = tempfile::tempdir().unwrap();
    let out = dataset(tmp.path(), "out");
    let report = uwnr_dataset::verify(&out, &|_, _| {}).unwrap();
    assert!(report.ok(), "{:?}", report.problems);
    assert_eq!((report.pairs, report.planned), (8, 8));
}

#[test]
fn a_deleted_file_is_found() {
    let tmp = tempfile::tempdir().unwrap();
    let out = dataset(tmp.path(), "out");
    std::fs::remove_file(out.join("clean/img01_1.png")).unwrap();
    let p = problems(&out);
    assert_eq!(p.len(), 1, "{p:?}");
    assert!(
        p[0].contains("clean/img01_1.png") && p[0].contains("missing"),
        "{p:?}"
    );
}

#[test]
fn a_truncated_file_is_found() {
    let tmp = tempfile::tempdir().unwrap();
    let out = dataset(tmp.path(), "out");
    let f = out.join("underwater/img02_0.png");
    let bytes = std::fs::read(&f).unwrap();
    std::fs::write(&f, &bytes[..bytes.len() / 2]).unwrap();
    let p = problems(&out);
    assert_eq!(p.len(), 1, "{p:?}");
    assert!(
        p[0].contains("underwater/img02_0.png") && p[0].contains("decode"),
        "{p:?}"
    );
}

#[test]
fn a_stray_manifest_line_is_found() {
    let tmp = tempfile::tempdir().unwrap();
    let out = dataset(tmp.path(), "out");
    let path = out.join("manifest.jsonl");
    let text = std::fs::read_to_string(&path).unwrap();
    let first = text.lines().next().unwrap().to_string();
    // A duplicate of a real line, a line for a pair the plan does not have, and garbage.
    let foreign = first.replace("img00_0", "img99_0");
    std::fs::write(&path, format!("{text}{first}\n{foreign}\nnot json\n")).unwrap();
    let p = problems(&out);
    assert_eq!(p.len(), 3, "{p:?}");
    assert!(
        p.iter()
            .any(|l| l.contains("line 9") && l.contains("twice")),
        "{p:?}"
    );
    assert!(
        p.iter()
            .any(|l| l.contains("img99_0") && l.contains("not in the plan")),
        "{p:?}"
    );
    assert!(p.iter().any(|l| l.contains("line 11")), "{p:?}");
}

#[test]
fn missing_pairs_and_stray_files_are_found() {
    let tmp = tempfile::tempdir().unwrap();
    let out = dataset(tmp.path(), "out");
    let path = out.join("manifest.jsonl");
    let text = std::fs::read_to_string(&path).unwrap();
    let kept: String = text.lines().skip(1).map(|l| format!("{l}\n")).collect();
    std::fs::write(&path, kept).unwrap();
    std::fs::write(out.join("underwater/.x_0.png.1-0.tmp"), b"").unwrap();
    let p = problems(&out);
    // img00_0's four files are now unrecorded, one pair is missing, one temp file.
    assert!(
        p.iter()
            .any(|l| l.contains("1 of 8 planned pairs are missing")),
        "{p:?}"
    );
    assert!(
        p.iter()
            .any(|l| l.contains("underwater/img00_0.png is not in the manifest")),
        "{p:?}"
    );
    assert!(p.iter().any(|l| l.contains("temporary file")), "{p:?}");
}
