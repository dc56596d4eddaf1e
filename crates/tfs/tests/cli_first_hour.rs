//! What a new user meets first, on the README's fixture: the same run writes the same model file
//! to the byte.

use std::path::Path;
use std::process::{Command, Output};

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures");
const LIBRARY: &str = "x^1..7, x', xb_acc";

fn fixture(name: &str) -> String {
    format!("{FIXTURES}/{name}")
}

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs `tfs args…`, asserts it succeeded, returns stdout.
fn ok(args: &[&str]) -> String {
    let o = tfs(args);
    assert!(
        o.status.success(),
        "tfs {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn identify_into(out: &Path, extra: &[&str]) -> String {
    let (a, b) = (
        fixture("kresling-30db-train-1.csv"),
        fixture("kresling-30db-train-2.csv"),
    );
    let out = out.display().to_string();
    let mut args = vec!["identify", &a, &b, "--library", LIBRARY, "--out", &out];
    args.extend_from_slice(extra);
    ok(&args)
}

/// Two identical runs write the same bytes: the model file holds no stage timings (they differ
/// from run to run), while `--json` still reports them.
#[test]
fn two_identical_identify_runs_write_byte_identical_model_files() {
    let dir = tempfile::tempdir().unwrap();
    let (m1, m2) = (dir.path().join("m1.json"), dir.path().join("m2.json"));
    identify_into(&m1, &[]);
    identify_into(&m2, &[]);
    let (b1, b2) = (std::fs::read(&m1).unwrap(), std::fs::read(&m2).unwrap());
    assert!(!b1.is_empty());
    assert!(
        b1 == b2,
        "the two model files differ:\n{}\n---\n{}",
        String::from_utf8_lossy(&b1),
        String::from_utf8_lossy(&b2)
    );
    assert!(!String::from_utf8_lossy(&b1).contains("timing_ms"));
    let json = identify_into(&dir.path().join("m3.json"), &["--json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(
        v["trace"]["timing_ms"]
            .as_array()
            .is_some_and(|t| !t.is_empty()),
        "--json lost the stage timings: {}",
        v["trace"]
    );
}
