//! The peers comparison's outputs: per-draw tables and figures, and the summary over draws.

use std::path::Path;

use anyhow::Result;
use serde_json::{Value, json};
use tfs::plot::{Figure, LineChart, Series};

use super::{LOG_FLOOR_PCT, RAMP, TEST, TRAIN, TRUTH_ROW};

/// A row's error `key` as a number for ranking: failures (and missing values) rank worst.
pub(super) fn rank_value(r: &Value, key: &str) -> f64 {
    r.get(key).and_then(Value::as_f64).unwrap_or(f64::INFINITY)
}

/// The median of `v` (upper median for an even count; infinite entries are failures).
pub(super) fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s.get(s.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Percent with "failed" for an infinite (failed) value.
pub(super) fn pct_or_failed(v: f64) -> String {
    if v.is_finite() {
        pct(v)
    } else {
        "failed".into()
    }
}

/// One (case, method) cell of a `--draws` run with its row from every draw (if any).
type DrawCell<'a> = ((String, String), Vec<Option<&'a Value>>);

/// `peers_draws.md` and `peers_draws.json` of a `--draws N` run: per case and method the median
/// and range of every error over the draws, and per case in how many draws each tfs variant is
/// at or below the oracle-chosen PySINDy weak form.
pub(super) fn write_draws_summary(out: &Path, draws: &[Vec<Value>], quick: bool) -> Result<()> {
    let n = draws.len();
    let key_of = |r: &Value| {
        let s = |k: &str| r.get(k).and_then(Value::as_str).unwrap_or("").to_string();
        (s("case"), s("method"))
    };
    // Cells in first-seen order, each with its row from every draw that has one.
    let mut cells: Vec<DrawCell<'_>> = Vec::new();
    for (d, rows) in draws.iter().enumerate() {
        for r in rows {
            let k = key_of(r);
            let i = match cells.iter().position(|(c, _)| *c == k) {
                Some(i) => i,
                None => {
                    cells.push((k, vec![None; n]));
                    cells.len() - 1
                }
            };
            cells[i].1[d] = Some(r);
        }
    }
    let values = |rows: &[Option<&Value>], key: &str| -> Vec<f64> {
        rows.iter()
            .map(|r| r.map_or(f64::INFINITY, |r| rank_value(r, key)))
            .collect()
    };
    let mut md = format!(
        "# tfs vs PySINDy over {n} noise draws\n\nThe cases of `peers.md`{} with noise realisations 0..{n} (draw 0 is `peers.md`, draw K is `draw-K/peers.md`). Each cell: the median over the draws (the upper one for an even count) and the range; a failed fit or score counts as the worst value. PySINDy's settings are still chosen per draw by the lowest test R-MSE (an oracle); tfs chooses its own from the training records.\n\n| case | method | force error: median (range) | BOA error: median (range) | fit time (s), median |\n|---|---|---|---|---|\n",
        if quick { " (--quick)" } else { "" }
    );
    let range = |v: &[f64]| {
        let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        format!("{}–{}", pct_or_failed(lo), pct_or_failed(hi))
    };
    let mut json_cells = Vec::new();
    for ((case, method), rows) in &cells {
        let fe = values(rows, "force_error");
        let be = values(rows, "boa_error");
        let ft: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.and_then(|r| r.get("fit_seconds")).and_then(Value::as_f64))
            .collect();
        md += &format!(
            "| {case} | {method} | {} ({}) | {} ({}) | {} |\n",
            pct_or_failed(median(&fe)),
            range(&fe),
            pct_or_failed(median(&be)),
            range(&be),
            if ft.is_empty() {
                "—".to_string()
            } else {
                format!("{:.3}", median(&ft))
            }
        );
        let num_or_null = |v: f64| if v.is_finite() { num(v) } else { Value::Null };
        json_cells.push(json!({"case": case, "method": method,
            "force_error": fe.iter().map(|&v| num_or_null(v)).collect::<Vec<_>>(),
            "boa_error": be.iter().map(|&v| num_or_null(v)).collect::<Vec<_>>(),
            "fit_seconds": ft}));
    }
    md += "\nDraws in which a tfs variant is at or below PySINDy weak (force error, BOA error):\n\n| case | method | force error | BOA error |\n|---|---|---|---|\n";
    let cases: Vec<&String> = cells
        .iter()
        .map(|((c, _), _)| c)
        .fold(Vec::new(), |mut v, c| {
            if !v.contains(&c) {
                v.push(c);
            }
            v
        });
    for case in cases {
        let find = |m: &str| cells.iter().find(|((c, mm), _)| c == case && mm == m);
        let Some((_, weak)) = find("PySINDy weak") else {
            continue;
        };
        for m in ["tfs", "tfs (classical library)"] {
            let Some((_, ours)) = find(m) else { continue };
            let wins = |key: &str| {
                let (a, b) = (values(ours, key), values(weak, key));
                a.iter().zip(&b).filter(|(a, b)| a <= b).count()
            };
            md += &format!(
                "| {case} | {m} | {} of {n} | {} of {n} |\n",
                wins("force_error"),
                wins("boa_error")
            );
        }
    }
    tfs::data::write_atomic(out.join("peers_draws.md"), md)?;
    tfs::data::write_atomic(
        out.join("peers_draws.json"),
        serde_json::to_string_pretty(
            &json!({"format": "tfs-peers-draws/1", "quick": quick, "draws": n, "cells": json_cells}),
        )?,
    )?;
    Ok(())
}

