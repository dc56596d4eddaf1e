//! The pinned PySINDy environment and its runs on the same CSV files.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, anyhow, bail};
use serde_json::{Value, json};
use tfs::data::Record;
use tfs::dynamics::{SimulateOptions, rmse_ratio, simulate_model_on_record};
use tfs::library::Model;

use super::{PeersArgs, num};

/// Folder of the Python script and requirements.
pub(super) fn peers_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers")
}

/// Creates (once) the `--venv` environment with the pinned requirements; returns its Python.
pub(super) fn venv(args: &PeersArgs) -> Result<PathBuf> {
    let dir = &args.venv;
    let py = dir.join("bin").join("python");
    let req = peers_dir().join("requirements.txt");
    let stamp = dir.join(".tfs-requirements");
    let want =
        std::fs::read_to_string(&req).with_context(|| format!("reading {}", req.display()))?;
    if py.exists() && std::fs::read_to_string(&stamp).is_ok_and(|s| s == want) {
        return Ok(py);
    }
    if !py.exists() {
        eprintln!("creating {} …", dir.display());
        if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {} for --venv", parent.display()))?;
        }
        let st = Command::new(&args.python)
            .args(["-m", "venv"])
            .arg(dir)
            .status()
            .with_context(|| {
                format!(
                    "running '{} -m venv'; install Python 3 with venv or pass --no-python",
                    args.python
                )
            })?;
        if !st.success() {
            bail!(
                "'{} -m venv {}' failed ({st}); install python3-venv or pass --no-python",
                args.python,
                dir.display()
            );
        }
    }
    eprintln!("installing {} …", req.display());
    let st = Command::new(&py)
        .args(["-m", "pip", "install", "-q", "-r"])
        .arg(&req)
        .status()
        .context("running pip in the virtual environment")?;
    if !st.success() {
        bail!(
            "pip install -r {} failed ({st}); check network access to PyPI or pass --no-python",
            req.display()
        );
    }
    tfs::data::write_atomic(&stamp, want)?;
    Ok(py)
}

/// One method's result: name, (model, fit seconds) or failure text, selection details.
pub(super) type Fit = (String, std::result::Result<(Model, f64), String>, Value);

/// Runs the PySINDy script on `data`; it writes candidate models (one per setting of its grid)
/// and `index.json`. For each variant, the candidate with the lowest test R-MSE is kept (the
/// oracle: the choice uses the test record).
pub(super) fn pysindy(
    py: &Path,
    data: &Path,
    models_dir: &Path,
    test: &Record,
    clean_test: &[f64],
) -> Result<Vec<Fit>> {
    let out = models_dir.join("pysindy");
    std::fs::create_dir_all(&out)?;
    let script = peers_dir().join("run_pysindy.py");
    let st = Command::new(py)
        .arg(&script)
        .arg("--data")
        .arg(data)
        .arg("--out")
        .arg(&out)
        .status()
        .with_context(|| format!("running {}", script.display()))?;
    if !st.success() {
        bail!("{} failed ({st})", script.display());
    }
    oracle_pick(&out, test, clean_test)
}

