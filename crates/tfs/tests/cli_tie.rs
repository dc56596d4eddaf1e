//! `tfs identify --tie`: a two-mass chain identified with each coupling term shared by both
//! equations (Newton's third law), with intervals; bad combinations are refused by name.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tfs::data::{Record, write_csv};
use tfs::dynamics::{Dopri5, Integrator, SampledInput};
use tfs::library::Model;
use tfs::signal::{Excitation, Sweep, SweepKind};

const DT: f64 = 0.01;

/// x1'' = −4 x1 − 0.3 x1' + 6 h + 0.2 h' − u, x2'' = −6 h − 0.2 h' − u, h = x2 − x1.
fn truth() -> Model {
    let t = |s: &str, c: f64| format!(r#"{{"term":"{s}","coef":{c}}}"#);
    let json = format!(
        r#"{{"format":"tfs-model/1","dofs":["x1","x2"],"equations":[{{"dof":"x1","terms":[{},{},{},{},{}]}},{{"dof":"x2","terms":[{},{},{}]}}],"method":"truth"}}"#,
        t("x1", -4.0),
        t("x1'", -0.3),
        t("(x2-x1)", 6.0),
        t("(x2-x1)'", 0.2),
        t("xb_acc", -1.0),
        t("(x2-x1)", -6.0),
        t("(x2-x1)'", -0.2),
        t("xb_acc", -1.0),
    );
    Model::from_json_str(&json).unwrap()
}

fn record(dir: &Path, name: &str, f0: f64, f1: f64, dur: f64, amp: f64) -> PathBuf {
    let n = (dur / DT) as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    let u = Sweep::new(SweepKind::Linear, f0, f1, dur, amp, 2.0)
        .unwrap()
        .sample(&t);
    let sys = truth().compile().unwrap();
    let tr = Dopri5::with_tol(1e-10, 1e-12)
        .integrate(
            &sys,
            &SampledInput::new(0.0, DT, vec![u.clone()]).unwrap(),
            &[0.0, 0.0],
            &[0.0, 0.0],
            &t,
        )
        .unwrap();
    let rec = Record::new(
        name,
        t,
        vec![
            ("x1".into(), tr.x[0].clone()),
            ("x2".into(), tr.x[1].clone()),
            ("xb_acc".into(), u),
        ],
    )
    .unwrap();
    let path = dir.join(name);
    write_csv(&path, &rec).unwrap();
    path
}

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn tie_shares_the_coupling_between_the_equations() {
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<String> = [
        (0.05, 1.5, 60.0, 1.5),
        (0.1, 1.2, 50.0, 2.0),
        (0.05, 1.8, 60.0, 1.8),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(f0, f1, d, a))| {
        record(dir.path(), &format!("r{i}.csv"), f0, f1, d, a)
            .display()
            .to_string()
    })
    .collect();
    let out = dir.path().join("m.json").display().to_string();
    let mut args = vec!["identify", "--tie", "--out", &out, "--json"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--library", "x1, x1', (x2-x1), (x2-x1)', xb_acc"]);
    let o = tfs(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let m = Model::from_path(Path::new(&out)).unwrap();
    assert_eq!(m.method, "tfs-sindy-tied");
    let want = truth();
    for eq in &want.equations {
        for w in &eq.terms {
            let got = m
                .equation(&eq.dof)
                .unwrap()
                .terms
                .iter()
                .find(|t| t.term == w.term)
                .unwrap_or_else(|| panic!("{} missing from {}", w.term, m.equation_string()))
                .clone();
            assert!(
                (got.coef - w.coef).abs() < 0.01 * w.coef.abs(),
                "{}: {} in {}'' against {}",
                w.term,
                got.coef,
                eq.dof,
                w.coef
            );
            let [lo, hi] = got.interval.expect("interval");
            assert!(lo <= got.coef && got.coef <= hi);
        }
    }
    // The shared terms are one unknown: exactly opposite in the two equations.
    let c = |dof: &str, term: &str| {
        m.equation(dof)
            .unwrap()
            .terms
            .iter()
            .find(|t| t.term.to_string() == term)
            .map(|t| t.coef)
            .unwrap()
    };
    assert_eq!(c("x1", "(x2-x1)"), -c("x2", "(x2-x1)"));
    assert_eq!(c("x1", "(x2-x1)'"), -c("x2", "(x2-x1)'"));

    // Refused by name: the classical method, a wrong mass count, a single DOF.
    let o = tfs(&[
        "identify", "--tie", "--method", "sindy", &files[0], &files[1],
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--tie"));
    let o = tfs(&["identify", "--tie", "--masses", "1", &files[0], &files[1]]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--masses '1'"));
    let o = tfs(&["identify", "--tie", "--dofs", "x1", &files[0], &files[1]]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--tie"));
}
