//! Rig measurements through the binary (issue #11): bad input that real acquisitions produce (a
//! gap in time, a clipped channel, a dead input channel) is refused with one line naming the file
//! and the column; per-channel DC offsets are handled as `--offsets` says and the trace shows it;
//! `compare` reports the error in the record's own units.

mod common;
use common::assert_fails;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tfs::data::{Record, write_csv};
use tfs::dynamics::{SimulateOptions, simulate_model_on_record};
use tfs::library::Model;
use tfs::signal::noise::add_noise_seeded;
use tfs::signal::{Excitation, Multisine, NoiseKind};

const DT: f64 = 1e-3;
/// DC offsets of the displacement and input channels (volts).
const OFFSETS: (f64, f64) = (0.31, -0.12);

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .expect("the tfs binary runs")
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// `x'' = −ω² x − 2ζω x' − k3 x³ + g u` (100 Hz, ζ = 0.03) in volt units; `k3 = 0` is linear.
fn rig_model(k3: f64, g: f64) -> Model {
    let w = 2.0 * std::f64::consts::PI * 100.0;
    let json = format!(
        r#"{{"format":"tfs-model/1","dofs":["x"],"inputs":["u"],"equations":[{{"dof":"x","terms":[{{"term":"x","coef":{}}},{{"term":"x'","coef":{}}},{{"term":"x^3","coef":{}}},{{"term":"u","coef":{g}}}]}}],"method":"truth"}}"#,
        -w * w,
        -0.06 * w,
        -k3
    );
    Model::from_json_str(&json).unwrap()
}

/// A rig record: the model simulated from rest under a multisine (10 samples per resonance
/// period), 60 dB noise on both channels, `x ↦ scale·x + off.0`, `u ↦ u + off.1`.
fn rig_record(model: &Model, n: usize, seed: u64, scale: f64, off: (f64, f64)) -> Record {
    let ms = Multisine::new(5.0, 200.0, 150, 1.0, n as f64 * DT, 0.2, seed).unwrap();
    let u: Vec<f64> = (0..n).map(|k| ms.value(k as f64 * DT)).collect();
    let t: Vec<f64> = (0..n).map(|k| k as f64 * DT).collect();
    let clean = Record::new(
        "gen",
        t.clone(),
        vec![("x".into(), vec![0.0; n]), ("u".into(), u.clone())],
    )
    .unwrap();
    let tr = simulate_model_on_record(model, &clean, &SimulateOptions::default()).unwrap();
    let x = add_noise_seeded(&tr.x[0], 60.0, NoiseKind::White, seed).unwrap();
    let um = add_noise_seeded(&u, 60.0, NoiseKind::White, seed + 1000).unwrap();
    Record::new(
        "rig",
        t,
        vec![
            ("x".into(), x.iter().map(|v| scale * v + off.0).collect()),
            ("u".into(), um.iter().map(|v| v + off.1).collect()),
        ],
    )
    .unwrap()
}

fn write(dir: &Path, name: &str, r: &Record) -> PathBuf {
    let p = dir.join(name);
    write_csv(&p, r).unwrap();
    p
}

/// `t,x,u` text of `n` rows with the given column functions of the sample index.
fn csv_text(
    n: usize,
    skip: std::ops::Range<usize>,
    x: impl Fn(usize) -> f64,
    u: impl Fn(usize) -> f64,
) -> String {
    let mut out = String::from("t,x,u\n");
    for k in (0..n).filter(|k| !skip.contains(k)) {
        out.push_str(&format!("{},{},{}\n", k as f64 * DT, x(k), u(k)));
    }
    out
}

fn identify_sindy(file: &Path, extra: &[&str]) -> Output {
    let f = s(file);
    let mut args = vec!["identify", &f, "--method", "sindy", "--library", "x, x', u"];
    args.extend_from_slice(extra);
    tfs(&args)
}

fn wave(k: usize) -> f64 {
    (0.21 * k as f64).sin() + 0.3 * (0.057 * k as f64).cos()
}

#[test]
fn gap_in_time_names_the_row_the_time_and_the_expected_step() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("gap.csv");
    // Samples 200..205 are missing: the row after the gap is sample 205 on line 202.
    std::fs::write(&p, csv_text(512, 200..205, wave, |k| wave(k + 7))).unwrap();
    assert_fails(
        &identify_sindy(&p, &[]),
        &[
            "gap.csv",
            "row 202",
            "column 't'",
            "gap",
            "t = 0.205",
            "1.000000e-3",
        ],
    );
}

#[test]
fn rounded_timestamps_are_regridded_with_a_warning() {
    // 3 kHz written with 4 decimals (steps 0.0003 / 0.0004): accepted, put back on the grid.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("daq.csv");
    let mut text = String::from("t,x,u\n");
    for k in 0..1500 {
        text.push_str(&format!(
            "{:.4},{},{}\n",
            k as f64 / 3000.0,
            wave(k),
            wave(k + 7)
        ));
    }
    std::fs::write(&p, text).unwrap();
    let out = identify_sindy(&p, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.starts_with("warning: ") && err.contains("daq.csv") && err.contains("rounded"),
        "{err}"
    );
}

