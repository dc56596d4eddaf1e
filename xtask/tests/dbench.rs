//! Runs `xtask diagnose-bench` on a tiny configuration (one baseline, two hidden effects and
//! the two controls, one draw) and checks its outputs agree with each other: every case in
//! `cases.csv` and `results.json`, the confusion matrix holding every case that ran, the
//! headline counts equal to the cases' own verdicts; `--keep-records` writes every case's
//! records and a start model that is the one the case diagnosed.

use std::process::Command;

use serde_json::Value;

#[test]
fn tiny_diagnosis_benchmark_writes_consistent_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dbench");
    let kept = dir.path().join("kept");
    let run = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["diagnose-bench", "--quick", "--only", "duffing"])
        .args(["--effects", "offset,quadratic-damping", "--out"])
        .arg(&out)
        .arg("--keep-records")
        .arg(&kept)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "diagnose-bench failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("top-1 correct"), "{stdout}");
    assert!(stdout.contains("hidden \\ named first"), "{stdout}");

    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let cases = json["cases"].as_array().unwrap();
    // Two effects at 40 dB, one control noise-free and one at 40 dB.
    assert_eq!(cases.len(), 4);
    for c in cases {
        assert_eq!(c["status"], "ok", "case did not run: {c}");
    }
    let csv = std::fs::read_to_string(out.join("cases.csv")).unwrap();
    assert_eq!(csv.lines().count(), cases.len() + 1, "{csv}");

    let g = &json["summary"]["groups"][0];
    let counts: usize = g["confusion"]["counts"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap())
        .map(|v| v.as_u64().unwrap() as usize)
        .sum();
    assert_eq!(counts, 4, "every case once in the ≥40 dB matrix");
    assert_eq!(g["controls"], 2);

    // The headline's counts from the cases themselves.
    let single: Vec<&Value> = cases
        .iter()
        .filter(|c| c["spec"]["group"] == "single")
        .collect();
    let correct = single
        .iter()
        .filter(|c| c["rounds"][0]["top_effect"] == c["spec"]["hidden"][0])
        .count();
    assert_eq!(g["top1_correct"].as_u64().unwrap() as usize, correct);
    assert_eq!(g["top1_cases"].as_u64().unwrap() as usize, single.len());
    let alarms = cases
        .iter()
        .filter(|c| c["spec"]["group"] == "control" && !c["rounds"][0]["top"].is_null())
        .count();
    assert_eq!(g["false_alarms"].as_u64().unwrap() as usize, alarms);
    for f in ["report.md", "confusion.csv"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }

    // Every case's folder: the records as CSV and the start model the case diagnosed.
    let mut folders: Vec<_> = std::fs::read_dir(&kept)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    folders.sort();
    assert_eq!(folders.len(), cases.len(), "{folders:?}");
    for c in cases {
        let id = c["spec"]["id"].as_u64().unwrap();
        let prefix = format!("case{id:03}-duffing-");
        let f = folders
            .iter()
            .find(|p| {
                p.file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with(&prefix)
            })
            .unwrap_or_else(|| panic!("no folder for case {id}: {folders:?}"));
        for r in ["train0", "train1", "train2", "heldout"] {
            let rec = tfs::data::read_csv(f.join(format!("{r}.csv"))).unwrap();
            assert_eq!(rec.names(), ["x", "xb_acc"], "{r} in {}", f.display());
            assert!(rec.len() > 1000, "{r}: {} samples", rec.len());
        }
        let text = std::fs::read_to_string(f.join("start.json")).unwrap();
        let model = tfs::library::Model::from_json_str(&text).unwrap();
        assert_eq!(Some(model.equation_string().as_str()), c["start"].as_str());
    }
}
