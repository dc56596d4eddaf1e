//! Runs `xtask reproduce-paper --quick` into a temporary folder and checks the outputs: every
//! study present and error-free, the expected keys in `results.json` with sane ranges, and every
//! table and figure the report links to on disk.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

fn get<'a>(v: &'a Value, path: &str) -> &'a Value {
    let mut cur = v;
    for k in path.split('.') {
        cur = cur
            .get(k)
            .unwrap_or_else(|| panic!("results.json has no key '{path}' (missing '{k}')"));
    }
    cur
}

fn finite_nonneg(v: &Value, what: &str) -> f64 {
    let x = v
        .as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"));
    assert!(
        x.is_finite() && x >= 0.0,
        "{what} = {x} must be finite and ≥ 0"
    );
    x
}

fn fraction(v: &Value, what: &str) {
    let x = finite_nonneg(v, what);
    assert!(x <= 1.0, "{what} = {x} must be a share in [0, 1]");
}

#[test]
fn quick_reproduction_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("paper");
    let status = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["reproduce-paper", "--quick", "--out"])
        .arg(&out)
        .arg("--peers")
        .arg(dir.path().join("no-peers-run"))
        .status()
        .expect("xtask runs");
    let text = std::fs::read_to_string(out.join("results.json")).expect("results.json written");
    let r: Value = serde_json::from_str(&text).unwrap();
    let failed = get(&r, "failed_studies").as_array().unwrap();
    assert!(failed.is_empty(), "studies failed: {failed:?}");
    // The exit status says whether a check failed: 0 exactly when every check passed.
    let failed_checks: Vec<&Value> = get(&r, "summary")
        .as_array()
        .unwrap()
        .iter()
        .filter(|row| row["within_tolerance"] == Value::Bool(false))
        .collect();
    assert_eq!(
        status.success(),
        failed_checks.is_empty(),
        "xtask exited with {status}; failed checks: {failed_checks:?}"
    );
    assert_eq!(get(&r, "quick"), &Value::Bool(true));

    for key in [
        "s1_white",
        "s2_pink",
        "s3_chain",
        "s4_table_b1",
        "s5_experiment",
    ] {
        let s = get(&r, &format!("studies.{key}"));
        assert!(
            s.get("error").is_some_and(Value::is_null),
            "{key}: {:?}",
            s.get("error")
        );
        finite_nonneg(get(s, "seconds"), &format!("{key}.seconds"));
    }
    // Study 6 is a note until `cargo xtask peers` has been run.
    assert_eq!(
        get(&r, "studies.s6_peers.available"),
        &Value::Bool(false),
        "no peers run was given"
    );
    // Study 1: Table 1 and BOA errors.
    for snr in ["60db", "30db"] {
        for c in ["zeta", "alpha", "beta", "gamma"] {
            let v = get(&r, &format!("studies.s1_white.table1_{snr}.ours.{c}"));
            assert!(v.is_number(), "table1_{snr}.ours.{c} = {v}");
        }
    }
    fraction(
        get(&r, "studies.s1_white.white_60db.boa_error"),
        "white 60 dB BOA error",
    );
    for path in [
        "studies.s1_white.white_30db.boa_error",
        "studies.s2_pink.pink_30db.boa_error",
        "studies.s3_chain.chain_60db.boa_error",
        "studies.s3_chain.chain_30db.boa_error",
        "studies.s5_experiment.med.model_boa_error",
    ] {
        let v = get(&r, path);
        if !v.is_null() {
            fraction(v, path);
        }
    }
    finite_nonneg(get(&r, "studies.s1_white.truth.med.energy"), "truth MED");
    assert!(
        get(&r, "studies.s1_white.fig3c_kappa")
            .as_array()
            .is_some_and(|a| !a.is_empty())
    );
    assert!(
        get(&r, "studies.s1_white.fig3d_pruning")
            .as_array()
            .is_some_and(|a| !a.is_empty())
    );
    // Study 4: Table B1.
    finite_nonneg(get(&r, "studies.s4_table_b1.tfs.test_r_mse"), "T-F-S R-MSE");
    let s = get(&r, "studies.s4_table_b1.sindy");
    if s["blew_up"] != Value::Bool(true) {
        finite_nonneg(&s["test_r_mse"], "classical SINDy R-MSE");
    }
    for m in ["tfs", "sindy"] {
        assert!(
            get(&r, &format!("studies.s4_table_b1.{m}.rows"))
                .as_u64()
                .unwrap()
                > 0
        );
        assert!(
            get(&r, &format!("studies.s4_table_b1.{m}.cols"))
                .as_u64()
                .unwrap()
                > 0
        );
        finite_nonneg(
            get(&r, &format!("studies.s4_table_b1.{m}.seconds")),
            "identification time",
        );
    }
    // Study 5.
    let correct = get(&r, "studies.s5_experiment.deployment.correct")
        .as_u64()
        .unwrap();
    assert!(correct <= 8);
    assert_eq!(
        get(&r, "studies.s5_experiment.deployment.tests")
            .as_array()
            .unwrap()
            .len(),
        8
    );
    finite_nonneg(
        get(&r, "studies.s5_experiment.fig9.resonance_error"),
        "resonance error",
    );
    // Summary rows.
    let summary = get(&r, "summary").as_array().unwrap();
    assert!(summary.len() >= 15, "only {} summary rows", summary.len());
    for row in summary {
        for k in [
            "metric",
            "truth",
            "paper",
            "ours",
            "within_tolerance",
            "rule",
        ] {
            assert!(row.get(k).is_some(), "summary row without '{k}': {row}");
        }
    }
    // Files: reports, and every figure and table they link to.
    for f in [
        "report.md",
        "index.html",
        "tables/summary.csv",
        "tables/table1.csv",
        "tables/table2.csv",
        "tables/table3.csv",
        "tables/table_b1.csv",
    ] {
        assert_nonempty(&out.join(f));
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let mut figures = 0;
    for part in md.split("](figures/").skip(1) {
        let name = &part[..part.find(')').unwrap()];
        assert_nonempty(&out.join("figures").join(name));
        assert!(
            html.contains(&format!("figures/{name}")),
            "index.html lacks {name}"
        );
        figures += 1;
    }
    assert!(figures >= 20, "only {figures} figure links in report.md");
    for stem in [
        "fig3c_kappa",
        "fig3d_pruning",
        "fig3e_spectrum",
        "fig3f_mu_sigma",
        "fig4a_potential",
        "fig4b_force",
        "fig4c_boa_truth",
        "fig5a_potential",
        "fig7a_force_cell1",
        "fig7c_boa_truth",
        "fig9c_frequency_response",
        "fig10_test1",
    ] {
        assert_nonempty(&out.join("figures").join(format!("{stem}.png")));
        assert_nonempty(&out.join("figures").join(format!("{stem}.svg")));
    }
    // Every figure: no tick label that is a rounding residue of zero (|v| < 1e-12; none of
    // these axes spans so little), and an axis label with a unit in parentheses.
    for e in std::fs::read_dir(out.join("figures")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().and_then(|x| x.to_str()) != Some("svg") {
            continue;
        }
        let svg = std::fs::read_to_string(&p).unwrap();
        let texts: Vec<&str> = svg
            .split("<text")
            .skip(1)
            .filter_map(|t| Some(&t[t.find('>')? + 1..t.find("</text>")?]))
            .collect();
        for v in texts.iter().filter_map(|t| t.trim().parse::<f64>().ok()) {
            assert!(
                v == 0.0 || v.abs() >= 1e-12,
                "{}: tick label {v}",
                p.display()
            );
        }
        assert!(
            texts.iter().any(|t| t.contains('(') && t.contains(')')),
            "{}: no axis label with a unit: {texts:?}",
            p.display()
        );
    }
}

fn assert_nonempty(p: &Path) {
    let len = std::fs::metadata(p)
        .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        .len();
    assert!(len > 0, "{} is empty", p.display());
}