#[test]
fn clipped_displacement_is_refused_then_accepted_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("clip.csv");
    // The sensor saturates at +1.0 V: the tops of 1.4·wave are flat.
    std::fs::write(
        &p,
        csv_text(512, 0..0, |k| (1.4 * wave(k)).min(1.0), |k| wave(k + 7)),
    )
    .unwrap();
    assert_fails(
        &identify_sindy(&p, &[]),
        &[
            "clip.csv",
            "column 'x'",
            "clipped",
            "maximum",
            "--clipped warn",
        ],
    );
    let out = identify_sindy(&p, &["--clipped", "warn"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.starts_with("warning: ") && err.contains("column 'x'") && err.contains("clipped"),
        "{err}"
    );
    let out = identify_sindy(&p, &["--clipped", "allow"]);
    assert!(out.status.success() && out.stderr.is_empty());
}

#[test]
fn clipped_input_channel_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("uclip.csv");
    std::fs::write(
        &p,
        csv_text(512, 0..0, wave, |k| (2.0 * wave(k + 7)).max(-1.5)),
    )
    .unwrap();
    assert_fails(
        &identify_sindy(&p, &[]),
        &["uclip.csv", "column 'u'", "clipped", "minimum"],
    );
}

#[test]
fn constant_input_column_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dead.csv");
    std::fs::write(&p, csv_text(512, 0..0, wave, |_| 0.25)).unwrap();
    assert_fails(
        &identify_sindy(&p, &[]),
        &[
            "dead.csv",
            "column 'u'",
            "constant",
            "nothing about its coefficient",
        ],
    );
}

#[test]
fn offsets_are_removed_by_default_for_a_force_input_and_the_trace_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let truth = rig_model(3.0e4, 8.0e4);
    let rec = rig_record(&truth, 8192, 3, 1.0, OFFSETS);
    let (mx, mu) = (
        mean(rec.column("x").unwrap()),
        mean(rec.column("u").unwrap()),
    );
    let train = write(dir.path(), "train.csv", &rec);
    let model = dir.path().join("m.json");
    let v = json_of(&tfs(&[
        "identify",
        &s(&train),
        "--library",
        "x, x^3, x', u",
        "--out",
        &s(&model),
        "--json",
    ]));
    let off = &v["offsets"];
    assert_eq!(off["mode"], "remove", "{off}");
    assert_eq!(off["requested"], "auto", "{off}");
    let removed = &off["per_record"][0]["removed"];
    // The offsets removed are the channel means (the sensor offsets plus the tiny response mean).
    assert!((removed["x"].as_f64().unwrap() - mx).abs() < 1e-12, "{off}");
    assert!((removed["u"].as_f64().unwrap() - mu).abs() < 1e-12, "{off}");
    assert!(
        (mx - OFFSETS.0).abs() < 0.02 && (mu - OFFSETS.1).abs() < 0.05,
        "{mx} {mu}"
    );
    // Identified in the centred coordinates, the cubic is the truth's (the offset on x would
    // otherwise need an x² term).
    let k3 = coef(&v, "x^3");
    assert!((k3 + 3.0e4).abs() < 0.05 * 3.0e4, "x^3 coefficient {k3}");
    // The model file remembers it, and `compare` treats held-out records the same way.
    let m = Model::from_path(&model).unwrap();
    assert_eq!(m.trace["offsets"]["mode"], "remove");
    let val = write(
        dir.path(),
        "val.csv",
        &rig_record(&truth, 4096, 5, 1.0, OFFSETS),
    );
    let auto = json_of(&tfs(&[
        "compare",
        "--model",
        &s(&model),
        &s(&val),
        "--json",
    ]));
    assert_eq!(auto["offsets"]["mode"], "remove", "{auto}");
    let explicit = json_of(&tfs(&[
        "compare",
        "--model",
        &s(&model),
        &s(&val),
        "--json",
        "--offsets",
        "remove",
    ]));
    let e_auto = auto["files"][0]["dofs"][0]["rms_error"].as_f64().unwrap();
    let e_explicit = explicit["files"][0]["dofs"][0]["rms_error"]
        .as_f64()
        .unwrap();
    assert_eq!(e_auto, e_explicit);
    // Keeping the offsets against a model fitted without them is warned about and is worse.
    let kept = tfs(&[
        "compare",
        "--model",
        &s(&model),
        &s(&val),
        "--json",
        "--offsets",
        "keep",
    ]);
    assert!(String::from_utf8_lossy(&kept.stderr).contains("warning: --offsets keep differs"));
    let e_kept = json_of(&kept)["files"][0]["dofs"][0]["rms_error"]
        .as_f64()
        .unwrap();
    assert!(e_kept > 2.0 * e_auto, "kept {e_kept} vs removed {e_auto}");
}

