//! What a new user meets first, on the README's fixture: the same run writes the same model file
//! to the byte, and the default output of each command fits on one screen with the full trace
//! under `-v`.

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

/// The lines a run printed on stdout (warnings are repeated there when stdout is not a
/// terminal, so they count).
fn lines(text: &str) -> usize {
    text.lines().count()
}

/// `identify` prints the equation, its fit, the verdict and what to do next on one screen; the
/// criteria trace is under `-v`.
#[test]
fn identify_fits_on_one_screen_and_verbose_keeps_the_trace() {
    let dir = tempfile::tempdir().unwrap();
    let short = identify_into(&dir.path().join("m.json"), &[]);
    assert!(lines(&short) <= 10, "{} lines:\n{short}", lines(&short));
    assert!(
        short.starts_with("x'' = ") || short.contains("\nx'' = "),
        "{short}"
    );
    assert!(short.contains("±"), "no intervals:\n{short}");
    for needle in ["fit x: ", "verdict x: ", "next: ", "tfs compare --model"] {
        assert!(short.contains(needle), "'{needle}' missing:\n{short}");
    }
    assert!(
        !short.contains("criterion 1") && !short.contains("time (ms)"),
        "{short}"
    );
    let long = identify_into(&dir.path().join("m.json"), &["-v"]);
    for needle in [
        "criterion 1: κ = ",
        "criterion 3",
        "why:",
        "time (ms):",
        "offsets:",
    ] {
        assert!(
            long.contains(needle),
            "'{needle}' missing under -v:\n{long}"
        );
    }
    assert!(lines(&long) > 20, "{long}");
}

/// `compare`, `diagnose` and `refit` print their table and verdict by default, the per-record
/// lines and reasons under `-v`.
#[test]
fn compare_diagnose_and_refit_are_short_by_default() {
    let dir = tempfile::tempdir().unwrap();
    // Without the damping term: the diagnosis has an effect to name.
    let model = dir.path().join("m.json");
    let (a, b) = (
        fixture("kresling-30db-train-1.csv"),
        fixture("kresling-30db-train-2.csv"),
    );
    let test = fixture("kresling-30db-test.csv");
    let m = model.display().to_string();
    ok(&[
        "identify",
        &a,
        &b,
        "--library",
        "x^1..7, xb_acc",
        "--out",
        &m,
    ]);

    let c = ok(&["compare", "--model", &m, &test]);
    assert!(lines(&c) <= 4, "{c}");
    assert!(ok(&["compare", "--model", &m, &test, "-v"]).contains("offsets:"));

    let d = ok(&["diagnose", "--model", &m, &a, &b]);
    assert!(lines(&d) <= 16, "{} lines:\n{d}", lines(&d));
    assert!(d.contains("effect") && d.contains("R-MSE after"), "{d}");
    assert!(d.contains("the model's R-MSE on these records"), "{d}");
    assert!(!d.contains("residual: "), "{d}");
    let dv = ok(&["diagnose", "--model", &m, &a, &b, "--verbose"]);
    assert!(dv.contains("residual: ") && dv.contains("R-MSE"), "{dv}");
    assert!(lines(&dv) > lines(&d), "{dv}");

    let out = dir.path().join("r.json").display().to_string();
    let r = ok(&[
        "refit",
        "--model",
        &m,
        "--add",
        "linear-damping",
        "--out",
        &out,
        &a,
        &b,
    ]);
    assert!(lines(&r) <= 8, "{} lines:\n{r}", lines(&r));
    assert!(r.contains("lowered the geometric-mean R-MSE"), "{r}");
}

/// The README's loop, run as written (its `/tmp/` files in a temporary folder, its globs
/// expanded): every `# held-out R-MSE X` comment is what that `compare` prints, to the digits
/// shown, and `diagnose` names the effect its comment says.
#[test]
fn the_readmes_loop_prints_the_numbers_its_comments_show() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../README.md")).unwrap();
    let start = readme
        .find("The loop on the repository's fixtures")
        .expect("the README's loop section");
    let block = readme[start..]
        .split("```sh")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("the loop's shell block");
    let dir = tempfile::tempdir().unwrap();
    let root = format!("{FIXTURES}/..");
    let mut checked = 0;
    for line in block.lines().filter(|l| l.starts_with("tfs ")) {
        let (cmd, comment) = line.split_once('#').unwrap_or((line, ""));
        let tmp = format!("{}/", dir.path().display());
        let mut args: Vec<String> = Vec::new();
        for word in shell_words(cmd).into_iter().skip(1) {
            let w = word.replace("/tmp/", &tmp);
            if let Some((head, tail)) = w.split_once('*') {
                // A glob over fixtures: the files it matches, sorted.
                let (folder, prefix) = head.rsplit_once('/').unwrap();
                let mut hits: Vec<String> = std::fs::read_dir(format!("{root}/{folder}"))
                    .unwrap()
                    .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                    .filter(|n| n.starts_with(prefix) && n.ends_with(tail))
                    .map(|n| format!("{root}/{folder}/{n}"))
                    .collect();
                hits.sort();
                args.extend(hits);
            } else if w.starts_with("fixtures/") {
                args.push(format!("{root}/{w}"));
            } else {
                args.push(w);
            }
        }
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = ok(&refs);
        let comment = comment.trim();
        if let Some(v) = comment.strip_prefix("held-out R-MSE ") {
            let row = out.lines().nth(1).unwrap_or("");
            let got: f64 = row.split_whitespace().nth(1).unwrap().parse().unwrap();
            let digits = v.trim_start_matches("0.").trim_start_matches('0').len();
            assert_eq!(
                format!("{:.*e}", digits.saturating_sub(1), got),
                format!(
                    "{:.*e}",
                    digits.saturating_sub(1),
                    v.parse::<f64>().unwrap()
                ),
                "`{line}` printed {row}"
            );
            checked += 1;
        } else if let Some(e) = comment.strip_prefix("missing effect: ") {
            assert!(
                out.contains(&format!("missing effect: {e}")),
                "`{line}`:\n{out}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 3, "the loop's commented commands");
}

/// A command line split as a shell splits it: on blanks outside double quotes, the quotes
/// removed.
fn shell_words(line: &str) -> Vec<String> {
    let mut words = Vec::new();
    let (mut word, mut quoted, mut any) = (String::new(), false, false);
    for c in line.chars() {
        match c {
            '"' => {
                quoted = !quoted;
                any = true;
            }
            c if c.is_whitespace() && !quoted => {
                if any {
                    words.push(std::mem::take(&mut word));
                    any = false;
                }
            }
            c => {
                word.push(c);
                any = true;
            }
        }
    }
    if any {
        words.push(word);
    }
    words
}
