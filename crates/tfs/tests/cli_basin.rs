//! `tfs basin` and `tfs med` end to end: limits named by flag, the coarse-to-fine map against
//! the library's every-start map, the MED the same as on the original scalar path, and a figure
//! whose axes carry units.

use std::path::PathBuf;
use std::process::{Command, Output};

use tfs::basin::{BasinConfig, Method, WellInfo, basin_sdof, compare, med_sdof};
use tfs::library::Model;

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .expect("the tfs binary runs")
}

fn model(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../../fixtures/models/{name}.json"))
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// One stderr line, exit code 2, every needle present.
fn assert_refused(out: &Output, needles: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    for n in needles {
        assert!(err.contains(n), "'{n}' missing from: {err}");
    }
}

/// Wells of a 1-DOF model file as the CLI builds them (restoring force and potential).
fn wells_of(m: &Model, search: (f64, f64)) -> WellInfo {
    let r = m.restoring("x").unwrap();
    let r2 = r.clone();
    WellInfo::from_force(move |x| r.force(x), move |x| r2.potential(x), search, 1.0).unwrap()
}

#[test]
fn unstable_or_endless_steps_are_refused_by_flag() {
    let m = model("duffing-double-well");
    let m = m.to_str().unwrap();
    let out = tfs(&["basin", "--model", m, "--grid", "50x50", "--dt", "100"]);
    assert_refused(&out, &["--dt", "dt = 100", "stable only for dt below"]);
    let out = tfs(&["basin", "--model", m, "--grid", "200x200", "--dt", "1e-9"]);
    assert_refused(&out, &["--dt", "steps per start", "use dt ≥"]);
    let out = tfs(&["med", "--model", m, "--grid", "50x50", "--x", "-2:2"]);
    assert!(out.status.success());
}

#[test]
fn double_well_map_matches_every_start_and_draws_units() {
    let path = model("duffing-double-well");
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("basin.png");
    let out = json(&tfs(&[
        "basin",
        "--model",
        path.to_str().unwrap(),
        "--grid",
        "180x150",
        "--json",
        "--out",
        png.to_str().unwrap(),
    ]));
    let shares: Vec<f64> = serde_json::from_value(out["shares"].clone()).unwrap();
    assert_eq!(shares.len(), 2, "{out}");
    assert!(shares.iter().all(|&s| s > 0.3), "{shares:?}");
    assert_eq!(out["unsettled"], 0);
    assert!(out["integrated"].as_u64().unwrap() < 180 * 150);
    // The same map with every start integrated, through the library.
    let m = Model::from_path(&path).unwrap();
    let sys = m.compile().unwrap();
    let wells = wells_of(&m, (-1.0, 3.0));
    let mut cfg = BasinConfig::new(180, 150, (0.0, 2.0), (-3.0, 3.0));
    cfg.method = Method::EveryCell;
    let every = basin_sdof(&sys, &wells, &cfg, None).unwrap();
    cfg.method = Method::Refined;
    let refined = basin_sdof(&sys, &wells, &cfg, None).unwrap();
    assert_eq!(refined.shares, shares);
    assert!(compare(&every, &refined).unwrap().error < 0.005);
    let svg = std::fs::read_to_string(dir.path().join("basin.svg")).unwrap();
    assert!(svg.contains("length unit)") && svg.contains("length unit / s)"));
}

#[test]
fn med_is_the_scalar_paths_med() {
    let path = model("table1-60db");
    let out = json(&tfs(&[
        "med",
        "--model",
        path.to_str().unwrap(),
        "--grid",
        "120x120",
        "--json",
    ]));
    let m = Model::from_path(&path).unwrap();
    let sys = m.compile().unwrap();
    let wells = wells_of(&m, (-1.0, 3.0));
    let mut cfg = BasinConfig::new(120, 120, (0.0, 2.0), (-3.0, 3.0));
    cfg.method = Method::Scalar;
    let map = basin_sdof(&sys, &wells, &cfg, None).unwrap();
    let med = med_sdof(&sys, &wells, &map, &cfg, 0, 1).unwrap();
    for (key, want) in [("energy", med.energy), ("x0", med.x0), ("v0", med.v0)] {
        let got = out[key].as_f64().unwrap();
        assert_eq!(got, want, "{key}: CLI {got} vs scalar path {want}");
    }
}
