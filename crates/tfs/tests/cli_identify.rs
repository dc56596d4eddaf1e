//! End to end through the binary: records simulated from known equations are identified by
//! `tfs identify`, and `tfs compare` scores the model on a held-out sweep.

use std::path::{Path, PathBuf};
use std::process::Command;

use tfs::data::{Record, write_csv};
use tfs::dynamics::{Dopri5, Integrator, SampledInput};
use tfs::library::Model;
use tfs::signal::{Excitation, Sweep, SweepKind};

const DT: f64 = 0.005;

/// A 1-DOF model `x'' = Σ coef·term` (terms in the tfs grammar).
fn model(terms: &[(&str, f64)]) -> Model {
    let list: Vec<String> = terms
        .iter()
        .map(|(t, c)| format!(r#"{{"term":"{t}","coef":{c}}}"#))
        .collect();
    let json = format!(
        r#"{{"format":"tfs-model/1","dofs":["x"],"equations":[{{"dof":"x","terms":[{}]}}],"method":"truth"}}"#,
        list.join(",")
    );
    Model::from_json_str(&json).unwrap()
}

/// Simulates `truth` under a linear sweep of base acceleration and writes `t, x, xb_acc`.
fn record(truth: &Model, dir: &Path, name: &str, sweep: (f64, f64, f64, f64), x0: f64) -> PathBuf {
    let (f0, f1, dur, amp) = sweep;
    let n = (dur / DT).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    let u = Sweep::new(SweepKind::Linear, f0, f1, dur, amp, 2.0)
        .unwrap()
        .sample(&t);
    let input = SampledInput::new(0.0, DT, vec![u.clone()]).unwrap();
    let sys = truth.compile().unwrap();
    let traj = Dopri5::with_tol(1e-11, 1e-12)
        .integrate(&sys, &input, &[x0], &[0.0], &t)
        .unwrap();
    let rec = Record::new(
        name,
        t,
        vec![("x".into(), traj.x[0].clone()), ("xb_acc".into(), u)],
    )
    .unwrap();
    let path = dir.join(name);
    write_csv(&path, &rec).unwrap();
    path
}

fn tfs(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tfs {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Identifies with `method`, checks every true coefficient within `tol` (relative) and no
/// spurious term, then checks the held-out R-MSE.
fn check(truth: &Model, library: &str, method: &str, train: &[PathBuf], test: &Path, tol: f64) {
    let dir = test.parent().unwrap();
    let out_model = dir.join(format!("model-{method}.json"));
    let mut args: Vec<&str> = vec!["identify"];
    let train_s: Vec<String> = train.iter().map(|p| p.display().to_string()).collect();
    args.extend(train_s.iter().map(String::as_str));
    let out_s = out_model.display().to_string();
    args.extend([
        "--method",
        method,
        "--library",
        library,
        "--out",
        &out_s,
        "--json",
    ]);
    let v = tfs(&args);
    assert!(v["trace"].is_object(), "the trace is part of --json");
    let found = Model::from_path(&out_model).unwrap();
    let want = &truth.equations[0].terms;
    let got = &found.equations[0].terms;
    for w in want {
        let g = got.iter().find(|g| g.term == w.term).unwrap_or_else(|| {
            panic!(
                "{method}: term {} missing from {}",
                w.term,
                found.equation_string()
            )
        });
        let rel = ((g.coef - w.coef) / w.coef).abs();
        assert!(
            rel < tol,
            "{method}: {} = {} vs truth {} ({:.3}%)",
            w.term,
            g.coef,
            w.coef,
            100.0 * rel
        );
    }
    assert_eq!(
        got.len(),
        want.len(),
        "{method}: spurious terms in {}",
        found.equation_string()
    );
    let cmp = tfs(&[
        "compare",
        "--model",
        &out_s,
        &test.display().to_string(),
        "--json",
    ]);
    let r = cmp["files"][0]["r_mse"].as_f64().unwrap();
    assert!(r < 1e-3, "{method}: held-out R-MSE {r}");
    // The input-noise spread is reported per DOF (null where the input has no noise-only floor),
    // with the verdict on whether the error is the input's doing.
    let d = &cmp["files"][0]["dofs"][0];
    assert!(d.get("input_noise_spread").is_some(), "{cmp}");
    assert!(
        cmp["files"][0].get("error_is_input_noise").is_some(),
        "{cmp}"
    );
    // A model this close is ranked by its free run: no short-horizon ruler is needed.
    assert!(cmp["files"][0]["short_horizon"].is_null(), "{cmp}");
    // Asked for, the pieces of the length given score it too, and as closely.
    let cmp = tfs(&[
        "compare",
        "--model",
        &out_s,
        &test.display().to_string(),
        "--horizon",
        "50",
        "--json",
    ]);
    let sh = &cmp["files"][0]["short_horizon"];
    assert_eq!(sh["samples"].as_u64(), Some(50), "{cmp}");
    let r = sh["r_mse"].as_f64().unwrap();
    assert!(r < 1e-3, "{method}: short-horizon R-MSE {r}");
    let bad = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(["compare", "--model", &out_s, &test.display().to_string()])
        .args(["--horizon", "1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && err.contains("--horizon"), "{err}");
}

#[test]
fn duffing_is_recovered_by_both_methods() {
    let dir = tempfile::tempdir().unwrap();
    // x'' + 0.3x' − x + x³ = −xb_acc, started in the right-hand well.
    let truth = model(&[("x'", -0.3), ("x", 1.0), ("x^3", -1.0), ("xb_acc", -1.0)]);
    let train = vec![
        record(&truth, dir.path(), "d1.csv", (0.05, 0.6, 80.0, 0.8), 1.0),
        record(&truth, dir.path(), "d2.csv", (0.05, 0.5, 60.0, 1.2), 1.0),
    ];
    let test = record(&truth, dir.path(), "dtest.csv", (0.08, 0.5, 60.0, 1.0), 1.0);
    let lib = "x^1..5, x', xb_acc";
    check(&truth, lib, "sindy", &train, &test, 0.005);
    check(&truth, lib, "tfs", &train, &test, 0.005);
}

#[test]
fn table1_polynomial_model_is_recovered_by_both_methods() {
    let dir = tempfile::tempdir().unwrap();
    // x'' + 1.99x' + 12.12x⁵ − 18.03x⁶ + 6.56x⁷ = −xb_acc (the paper's Table 1, 60 dB row).
    let truth = model(&[
        ("x'", -1.99),
        ("x^5", -12.12),
        ("x^6", 18.03),
        ("x^7", -6.56),
        ("xb_acc", -1.0),
    ]);
    let train = vec![
        record(&truth, dir.path(), "k1.csv", (0.05, 1.5, 60.0, 4.0), 0.0),
        record(&truth, dir.path(), "k2.csv", (0.1, 1.2, 60.0, 5.0), 0.0),
    ];
    let test = record(&truth, dir.path(), "ktest.csv", (0.08, 1.4, 60.0, 4.5), 0.0);
    let lib = "x^1..7, x', xb_acc";
    check(&truth, lib, "sindy", &train, &test, 0.005);
    check(&truth, lib, "tfs", &train, &test, 0.005);
}

/// Without `--json`, every stage of the trace is printed for people: Criteria 1–4 in order
/// (Criterion 2 too, when it was not run), the settings and assembly tables, the verdict, and no
/// raw JSON; the model file carries the whole trace with the offsets.
#[test]
fn the_trace_is_printed_stage_by_stage_without_raw_json() {
    let dir = tempfile::tempdir().unwrap();
    let truth = model(&[("x'", -0.3), ("x", 1.0), ("x^3", -1.0), ("xb_acc", -1.0)]);
    let train = [
        record(&truth, dir.path(), "p1.csv", (0.05, 0.6, 80.0, 0.8), 1.0),
        record(&truth, dir.path(), "p2.csv", (0.05, 0.5, 60.0, 1.2), 1.0),
    ];
    let model_path = dir.path().join("p.json");
    let out = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(["identify", "-v", "--library", "x^1..5, x', xb_acc", "--out"])
        .arg(&model_path)
        .args(&train)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let mut at = 0;
    for stage in [
        "criterion 1: κ = ",
        "criterion 2: not run",
        "criterion 3 (Weak form)",
        "held-out (terms)",
        "← used",
        "criterion 4 (held out:",
        "assembly: ",
        "verdict: supported",
        "time (ms):",
        "offsets:",
    ] {
        let i = text[at..]
            .find(stage)
            .unwrap_or_else(|| panic!("'{stage}' missing or out of order in:\n{text}"));
        at += i;
    }
    assert!(
        !text.contains("{\""),
        "raw JSON in the human output:\n{text}"
    );
    let m = Model::from_path(&model_path).unwrap();
    assert_eq!(m.trace["method"], "tfs-sindy");
    assert!(m.trace["dofs"][0]["criterion1"]["supported"].is_boolean());
    assert!(m.trace["offsets"]["mode"].is_string(), "{}", m.trace);
}
