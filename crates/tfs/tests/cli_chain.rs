//! A two-cell Kresling chain through the CLI, as README tells a user to run it: `tfs simulate
//! chain` with its default records (noise-free and at 30 dB), `tfs identify` on them (tied by
//! default for a chain, and with `--tie`; `--no-tie` never calls the clean data noisy), then `diagnose` finds the folded stop the polynomial
//! model lacks and `refit` with it gives a model that `compare` simulates on every record and
//! whose basins and minimum-energy deployment `basin` and `med` map on the paper's slice. The
//! identified cells are judged against the truss truth: cell 1 monostable, cell 2 bistable, each
//! stable state within 0.05 of the truth's.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tfs::library::Model;
use tfs::origami::{CellSpec, KreslingParams, SystemSpec, Truth, build_system};

/// The angles of the README's chain (`tfs simulate chain`'s default).
const GAMMA0: [f64; 2] = [20.0, 28.5];
/// How far an identified stable state may lie from the truth's.
const TOLERANCE: f64 = 0.05;

fn tfs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tfs"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let o = tfs(args);
    assert!(
        o.status.success(),
        "tfs {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `tfs simulate chain` with its defaults (plus `extra`) into `dir/name.csv`; the files written.
fn simulate(dir: &Path, name: &str, extra: &[&str]) -> Vec<String> {
    let out = dir.join(format!("{name}.csv")).display().to_string();
    let mut args = vec!["simulate", "chain", "--out", &out];
    args.extend_from_slice(extra);
    let text = ok(&args);
    assert!(text.contains("folded stop"), "{text}");
    let files: Vec<String> = text
        .lines()
        .filter_map(|l| l.strip_prefix("written: "))
        .map(str::to_string)
        .collect();
    assert!(files.len() >= 2, "{text}");
    files
}

/// The truss truth's stable states of each cell.
fn truth_states() -> Vec<Vec<f64>> {
    let cells = GAMMA0
        .iter()
        .map(|g| CellSpec {
            params: KreslingParams {
                gamma0_deg: *g,
                ..Default::default()
            },
            truth: Truth::Truss,
            ..Default::default()
        })
        .collect();
    let chain = build_system(&SystemSpec::Chain { cells }).unwrap();
    chain
        .cells()
        .iter()
        .map(|c| c.force_law().equilibria().0)
        .collect()
}

/// The stable states of each cell of a chain model on 0 < h ≤ 2: the zeros of the cell's
/// polynomial force per unit mass (`x1^k` in x1'', `(x2-x1)^k` in x2'') where it falls through 0.
fn model_states(path: &Path) -> Vec<Vec<f64>> {
    let model = Model::from_json_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let coefs = |dof: &str, var: &str| -> Vec<f64> {
        let eq = model.equations.iter().find(|e| e.dof == dof).unwrap();
        (0..=7)
            .map(|k| {
                let name = if k == 1 {
                    var.to_string()
                } else {
                    format!("{var}^{k}")
                };
                eq.terms
                    .iter()
                    .find(|t| t.term.to_string() == name)
                    .map_or(0.0, |t| t.coef)
            })
            .collect()
    };
    [coefs("x1", "x1"), coefs("x2", "(x2-x1)")]
        .iter()
        .map(|c| {
            let f = |h: f64| c.iter().rev().fold(0.0, |acc, a| acc * h + a);
            let n = 4000;
            let mut states = Vec::new();
            for i in 1..n {
                let (a, b) = (2.0 * i as f64 / n as f64, 2.0 * (i + 1) as f64 / n as f64);
                if f(a) > 0.0 && f(b) <= 0.0 {
                    states.push(0.5 * (a + b));
                }
            }
            states
        })
        .collect()
}

/// Identifies the chain from `files` (with `flags`) and checks the cells against the truth.
fn identify_and_judge(dir: &Path, files: &[String], flags: &[&str], name: &str) -> PathBuf {
    let model = dir.join(format!("{name}.json"));
    let m = model.display().to_string();
    let mut args = vec!["identify"];
    args.extend(files.iter().map(String::as_str));
    args.extend_from_slice(flags);
    args.extend_from_slice(&["--out", &m]);
    let o = tfs(&args);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{name}: {stderr}");
    assert!(
        stdout.contains("method: tfs-sindy-tied"),
        "{name}: {stdout}"
    );
    assert!(
        !stdout.contains("too noisy") && !stderr.contains("too noisy"),
        "{name}: {stdout}{stderr}"
    );
    let (want, got) = (truth_states(), model_states(&model));
    assert_eq!(want[0].len(), 1, "the truth's cell 1 is monostable");
    assert_eq!(want[1].len(), 2, "the truth's cell 2 is bistable");
    for (cell, (w, g)) in want.iter().zip(&got).enumerate() {
        assert_eq!(
            w.len(),
            g.len(),
            "{name}: cell {} has stable states {g:?}, the truth {w:?}",
            cell + 1
        );
        for (a, b) in w.iter().zip(g) {
            assert!(
                (a - b).abs() <= TOLERANCE,
                "{name}: cell {} stable state {b:.4} vs the truth's {a:.4}",
                cell + 1
            );
        }
    }
    model
}

#[test]
fn the_readme_chain_is_identified_from_the_cli_clean_and_at_30_db() {
    let dir = tempfile::tempdir().unwrap();
    let clean = simulate(dir.path(), "chain", &[]);
    // A chain is tied by default; `--tie` asks for the same fit.
    let model = identify_and_judge(dir.path(), &clean, &[], "clean");
    identify_and_judge(dir.path(), &clean, &["--tie"], "clean-tie");
    // Each equation on its own: clean data are never called noisy, whatever the verdict.
    let untied = dir.path().join("untied.json").display().to_string();
    let mut args = vec!["identify", "--no-tie", "--out", &untied];
    args.extend(clean.iter().map(String::as_str));
    let o = tfs(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(text.contains("method: tfs-sindy\n"), "{text}");
    assert!(!text.contains("too noisy"), "{text}");
    let noisy = simulate(dir.path(), "noisy", &["--snr-db", "30", "--seed", "1"]);
    identify_and_judge(dir.path(), &noisy, &[], "noisy");

    // The polynomial cells fall through the folded state where the records touch it: diagnose
    // names the stop, and the model refitted with it simulates every record.
    let m = model.display().to_string();
    let d = ok(&["diagnose", "--model", &m, &clean[clean.len() - 1]]);
    assert!(d.contains("missing effect: stop@"), "{d}");
    let refit = dir.path().join("stop.json").display().to_string();
    let mut args = vec![
        "refit", "--model", &m, "--add", "stop@x1", "--add", "stop@x2", "--out", &refit,
    ];
    args.extend(clean.iter().map(String::as_str));
    ok(&args);
    let mut args = vec!["compare", "--model", &refit];
    args.extend(clean.iter().map(String::as_str));
    let c = ok(&args);
    assert!(!c.contains("blew up"), "{c}");

    // Basins and the minimum-energy deployment of the chain, on the paper's slice.
    let png = dir.path().join("basin.png").display().to_string();
    let b = ok(&["basin", "--model", &refit, "--grid", "30x30", "--out", &png]);
    assert!(
        b.contains("cell 1: monostable") && b.contains("cell 2: bistable"),
        "{b}"
    );
    assert!(
        b.contains("basin of S1") && b.contains("basin of S2"),
        "{b}"
    );
    assert!(!b.contains("diverged"), "{b}");
    assert!(Path::new(&png).exists());
    let med = ok(&["med", "--model", &refit, "--grid", "30x30"]);
    assert!(
        med.contains("MED from S1") && med.contains("E_in = "),
        "{med}"
    );
    // Without the stop, starts that fall through the folded state are counted and explained.
    let b = ok(&["basin", "--model", &m, "--grid", "20x20"]);
    assert!(b.contains("cell 2: bistable"), "{b}");
}
