//! `tfs compare` on models that `tfs diagnose`/`refit` extended: a delayed input is computed
//! from the record and a hidden Maxwell element is an internal state simulated with the motion
//! (also when an older model file names it as a computed column), not demanded as CSV columns.

use std::path::{Path, PathBuf};
use std::process::Command;

use tfs::data::{Record, write_csv};
use tfs::dynamics::{Dopri5, Integrator, SampledInput};
use tfs::library::Model;
use tfs::signal::{Excitation, Sweep, SweepKind};

const DT: f64 = 0.01;

fn model(dofs: &[&str], equations: &[&[(&str, f64)]]) -> Model {
    let eqs: Vec<String> = dofs
        .iter()
        .zip(equations)
        .map(|(d, terms)| {
            let list: Vec<String> = terms
                .iter()
                .map(|(t, c)| format!(r#"{{"term":"{t}","coef":{c}}}"#))
                .collect();
            format!(r#"{{"dof":"{d}","terms":[{}]}}"#, list.join(","))
        })
        .collect();
    let names: Vec<String> = dofs.iter().map(|d| format!("\"{d}\"")).collect();
    let json = format!(
        r#"{{"format":"tfs-model/1","dofs":[{}],"equations":[{}],"method":"truth"}}"#,
        names.join(","),
        eqs.join(",")
    );
    Model::from_json_str(&json).unwrap()
}

/// A 60 s sweep of base acceleration, from rest.
fn sweep() -> (Vec<f64>, Vec<f64>) {
    let n = (60.0 / DT) as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    let u = Sweep::new(SweepKind::Linear, 0.1, 1.2, 60.0, 2.0, 2.0)
        .unwrap()
        .sample(&t);
    (t, u)
}

/// Simulates `sys_model` under `inputs` (its input columns, in its order) and writes
/// `t, x, xb_acc` only: the effect columns are not in the file.
fn write(
    dir: &Path,
    name: &str,
    sys_model: &Model,
    inputs: Vec<Vec<f64>>,
    t: &[f64],
    u: &[f64],
) -> PathBuf {
    let sys = sys_model.compile().unwrap();
    let n = sys_model.dofs.len();
    let traj = Dopri5::with_tol(1e-10, 1e-12)
        .integrate(
            &sys,
            &SampledInput::new(0.0, DT, inputs).unwrap(),
            &vec![0.0; n],
            &vec![0.0; n],
            t,
        )
        .unwrap();
    let rec = Record::new(
        name,
        t.to_vec(),
        vec![
            ("x".into(), traj.x[0].clone()),
            ("xb_acc".into(), u.to_vec()),
        ],
    )
    .unwrap();
    let path = dir.join(name);
    write_csv(&path, &rec).unwrap();
    path
}

fn compare(model: &Model, dir: &Path, data: &Path) -> serde_json::Value {
    let mpath = dir.join("model.json");
    model.write_path(&mpath).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args([
            "compare",
            "--model",
            &mpath.display().to_string(),
            &data.display().to_string(),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tfs compare failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn compare_computes_a_delayed_input() {
    let dir = tempfile::tempdir().unwrap();
    let (t, u) = sweep();
    let delay = 0.05;
    let ud = tfs::diagnose::effects::delayed(&u, DT, delay);
    // The system is driven by the delayed input; the file holds only the input as measured.
    let col = "xb_acc_delay_0p05";
    let m = model(
        &["x"],
        &[&[("x", -4.0), ("x'", -0.3), ("x^3", -2.0), (col, -1.0)]],
    );
    let data = write(dir.path(), "delayed.csv", &m, vec![ud], &t, &u);
    let v = compare(&m, dir.path(), &data);
    let r = v["files"][0]["r_mse"].as_f64().unwrap();
    assert!(r < 1e-3, "the true delayed model scores R-MSE {r}: {v}");
    // Scoring the same data without the delay must be visibly worse, or the test proves nothing.
    let plain = model(
        &["x"],
        &[&[("x", -4.0), ("x'", -0.3), ("x^3", -2.0), ("xb_acc", -1.0)]],
    );
    let r0 = compare(&plain, dir.path(), &data)["files"][0]["r_mse"]
        .as_f64()
        .unwrap();
    assert!(r0 > 5.0 * r, "without the delay {r0}, with it {r}");
}

#[test]
fn compare_simulates_a_maxwell_element() {
    let dir = tempfile::tempdir().unwrap();
    let (t, u) = sweep();
    let tau = 0.5;
    // The generating system carries the Maxwell element as a second coordinate p with
    // tau p'' + p' = x' (p' is the filtered velocity), which only this test sees.
    let sys = model(
        &["x", "p"],
        &[
            &[
                ("x", -4.0),
                ("x'", -0.2),
                ("x^3", -2.0),
                ("p'", -1.5),
                ("xb_acc", -1.0),
            ],
            &[("x'", 1.0 / tau), ("p'", -1.0 / tau)],
        ],
    );
    let data = write(dir.path(), "maxwell.csv", &sys, vec![u.clone()], &t, &u);
    let m = model(
        &["x"],
        &[&[
            ("x", -4.0),
            ("x'", -0.2),
            ("x^3", -2.0),
            ("maxwell(x', 0.5)", -1.5),
            ("xb_acc", -1.0),
        ]],
    );
    let v = compare(&m, dir.path(), &data);
    let r = v["files"][0]["r_mse"].as_f64().unwrap();
    assert!(r < 1e-2, "the true Maxwell model scores R-MSE {r}: {v}");
    // A model file written when the element was a computed column scores the same.
    let legacy = m
        .to_json_string()
        .unwrap()
        .replace("maxwell(x', 0.5)", "maxwell_x_tau_0p5")
        .replace(
            r#""inputs": [
    "xb_acc"
  ]"#,
            r#""inputs": ["xb_acc", "maxwell_x_tau_0p5"]"#,
        );
    let lpath = dir.path().join("legacy.json");
    std::fs::write(&lpath, legacy).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(["compare", "--model", &lpath.display().to_string()])
        .arg(&data)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lv: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let lr = lv["files"][0]["r_mse"].as_f64().unwrap();
    assert!((lr - r).abs() <= 1e-9 * r.max(1e-12), "legacy {lr} vs {r}");
    let plain = model(
        &["x"],
        &[&[("x", -4.0), ("x'", -0.2), ("x^3", -2.0), ("xb_acc", -1.0)]],
    );
    let r0 = compare(&plain, dir.path(), &data)["files"][0]["r_mse"]
        .as_f64()
        .unwrap();
    assert!(
        r0 > 5.0 * r,
        "without the Maxwell element {r0}, with it {r}"
    );
}

/// Runs `tfs` with `args` and returns its JSON output (the command must succeed).
fn tfs_json(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tfs {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// A double well with Bouc–Wen hysteresis: `refit --add hysteresis` writes a model file whose
/// internal state carries its law and parameters, and that file is read back and simulated
/// (state from rest) by `compare`, `diagnose` and `basin`.
#[test]
fn hysteretic_model_round_trips_through_refit_compare_diagnose_and_basin() {
    let dir = tempfile::tempdir().unwrap();
    let (t, u) = sweep();
    let structure = [("x", 1.0), ("x^3", -1.0), ("x'", -0.3), ("xb_acc", -1.0)];
    let mut with_memory = structure.to_vec();
    with_memory.push(("bouc_wen(x', 3, 1)", -0.5));
    let truth = model(&["x"], &[&with_memory]);
    let sys = truth.compile().unwrap();
    let coords = tfs::dynamics::SecondOrderSystem::dofs(&sys);
    assert_eq!(coords, 2, "one DOF and one internal state");
    let traj = Dopri5::with_tol(1e-10, 1e-12)
        .integrate(
            &sys,
            &SampledInput::new(0.0, DT, vec![u.clone()]).unwrap(),
            &vec![0.0; coords],
            &vec![0.0; coords],
            &t,
        )
        .unwrap();
    let rec = Record::new(
        "bw.csv",
        t.clone(),
        vec![("x".into(), traj.x[0].clone()), ("xb_acc".into(), u)],
    )
    .unwrap();
    let data = dir.path().join("bw.csv");
    write_csv(&data, &rec).unwrap();
    let p = |name: &str| dir.path().join(name).display().to_string();
    model(&["x"], &[&structure])
        .write_path(p("start.json"))
        .unwrap();
    let d = data.display().to_string();
    let refit = tfs_json(&[
        "refit",
        "--model",
        &p("start.json"),
        "--add",
        "hysteresis",
        "--out",
        &p("bw.json"),
        &d,
    ]);
    // The file carries the state and reads back as the same model.
    let text = std::fs::read_to_string(p("bw.json")).unwrap();
    assert!(text.contains("bouc_wen(x', "), "{text}");
    let back = Model::from_path(p("bw.json")).unwrap();
    assert_eq!(back.internal_states().len(), 1, "{refit}");
    let r = |m: &str| {
        tfs_json(&["compare", "--model", &p(m), &d])["files"][0]["r_mse"]
            .as_f64()
            .unwrap()
    };
    let (before, after) = (r("start.json"), r("bw.json"));
    assert!(after < 0.2 * before, "R-MSE {before} -> {after}");
    let diag = tfs_json(&["diagnose", "--model", &p("bw.json"), &d]);
    assert!(
        diag["ranked"].as_array().is_some_and(|a| !a.is_empty()),
        "{diag}"
    );
    let basin = tfs_json(&[
        "basin",
        "--model",
        &p("bw.json"),
        "--grid",
        "30x30",
        "--x",
        "-2:2",
        "--v",
        "-2:2",
    ]);
    let text = basin.to_string();
    assert!(text.contains("stable"), "{text}");
}
