//! `tfs simulate`: the README's chain command runs (a chain defaults to the truss force with its
//! folded stop), and a surrogate chain that runs away says why and what to do, once.

use std::process::{Command, Output};

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn readme_chain_command_runs_on_the_truss_truth() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("chain.csv");
    let o = tfs(&[
        "simulate",
        "chain",
        "--gamma0",
        "20,28.5",
        "--excitation",
        "sweep:0.05:1.5:4",
        "--duration",
        "30",
        "--out",
        &out.display().to_string(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["meta"]["truth"], "truss,truss", "{v}");
    assert!(out.exists());
}

#[test]
fn runaway_surrogate_chain_names_the_way_out() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("chain.csv");
    let o = tfs(&[
        "simulate",
        "chain",
        "--truth",
        "surrogate",
        "--excitation",
        "sweep:0.05:1.5:4",
        "--duration",
        "30",
        "--out",
        &out.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--truth truss") && err.contains("blew up"),
        "{err}"
    );
    // The integrator's message appears once, not once per level of the error chain.
    assert_eq!(err.matches("blew up").count(), 1, "{err}");
}