#[test]
fn constant_term_and_keep_modes_are_visible_in_the_trace() {
    let dir = tempfile::tempdir().unwrap();
    let rec = rig_record(&rig_model(0.0, 8.0e4), 4096, 4, 1.0, OFFSETS);
    let train = write(dir.path(), "lin.csv", &rec);
    let run = |mode: &str| {
        json_of(&tfs(&[
            "identify",
            &s(&train),
            "--library",
            "x, x', u",
            "--offsets",
            mode,
            "--json",
        ]))
    };
    let v = run("constant-term");
    assert_eq!(v["offsets"]["mode"], "constant-term");
    assert_eq!(v["offsets"]["constant_term_added"], true);
    let lib = v["trace"]["dofs"][0]["library"].as_array().unwrap();
    assert!(lib.iter().any(|t| t == "1"), "library {lib:?}");
    let v = run("keep");
    assert_eq!(v["offsets"]["mode"], "keep");
    let means = &v["offsets"]["per_record"][0]["mean"];
    assert!((means["x"].as_f64().unwrap() - mean(rec.column("x").unwrap())).abs() < 1e-12);
}

#[test]
fn base_excitation_keeps_offsets_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("t,x,xb_acc\n");
    for k in 0..1024 {
        text.push_str(&format!(
            "{},{},{}\n",
            k as f64 * DT,
            2.0 + wave(k),
            wave(k + 3)
        ));
    }
    let p = dir.path().join("base.csv");
    std::fs::write(&p, text).unwrap();
    let v = json_of(&tfs(&[
        "identify",
        &s(&p),
        "--method",
        "sindy",
        "--library",
        "x, x', xb_acc",
        "--json",
    ]));
    assert_eq!(v["offsets"]["mode"], "keep", "{}", v["offsets"]);
}

/// `compare` reports the RMS error in the record's units: rescaling the record (and the model's
/// input gain with it) by 1000 leaves R-MSE unchanged and multiplies the RMS error by 1000; and
/// RMS error² = R-MSE · mean(x²) on the record as used.
#[test]
fn compare_reports_rms_error_in_record_units() {
    let dir = tempfile::tempdir().unwrap();
    let truth = rig_model(3.0e4, 8.0e4);
    // A deliberately wrong (linear) model so that the error is not noise only.
    let wrong = |g: f64| {
        let mut m = rig_model(0.0, g);
        m.equations[0].terms.retain(|t| t.term.to_string() != "x^3");
        m
    };
    let rec = rig_record(&truth, 4096, 9, 1.0, (0.0, 0.0));
    let big = rig_record(&truth, 4096, 9, 1000.0, (0.0, 0.0));
    let (p1, p2) = (
        write(dir.path(), "v1.csv", &rec),
        write(dir.path(), "v2.csv", &big),
    );
    let (m1, m2) = (dir.path().join("w1.json"), dir.path().join("w2.json"));
    wrong(8.0e4).write_path(&m1).unwrap();
    wrong(8.0e7).write_path(&m2).unwrap();
    let score = |m: &Path, p: &Path| {
        let v = json_of(&tfs(&["compare", "--model", &s(m), &s(p), "--json"]));
        let d = &v["files"][0]["dofs"][0];
        (
            d["r_mse"].as_f64().unwrap(),
            d["rms_error"].as_f64().unwrap(),
        )
    };
    let (r1, e1) = score(&m1, &p1);
    let (r2, e2) = score(&m2, &p2);
    assert!(r1 > 1e-3, "the wrong model should show an error: {r1}");
    assert!((r2 - r1).abs() <= 1e-6 * r1, "R-MSE {r1} vs {r2}");
    assert!((e2 / e1 - 1000.0).abs() <= 1e-3, "RMS error {e1} vs {e2}");
    // R-MSE is on the variance (mean removed); Appendix B's ratio over the mean square beside it.
    let x = rec.column("x").unwrap();
    let m = mean(x);
    let var = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64;
    assert!(
        (e1 * e1 - r1 * var).abs() <= 1e-9 * e1 * e1,
        "{e1}² vs {r1}·{var}"
    );
    let v = json_of(&tfs(&["compare", "--model", &s(&m1), &s(&p1), "--json"]));
    let rb = v["files"][0]["dofs"][0]["r_mse_mean_square"]
        .as_f64()
        .unwrap();
    let ms = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
    assert!(
        (e1 * e1 - rb * ms).abs() <= 1e-9 * e1 * e1,
        "{e1}² vs {rb}·{ms}"
    );
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

fn coef(v: &serde_json::Value, term: &str) -> f64 {
    v["model"]["equations"][0]["terms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["term"] == term)
        .and_then(|t| t["coef"].as_f64())
        .unwrap_or(0.0)
}
