//! The criteria trace for people: what each stage of the identification measured and decided,
//! as sentences and small tables with 4–5 significant digits (the raw trace is `--json`).

use tfs::criteria::{Criterion1, Criterion2, DofTrace, Support, Trace};

/// `v` with 4 significant digits (fixed notation between 1e-3 and 1e5, else scientific).
pub fn sig(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".to_string();
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A record's name as printed: its file name without the folder.
fn short(record: &str) -> &str {
    record.rsplit(['/', '\\']).next().unwrap_or(record)
}

/// Prints the summary `identify` shows by default, per DOF: one line of fit quality (the part
/// of `x''`'s spread the equation leaves on the held-out record, criterion 4's σ), one line of
/// verdict (a DOF the data do not support points to its warning, printed above the equation),
/// and why a DOF has no coefficient intervals when it has none.
pub fn print_summary(trace: &Trace, model: &tfs::library::Model) {
    for d in &trace.dofs {
        if let Some(line) = fit_line(d) {
            println!("{line}");
        }
        if let Some(c1) = &d.criterion1 {
            let verdict = match &c1.support {
                Support::NotSupported { .. } => {
                    "not supported by these data (the warning above says why and what to do)"
                        .to_string()
                }
                s => s.to_string(),
            };
            println!("verdict {}: {verdict}", d.dof);
        }
    }
    for note in tfs::report::interval_notes(trace, model) {
        println!("note: {note}");
    }
}

/// One DOF's fit quality in one line, from its last data-assembly step (criterion 4): the
/// spread of the equation's residual on the held-out record against the spread of the
/// acceleration (measurement noise included) and the residual's mean (its bias).
fn fit_line(d: &DofTrace) -> Option<String> {
    let last = d.assembly.last()?;
    Some(format!(
        "fit {0}: held-out residual {1} % of the spread of {0}'' (noise included), bias {2} % (on {3}; {4} term(s) from {5} record(s))",
        d.dof,
        sig(100.0 * last.sigma),
        sig(100.0 * last.mu),
        short(&d.held_out_record),
        last.n_terms,
        last.records.len(),
    ))
}

/// Prints the criteria trace: per DOF every stage in order, then the time per stage.
pub fn print_trace(trace: &Trace) {
    println!("method: {}", trace.method);
    for d in &trace.dofs {
        print_dof(d);
    }
    if let Some(t) = &trace.tied {
        println!("tied terms (coefficient in the partner's equation = factor × owner's):");
        for tie in &t.ties {
            println!(
                "  {:<16} owner {:<6} partner {:<6} factor {}",
                tie.term,
                tie.owner,
                tie.partner,
                sig(tie.factor_in_partner)
            );
        }
        let masses: Vec<String> = t.masses.iter().map(|m| sig(*m)).collect();
        println!("  masses: {}", masses.join(", "));
    }
    let timing: Vec<String> = trace
        .timing_ms
        .iter()
        .map(|(stage, ms)| format!("{stage} {}", sig(*ms)))
        .collect();
    println!("time (ms): {}", timing.join("; "));
}

/// One DOF's stages.
fn print_dof(d: &DofTrace) {
    println!("dof {}:", d.dof);
    match &d.criterion1 {
        Some(c1) => print_criterion1(c1),
        None => println!("  criterion 1: not run"),
    }
    match &d.criterion2 {
        Some(c2) => print_criterion2(c2, &d.library),
        None => println!("  criterion 2: not run (library pruning is off or the SNR is low)"),
    }
    print_criterion3(d);
    print_criterion4(d);
    if let Some(c1) = &d.criterion1 {
        println!("  verdict: {}", c1.support);
    }
    if let Some(t) = &d.term_test {
        println!(
            "  term test: a kept term needs |coefficient| ≥ {}·SE ({} candidate terms, {} degrees of freedom)",
            sig(t.t_critical),
            t.candidates,
            sig(t.dof)
        );
    }
    println!("  why:");
    for why in &d.settings.why {
        println!("    - {why}");
    }
}

fn print_criterion1(c1: &Criterion1) {
    let snr = c1.estimated_snr_db.map_or(String::new(), |v| {
        if v.lower_bound {
            format!(
                "; estimated displacement SNR at least {} dB if the noise is white (the spectrum shows no noise floor)",
                sig(v.db)
            )
        } else {
            format!("; estimated displacement SNR {} dB", sig(v.db))
        }
    });
    println!(
        "  criterion 1: κ = {} ({:?}) against κ0 = {}: {}{snr}",
        sig(c1.kappa.get(c1.variant)),
        c1.variant,
        sig(c1.kappa0),
        c1.snr,
    );
    println!("    κ0 {}", c1.kappa0_source);
}

fn print_criterion2(c2: &Criterion2, library: &[String]) {
    let kept: Vec<&str> = c2.kept.iter().map(|&j| library[j].as_str()).collect();
    println!(
        "  criterion 2: κ = {} with every term; {}",
        sig(c2.kappa_start),
        c2.kappa1_reason
    );
    println!("    kept: {}", kept.join(", "));
    let order: Vec<String> = c2
        .trace
        .iter()
        .map(|s| format!("{} (κ {})", s.name, sig(s.kappa_after)))
        .collect();
    println!("    elimination order: {}", order.join(", "));
}

fn print_criterion3(d: &DofTrace) {
    let s = &d.settings;
    println!(
        "  criterion 3 ({:?} form): δ = {}, {} window(s) per record, STLSQ threshold {}",
        s.form,
        sig(s.delta),
        s.windows,
        sig(s.threshold)
    );
    if !d.bins.is_empty() {
        println!(
            "    {:<24} {:>12} {:>10} {:>18} {:>11}",
            "record", "cut-off Hz", "kept bins", "band Hz", "decimation"
        );
        for b in &d.bins {
            println!(
                "    {:<24} {:>12} {:>10} {:>18} {:>11}",
                short(&b.record),
                sig(b.cutoff_hz),
                b.kept_bins,
                format!("{}–{}", sig(b.band_hz[0]), sig(b.band_hz[1])),
                b.decimation
            );
        }
    }
    if !s.candidates.is_empty() {
        println!(
            "    {:>8} {:>8} {:>16} {:>16}",
            "δ", "windows", "held-out (terms)", "(coefficients)"
        );
        for (i, c) in s.candidates.iter().enumerate() {
            let coef = s
                .coefficient_candidates
                .get(i)
                .map_or(String::new(), |c| sig(c.held_out_error));
            let chosen = if c.delta == s.delta && c.windows == s.windows {
                "  ← used"
            } else {
                ""
            };
            println!(
                "    {:>8} {:>8} {:>16} {:>16}{chosen}",
                sig(c.delta),
                c.windows,
                sig(c.held_out_error),
                coef
            );
        }
    }
}

fn print_criterion4(d: &DofTrace) {
    if !d.assembly.is_empty() {
        println!("  criterion 4 (held out: {}):", short(&d.held_out_record));
        println!(
            "    {:>8} {:>8} {:>6} {:>10} {:>10}",
            "records", "rows", "terms", "μ", "σ"
        );
        for s in &d.assembly {
            println!(
                "    {:>8} {:>8} {:>6} {:>10} {:>10}",
                s.records.len(),
                s.rows,
                s.n_terms,
                sig(s.mu),
                sig(s.sigma)
            );
        }
    }
    println!("  assembly: {}", d.assembly_verdict.outcome);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_significant_digits() {
        assert_eq!(sig(6.312257), "6.312");
        assert_eq!(sig(0.0378), "0.03780");
        assert_eq!(sig(12345.6), "12346");
        assert_eq!(sig(-1.2e-6), "-1.200e-6");
        assert_eq!(sig(2.5e7), "2.500e7");
        assert_eq!(sig(0.0), "0");
        assert_eq!(sig(f64::NAN), "NaN");
    }
}