pub(super) fn slug(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    s.split('_')
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join("_")
}

pub(super) fn num(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

pub(super) fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2}%", 100.0 * v)
    } else {
        "—".into()
    }
}

pub(super) fn cell(v: &Value, key: &str) -> String {
    match v.get(key) {
        Some(Value::Number(n)) => n.as_f64().map_or("—".into(), pct),
        _ => match v.get(
            key.replace("error", "failure")
                .replace("test_r_mse", "r_mse_failure")
                .as_str(),
        ) {
            Some(Value::String(_)) => "failed".into(),
            _ => "—".into(),
        },
    }
}

/// Which build the fit times come from: `release` (`cargo run --release -p xtask -- peers`), or
/// the shared `dev` build of `cargo xtask` (optimised, but with our crates' debug assertions).
pub(super) const BUILD: &str = if cfg!(debug_assertions) {
    "dev (`cargo xtask`)"
} else {
    "release"
};

pub(super) fn write_outputs(
    out: &Path,
    rows: &[Value],
    quick: bool,
    draw: u64,
    total: f64,
) -> Result<()> {
    let mut md = String::from("# tfs vs PySINDy: side by side\n\n");
    if draw > 0 {
        md += &format!(
            "Noise realisation {draw} (`--draw {draw}`): the same cases with new noise; the published table is draw 0.\n\n"
        );
    }
    md += &format!(
        "S-DOF Kresling cell, surrogate truth (γ0 = 30°, m = 1, c = 2). Four training sweeps {TRAIN:?} and test sweep {TEST:?} (f0 Hz, f1 Hz, T s, amplitude), {RAMP} s ramps, 200 Hz{}; noise on x and xb_acc at the SNR of each signal. Force error: relative RMS over 0 ≤ h ≤ 1.8. BOA error: share of a {} grid of (x0, v0) ∈ [0, 2] × [−3, 3] labelled differently from the truth. Test R-MSE: model driven by the measured test input, against the noise-free test displacement; the row `{TRUTH_ROW}` is the true model scored the same way, so its R-MSE is what the noise on the measured input alone costs a perfect model. Every simulation starts from a state fitted to the test record's first two periods. PySINDy settings (weak: test-function half-width and threshold; classical: threshold) are chosen by the lowest test R-MSE — an oracle that sees the test record; tfs and SINDy (tfs) choose theirs from the training data only. Fit time: tfs and SINDy (tfs), the median of five identical calls in this process; PySINDy, the selected candidate's velocity smoothing, library rows and STLSQ fit, each the median of five identical calls (no import or start-up), from a {} build. Total run time {total:.0} s.\n\n",
        if quick {
            ", records shortened to 30% (--quick)"
        } else {
            ""
        },
        if quick { "61×61" } else { "200×200" },
        BUILD
    );
    md += "| case | method | force error | BOA error | test R-MSE | fit time (ms) | PySINDy weak's fit time / this one's |\n|---|---|---|---|---|---|---|\n";
    let fit_secs = |r: &Value| r.get("fit_seconds").and_then(Value::as_f64);
    for r in rows {
        let s = |k: &str| r.get(k).and_then(Value::as_str).unwrap_or("").to_string();
        let weak = rows
            .iter()
            .find(|w| {
                w.get("case") == r.get("case")
                    && w.get("method").and_then(Value::as_str) == Some("PySINDy weak")
            })
            .and_then(fit_secs);
        let ratio = match (weak, fit_secs(r)) {
            (Some(w), Some(t)) if t > 0.0 => format!("{:.1}×", w / t),
            _ => "—".into(),
        };
        let secs = fit_secs(r).map_or("—".into(), |v| format!("{:.1}", 1000.0 * v));
        if let Some(f) = r.get("failure").and_then(Value::as_str) {
            md += &format!(
                "| {} | {} | failed: {} | | | | |\n",
                s("case"),
                s("method"),
                f.replace('|', "/")
            );
        } else {
            md += &format!(
                "| {} | {} | {} | {} | {} | {secs} | {ratio} |\n",
                s("case"),
                s("method"),
                cell(r, "force_error"),
                cell(r, "boa_error"),
                cell(r, "test_r_mse")
            );
        }
    }
    md += "\nEquations and the PySINDy selection grids are in peers.json; models in models/, data in data/.\n\n![force error](peers_force_error.svg) ![BOA error](peers_boa_error.svg)\n";
    tfs::data::write_atomic(out.join("peers.md"), md)?;
    tfs::data::write_atomic(
        out.join("peers.json"),
        serde_json::to_string_pretty(
            &json!({"format": "tfs-peers/1", "quick": quick, "draw": draw, "total_seconds": total, "build": BUILD, "rows": rows}),
        )?,
    )?;
    // Figure: errors against SNR for the white-noise cases.
    let methods = [
        "tfs",
        "tfs (classical library)",
        "tfs (plain FFT, paper)",
        "SINDy (tfs, classical)",
        "PySINDy weak",
        "PySINDy classical",
    ];
    for (key, what, stem) in [
        ("force_error", "force error", "peers_force_error"),
        ("boa_error", "BOA error", "peers_boa_error"),
    ] {
        // Log scale: the errors span 0.01 % to 10⁵ %. Exact zeros are drawn at the floor.
        let mut ch = LineChart::new(
            format!("{what} vs SNR (white noise)"),
            "SNR (dB)",
            format!("{what} (%, log; < {LOG_FLOOR_PCT}% drawn at {LOG_FLOOR_PCT}%)"),
        )
        .log_y(true);
        for m in methods {
            let mut pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| {
                    r.get("method").and_then(Value::as_str) == Some(m)
                        && r.get("pink") == Some(&Value::Bool(false))
                })
                .filter_map(|r| {
                    Some((
                        r.get("snr_db")?.as_f64()?,
                        (100.0 * r.get(key)?.as_f64()?).max(LOG_FLOOR_PCT),
                    ))
                })
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            if !pts.is_empty() {
                ch = ch.with_series(Series::line(m, pts));
            }
        }
        ch.x_range = Some((5.0, 65.0));
        if ch.series.iter().any(|s| !s.points.is_empty()) {
            Figure::Line(ch).save(&out.join(stem))?;
        }
    }
    Ok(())
}
