//! Table B1's PySINDy row: PySINDy 2.1's classical SINDy on the same training records, its
//! smoothing window and STLSQ threshold chosen on the last training record held out the same way
//! as ours (per window, the lowest BIC of the held-out equation error among fits with terms whose
//! model simulates that record; then the window whose choice simulates it best), then refitted
//! on every record with the chosen window and threshold.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, anyhow, bail};
use serde_json::Value;
use tfs::data::{Record, write_csv};
use tfs::library::Model;

use crate::common::sim_rmse;

/// Where the Python side comes from: `--no-python`, or the `--venv` folder to use.
pub enum PythonChoice {
    /// `--no-python`: PySINDy is not run.
    Off,
    /// The virtual environment with pysindy (used as it is; never created here).
    Venv(PathBuf),
}

/// PySINDy's classical fit and how it was chosen.
pub struct PySindyFit {
    /// The model refitted on every training record.
    pub model: Model,
    /// Wall time of that fit (median of five calls, in Python).
    pub seconds: f64,
    /// Savitzky–Golay window length (samples) chosen.
    pub window: usize,
    /// STLSQ threshold chosen (PySINDy's raw coefficient units).
    pub threshold: f64,
    /// R-MSE of the chosen candidate (fitted without the held-out record) simulated on it.
    pub held_out_r_mse: f64,
    /// Candidates fitted, and how many of them were simulated on the held-out record (per window
    /// from the lowest BIC up, until one simulates).
    pub tried: (usize, usize),
    /// PySINDy's version.
    pub version: String,
}

/// Runs PySINDy's classical SINDy on `train` (files under `dir`); `Ok(Err(why))` when Python or
/// PySINDy is not available, which the table says instead of failing.
pub fn run(
    choice: &PythonChoice,
    train: &[Record],
    dir: &Path,
) -> Result<std::result::Result<PySindyFit, String>> {
    let venv = match choice {
        PythonChoice::Off => return Ok(Err("not run (--no-python)".into())),
        PythonChoice::Venv(v) => v,
    };
    let py = venv.join("bin").join("python");
    if !py.exists() {
        return Ok(Err(format!(
            "not run: no Python environment at {} (make one with `cargo xtask peers`, or pass --venv DIR with pysindy 2.1 installed)",
            venv.display()
        )));
    }
    let probe = Command::new(&py)
        .args(["-c", "import pysindy"])
        .output()
        .with_context(|| format!("running {}", py.display()))?;
    if !probe.status.success() {
        return Ok(Err(format!(
            "not run: {} cannot import pysindy (install pysindy 2.1 there, or pass --venv DIR)",
            py.display()
        )));
    }
    let held = train.last().ok_or_else(|| anyhow!("no training record"))?;
    let data = dir.join("data");
    std::fs::create_dir_all(&data).with_context(|| format!("creating {}", data.display()))?;
    for (i, r) in train.iter().enumerate() {
        let col = |n: &str| {
            r.column(n)
                .map(<[f64]>::to_vec)
                .ok_or_else(|| anyhow!("record '{}' has no column '{n}'", r.source()))
        };
        let rec = Record::new(
            r.source(),
            r.t().to_vec(),
            vec![("x".into(), col("x")?), ("xb_acc".into(), col("xb_acc")?)],
        )?;
        write_csv(data.join(format!("train{}.csv", i + 1)), &rec)?;
    }
    let grid = dir.join("grid");
    let idx = script(&py, &data, &grid, &["--grid"])?;
    // Per window, the candidates with terms from the lowest held-out BIC up (ties: fewer terms).
    let mut by_window: Vec<(usize, Vec<Candidate>)> = Vec::new();
    let mut models = 0;
    for c in idx["models"].as_array().into_iter().flatten() {
        models += 1;
        let (file, w, thr) = entry(c)?;
        let k = c["terms"].as_u64().unwrap_or(0) as usize;
        if k == 0 {
            continue; // x'' = 0 is not a candidate (nor a model a tfs model file can hold)
        }
        let (Some(rss), Some(m)) = (c["held_out_rss"].as_f64(), c["held_out_rows"].as_f64()) else {
            bail!("{file}: no held-out equation error listed");
        };
        let bic = m * (rss.max(f64::MIN_POSITIVE) / m).ln() + k as f64 * m.ln();
        match by_window.iter_mut().find(|(ww, _)| *ww == w) {
            Some((_, v)) => v.push((bic, k, file, thr)),
            None => by_window.push((w, vec![(bic, k, file, thr)])),
        }
    }
    let mut simulated = 0;
    let mut best: Option<(f64, usize, f64)> = None;
    for (w, mut v) in by_window {
        v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (_, _, file, thr) in v {
            let m = Model::from_path(grid.join(file)).with_context(|| format!("reading {file}"))?;
            simulated += 1;
            match sim_rmse(&m, held, "x") {
                Ok((r, _)) if r.is_finite() => {
                    if best.is_none_or(|b| r < b.0) {
                        best = Some((r, w, thr));
                    }
                    break;
                }
                _ => continue,
            }
        }
    }
    let Some((held_out_r_mse, window, threshold)) = best else {
        return Ok(Err(format!(
            "no candidate of the {models} keeps a term and simulates the held-out record"
        )));
    };
    let fin = dir.join("final");
    let idx = script(
        &py,
        &data,
        &fin,
        &["--final", &window.to_string(), &threshold.to_string()],
    )?;
    let c = idx["models"]
        .get(0)
        .ok_or_else(|| anyhow!("{}: no final model listed", fin.display()))?;
    let (file, ..) = entry(c)?;
    if c["terms"].as_u64() == Some(0) {
        return Ok(Err(format!(
            "refit on every record at the chosen window {window} and threshold {threshold} kept no term"
        )));
    }
    let model = Model::from_path(fin.join(file)).with_context(|| format!("reading {file}"))?;
    Ok(Ok(PySindyFit {
        model,
        seconds: c["fit_seconds"].as_f64().unwrap_or(f64::NAN),
        window,
        threshold,
        held_out_r_mse,
        tried: (models, simulated),
        version: idx["pysindy"].as_str().unwrap_or_default().to_string(),
    }))
}

/// A grid candidate: (held-out BIC, terms, model file, threshold).
type Candidate<'a> = (f64, usize, &'a str, f64);

/// Runs the script with `args` into `out` and reads its `index.json`.
fn script(py: &Path, data: &Path, out: &Path, args: &[&str]) -> Result<Value> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("peers/pysindy_classical.py");
    let st = Command::new(py)
        .arg(&path)
        .arg("--data")
        .arg(data)
        .arg("--out")
        .arg(out)
        .args(args)
        .status()
        .with_context(|| format!("running {}", path.display()))?;
    if !st.success() {
        bail!("{} {} failed ({st})", path.display(), args.join(" "));
    }
    let idx = out.join("index.json");
    let text =
        std::fs::read_to_string(&idx).with_context(|| format!("reading {}", idx.display()))?;
    serde_json::from_str(&text).with_context(|| format!("parsing {}", idx.display()))
}

/// (file, window, threshold) of one listed model.
fn entry(c: &Value) -> Result<(&str, usize, f64)> {
    let file = c["file"]
        .as_str()
        .ok_or_else(|| anyhow!("a listed model without 'file'"))?;
    let w = c["params"]["window"]
        .as_u64()
        .ok_or_else(|| anyhow!("{file}: no window"))?;
    let thr = c["params"]["threshold"]
        .as_f64()
        .ok_or_else(|| anyhow!("{file}: no threshold"))?;
    Ok((file, w as usize, thr))
}