/// For each variant of the script's `index.json` in `out`, the candidate with the lowest test
/// R-MSE (the oracle); a candidate whose model file cannot be read (a threshold that removed
/// every term) is listed in the grid with its reason and passed over.
fn oracle_pick(out: &Path, test: &Record, clean_test: &[f64]) -> Result<Vec<Fit>> {
    let idx_path = out.join("index.json");
    let idx: Value = serde_json::from_str(
        &std::fs::read_to_string(&idx_path)
            .with_context(|| format!("reading {}", idx_path.display()))?,
    )
    .with_context(|| format!("parsing {}", idx_path.display()))?;
    let mut fits = Vec::new();
    for (variant, name) in [("weak", "PySINDy weak"), ("classical", "PySINDy classical")] {
        let cands = idx
            .get(variant)
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        let mut best: Option<(f64, Model, f64, Value)> = None;
        let mut tried = Vec::new();
        for c in cands {
            let file = c
                .get("file")
                .and_then(Value::as_str)
                .ok_or_else(|| anyhow!("{}: candidate without 'file'", idx_path.display()))?;
            let secs = c
                .get("fit_seconds")
                .and_then(Value::as_f64)
                .unwrap_or(f64::NAN);
            // A candidate whose threshold removed every term is a setting that failed, not a
            // failed run: it is listed with its reason and the grid goes on.
            let model = match Model::from_path(out.join(file)) {
                Ok(m) => m,
                Err(e) => {
                    tried.push(json!({"params": c.get("params"), "test_r_mse": null,
                        "failure": format!("{e}")}));
                    continue;
                }
            };
            let r = simulate_model_on_record(&model, test, &SimulateOptions::default())
                .map_err(anyhow::Error::from)
                .and_then(|tr| Ok(rmse_ratio(clean_test, &tr.x[0])?))
                .unwrap_or(f64::INFINITY);
            let r = if r.is_finite() { r } else { f64::INFINITY };
            tried.push(json!({"params": c.get("params"), "test_r_mse": num(r)}));
            if best.as_ref().is_none_or(|b| r < b.0) {
                best = Some((
                    r,
                    model,
                    secs,
                    c.get("params").cloned().unwrap_or(Value::Null),
                ));
            }
        }
        match best {
            Some((_, model, secs, params)) => fits.push((
                name.to_string(),
                Ok((model, secs)),
                json!({"chosen": params, "grid": tried, "rule": "lowest test R-MSE (oracle)"}),
            )),
            None => fits.push((
                name.to_string(),
                Err(format!("the script wrote no {variant} candidates")),
                Value::Null,
            )),
        }
    }
    Ok(fits)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs::library::{Equation, ModelTerm, Term};

    /// One PySINDy candidate with no terms (its model file is refused) does not abort the run:
    /// the oracle chooses among the others and lists the empty one with its reason.
    #[test]
    fn an_empty_candidate_is_a_failed_setting_not_a_failed_run() {
        let dir = tempfile::tempdir().unwrap();
        let dofs = ["x".to_string()];
        let term = |t: &str| Term::parse(t, &dofs).unwrap();
        let model = Model::new(
            dofs.to_vec(),
            vec![Equation {
                dof: "x".into(),
                terms: vec![
                    ModelTerm::new(term("x"), -1.0),
                    ModelTerm::new(term("x'"), -0.1),
                    ModelTerm::new(term("xb_acc"), -1.0),
                ],
            }],
            "PySINDy weak",
        )
        .unwrap();
        model.write_path(dir.path().join("good.json")).unwrap();
        // The same file with every term removed, as the script writes a threshold that kept none.
        let mut empty: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("good.json")).unwrap())
                .unwrap();
        empty["equations"][0]["terms"] = json!([]);
        std::fs::write(dir.path().join("empty.json"), empty.to_string()).unwrap();
        let idx = json!({"weak": [
            {"file": "empty.json", "params": {"H": 2.0}, "fit_seconds": 0.1},
            {"file": "good.json", "params": {"H": 4.0}, "fit_seconds": 0.2},
        ], "classical": []});
        std::fs::write(dir.path().join("index.json"), idx.to_string()).unwrap();
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.01).collect();
        let u: Vec<f64> = t.iter().map(|t| (1.3 * t).sin()).collect();
        let test = Record::new(
            "test",
            t.clone(),
            vec![
                ("x".into(), vec![0.0; t.len()]),
                ("xb_acc".into(), u.clone()),
            ],
        )
        .unwrap();
        let fits = oracle_pick(dir.path(), &test, &u).unwrap();
        let (name, weak, extra) = &fits[0];
        assert_eq!(name, "PySINDy weak");
        assert!(weak.is_ok(), "{weak:?}");
        assert_eq!(extra["chosen"]["H"], json!(4.0));
        let failure = extra["grid"][0]["failure"].as_str().unwrap();
        assert!(failure.contains("empty.json"), "{failure}");
        // No classical candidates: that variant fails and says so.
        assert!(fits[1].1.is_err());
    }
}
