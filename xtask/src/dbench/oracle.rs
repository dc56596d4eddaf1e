//! The oracle's score: how often the hidden effect added by name (`refit --add <hidden>`)
//! predicts the held-out record better than the start model, per baseline and noise level, and
//! the cases where it does not. `--oracle-only` runs just this (identify and the oracle refit
//! per single-effect case, no diagnosis).

use std::fmt::Write as _;

use super::case::{CaseResult, oracle_better};
use super::noise_key;
use super::truth::Kind;
use crate::common::f4;

/// (better, cases) over the single-effect cases of baseline `kind` (all when `None`) at noise
/// level `snr`.
pub fn count(cases: &[CaseResult], kind: Option<Kind>, snr: Option<f64>) -> (usize, usize) {
    let v: Vec<bool> = cases
        .iter()
        .filter(|c| kind.is_none_or(|k| c.spec.kind == k) && c.spec.snr == snr)
        .filter_map(oracle_better)
        .collect();
    (v.iter().filter(|b| **b).count(), v.len())
}

/// The terminal table: per noise level that ran, each baseline's count, then the total; with
/// `losses`, one line per case whose oracle refit is not better.
pub fn table(cases: &[CaseResult], losses: bool) -> String {
    let mut s = String::new();
    let mut levels: Vec<Option<f64>> = Vec::new();
    for c in cases.iter().filter(|c| oracle_better(c).is_some()) {
        if !levels.contains(&c.spec.snr) {
            levels.push(c.spec.snr);
        }
    }
    if levels.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "\nOracle refit (the hidden effect added by name) better than the start model on the held-out record:"
    );
    for snr in levels {
        let mut row = format!("  {:<6}", noise_key(snr));
        for k in Kind::ALL {
            let (b, n) = count(cases, Some(k), snr);
            if n > 0 {
                let _ = write!(row, "  {} {b}/{n}", k.key());
            }
        }
        let (b, n) = count(cases, None, snr);
        let _ = writeln!(
            s,
            "{row}  all {b}/{n} ({}%)",
            f4(100.0 * b as f64 / n.max(1) as f64)
        );
    }
    let short: Vec<&CaseResult> = cases
        .iter()
        .filter(|c| oracle_better(c).is_some())
        .filter(|c| {
            c.heldout_score
                .as_ref()
                .is_some_and(|s| s.horizon.is_some())
        })
        .collect();
    if !short.is_empty() {
        let free = short
            .iter()
            .filter(|c| matches!(c.oracle_free_run, (Some(s), Some(o)) if o < s))
            .count();
        let _ = writeln!(
            s,
            "  {} of these cases are scored by short-horizon pieces (the input's noise decides a compared model's free run there); by the free run, the oracle is better on {free} of them",
            short.len()
        );
    }
    if losses {
        for c in cases.iter().filter(|c| oracle_better(c) == Some(false)) {
            let _ = writeln!(
                s,
                "  not better: case {} {} {} {} size {}: start {} -> oracle {} ({})  [{}]",
                c.spec.id,
                c.spec.kind.key(),
                noise_key(c.spec.snr),
                c.spec.hidden.join("+"),
                f4(c.realised.first().copied().unwrap_or(f64::NAN)),
                c.start_heldout.map_or("failed".into(), f4),
                c.oracle_after.map_or("failed".into(), f4),
                c.heldout_score
                    .as_ref()
                    .map_or("free run".into(), |s| s.label()),
                c.oracle_model.as_deref().unwrap_or("-"),
            );
        }
    }
    s
}
