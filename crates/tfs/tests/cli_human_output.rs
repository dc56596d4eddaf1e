//! Human output and help: numbers to a few significant digits (no 16-digit floats), figures where
//! `--plots` says, negative numbers accepted where they are values, and help that lists only
//! what a command accepts.

use std::process::{Command, Output};

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).to_string()
}

/// The longest run of digits after a decimal point in `s`.
fn longest_fraction(s: &str) -> usize {
    let b = s.as_bytes();
    let mut best = 0;
    for (i, c) in b.iter().enumerate() {
        if *c == b'.' && i > 0 && b[i - 1].is_ascii_digit() {
            let n = b[i + 1..].iter().take_while(|c| c.is_ascii_digit()).count();
            best = best.max(n);
        }
    }
    best
}

#[test]
fn kresling_prints_short_numbers_and_writes_its_figures_into_plots() {
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("cell");
    let o = tfs(&["kresling", "--plots", &plots.display().to_string()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = text(&o);
    assert!(out.contains("stable states h: "), "{out}");
    assert!(longest_fraction(&out) <= 5, "long numbers in: {out}");
    for f in ["potential.svg", "potential.png", "force.svg", "force.png"] {
        assert!(plots.join(f).exists(), "{f} missing; output: {out}");
    }
    // the older prefix form still works
    let prefix = dir.path().join("k");
    let o = tfs(&["kresling", "--plot", &prefix.display().to_string()]);
    assert!(o.status.success());
    assert!(dir.path().join("k-force.png").exists());
}

#[test]
fn help_opens_with_what_tfs_does_and_lists_only_accepted_values() {
    let o = tfs(&["--help"]);
    let h = text(&o);
    assert!(!h.starts_with("tfs: tfs"), "{h}");
    assert!(
        h.lines().next().unwrap().contains("equations of motion"),
        "{h}"
    );
    for cmd in ["compare", "diagnose", "refit"] {
        let h = text(&tfs(&[cmd, "--help"]));
        assert!(h.contains("--offsets"), "{cmd}: {h}");
        assert!(
            !h.contains("constant-term"),
            "{cmd} lists constant-term: {h}"
        );
    }
    assert!(text(&tfs(&["identify", "--help"])).contains("constant-term"));
    let h = text(&tfs(&["simulate", "chain", "--help"]));
    assert!(h.contains("20,28.5") && !h.contains("20 28.5"), "{h}");
}

#[test]
fn a_negative_snr_is_a_value_not_a_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("noisy.csv");
    let o = tfs(&[
        "simulate",
        "kresling",
        "--snr-db",
        "-10",
        "--duration",
        "10",
        "--out",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t = text(&o);
    assert!(
        t.contains("SNR -10 dB") && t.contains("10.000 times"),
        "{t}"
    );
    assert!(out.exists());
}

const TRAIN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../fixtures/kresling-30db-train-1.csv"
);

#[test]
fn a_missing_dof_column_and_a_velocity_spelled_xdot_are_named() {
    let o = tfs(&["identify", TRAIN, "--dofs", "y"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("--dofs y") && e.contains("no column 'y'"), "{e}");
    let o = tfs(&["identify", TRAIN, "--library", "x^1..3, xdot, xb_acc"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("'xdot'") && e.contains("written x'"), "{e}");
}
