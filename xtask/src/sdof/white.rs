//! Study 1: §3.1 under white noise at 60 and 30 dB (Table 1, Figs 3–4).

use anyhow::{Result, anyhow};
use serde_json::json;
use tfs::data::Record;
use tfs::library::Library;
use tfs::origami::NoiseKind;
use tfs::plot::{LineChart, Series};

use crate::common::{Opts, dev, f4, num, pct, progress, rel};
use crate::report::{Study, Table};

use super::{
    BOA_BOUND, BOA_RULE, PAPER_T1_30, PAPER_T1_60, SdofFit, SdofTruth, TFS_LIBRARY,
    TFS_LIBRARY_NAMES, basin_cfg, basin_figures, fit_case, fit_json, force_figures, med_json,
    med_table, records, table1_coefs, truth, truth_basin, truth_note,
};

/// Table 1: the identified coefficients at 60 and 30 dB against the truth, the paper's rows
/// beside them (with checks and JSON), their deviations and the equations identified.
fn table1(st: &mut Study, t: &SdofTruth, fits: &[SdofFit]) -> Result<()> {
    let mut t1 = Table::new(
        "table1",
        "Table 1: coefficients of x'' + ζx' + αx^5 + βx^6 + γx^7 = −xb_acc (paper beside ours)",
        &[
            "SNR",
            "source",
            "ζ",
            "α",
            "β",
            "γ",
            "other terms kept",
            "xb_acc coef",
        ],
    );
    t1.row(vec![
        "—".into(),
        "truth (our surrogate)".into(),
        f4(t.zeta),
        f4(t.coefs[0]),
        f4(t.coefs[1]),
        f4(t.coefs[2]),
        "none".into(),
        "-1".into(),
    ]);
    for (f, paper, tol) in [(&fits[0], PAPER_T1_60, 0.02), (&fits[1], PAPER_T1_30, 0.05)] {
        let (c, others, xb) = table1_coefs(&f.model);
        let snr = if f.label.contains("60") {
            "60 dB"
        } else {
            "30 dB"
        };
        t1.row(vec![
            snr.into(),
            "paper".into(),
            f4(paper[0]),
            f4(paper[1]),
            f4(paper[2]),
            f4(paper[3]),
            "none".into(),
            "—".into(),
        ]);
        let oth = if others.is_empty() {
            "none".to_string()
        } else {
            others
                .iter()
                .map(|(n, c)| format!("{n}: {}", f4(*c)))
                .collect::<Vec<_>>()
                .join("; ")
        };
        t1.row(vec![
            snr.into(),
            "ours (T-F-S)".into(),
            f4(c[0]),
            f4(c[1]),
            f4(c[2]),
            f4(c[3]),
            oth.clone(),
            f4(xb),
        ]);
        let names = ["ζ", "α", "β", "γ"];
        // Judged against the truth the coefficients estimate; the paper's row is shown beside
        // it with its own distance from that truth.
        let truth_c = [t.zeta, t.coefs[0], t.coefs[1], t.coefs[2]];
        for k in 0..4 {
            let d = rel(c[k], truth_c[k]);
            st.compare(
                &format!("Table 1 {snr} {}", names[k]),
                &f4(truth_c[k]),
                &format!("{} ({})", f4(c[k]), dev(c[k], truth_c[k])),
                &format!(
                    "{} ({}; ours {} from it)",
                    f4(paper[k]),
                    dev(paper[k], truth_c[k]),
                    dev(c[k], paper[k])
                ),
                Some(d <= tol && others.is_empty()),
                &format!(
                    "within {:.0}% of the truth, no extra terms{}",
                    100.0 * tol,
                    if others.is_empty() {
                        String::new()
                    } else {
                        format!(" (extra: {})", others.len())
                    }
                ),
            );
        }
        st.set(
            &format!("table1_{}", if snr == "60 dB" { "60db" } else { "30db" }),
            json!({
                "paper": {"zeta": paper[0], "alpha": paper[1], "beta": paper[2], "gamma": paper[3]},
                "ours": {"zeta": num(c[0]), "alpha": num(c[1]), "beta": num(c[2]), "gamma": num(c[3])},
                "rel_dev_from_paper": (0..4).map(|k| num(rel(c[k], paper[k]))).collect::<Vec<_>>(),
                "rel_dev_from_truth": (0..4).map(|k| num(rel(c[k], truth_c[k]))).collect::<Vec<_>>(),
                "other_terms": others.iter().map(|(n, c)| json!({"term": n, "coef": num(*c)})).collect::<Vec<_>>(),
            }),
        );
    }
    st.table(t1)?;
    let truth_c = [t.zeta, t.coefs[0], t.coefs[1], t.coefs[2]];
    let dev = |f: &SdofFit| -> String {
        let (c, _, _) = table1_coefs(&f.model);
        (0..4)
            .map(|k| format!("{:+.2}%", 100.0 * (c[k] - truth_c[k]) / truth_c[k].abs()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    st.text(format!(
        "Deviation of our (ζ, α, β, γ) from the truth: 60 dB: {}; 30 dB: {}. The summary judges these against the truth; the paper's rows are shown beside them with their own distance from the truth (the paper's 30 dB row is about 12% below its 60 dB row and below the surrogate it fitted, so a fit that stays close to the truth at 30 dB is that far from the paper's row).",
        dev(&fits[0]),
        dev(&fits[1])
    ));
    st.text(format!(
        "Equations identified:\n\n- 60 dB: `{}`\n- 30 dB: `{}`",
        fits[0].model.equation_string(),
        fits[1].model.equation_string()
    ));
    Ok(())
}

/// The basin errors of both fits against the truth's map, the paper's beside them, with checks.
fn boa_table(st: &mut Study, fits: &[SdofFit]) -> Result<()> {
    let mut tb_tab = Table::new(
        "boa_white",
        "BOA errors against the truth (share of grid cells labelled differently)",
        &[
            "case",
            "BOA error (ours)",
            "BOA error (paper)",
            "stable states",
            "test R-MSE",
        ],
    );
    for (f, paper) in [(&fits[0], 0.0094), (&fits[1], 0.0246)] {
        let e = f.basin.as_ref().map(|b| b.2.error).unwrap_or(f64::NAN);
        tb_tab.row(vec![
            f.label.clone(),
            f.basin
                .as_ref()
                .map(|b| pct(b.2.error))
                .unwrap_or_else(|e| format!("failed: {e}")),
            pct(paper),
            f.basin
                .as_ref()
                .map(|b| {
                    format!(
                        "{:?}",
                        b.0.stable()
                            .iter()
                            .map(|v| (v * 1e3).round() / 1e3)
                            .collect::<Vec<_>>()
                    )
                })
                .unwrap_or_default(),
            f.r_mse
                .as_ref()
                .map(|r| f4(r.0))
                .unwrap_or_else(|e| format!("failed: {e}")),
        ]);
        st.compare(
            &format!("BOA error {}", f.label),
            "0% (the truth's map)",
            &pct(e),
            &format!("{} (ours {:+.2} points)", pct(paper), 100.0 * (e - paper)),
            Some(e.is_finite() && e < BOA_BOUND),
            BOA_RULE,
        );
    }
    st.table(tb_tab)?;
    Ok(())
}

/// Study 1: white noise at 60 and 30 dB (Table 1, Figs 3–4).
pub fn study_white(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(7, "§3.1 white");
    let scale = o.pick(0.5, 1.0);
    let t = truth()?;
    st.text(truth_note(&t));
    if o.quick {
        st.text("Quick mode: every sweep shortened to half its length; basin grid 41×41.");
    }
    let cfg = basin_cfg(o);
    pb.set_message("truth basin");
    let tb = truth_basin(&t, &cfg)?;
    pb.inc(1);
    let mut fits = Vec::new();
    for (snr, seed) in [(60.0, 100), (30.0, 200)] {
        pb.set_message(format!("data {snr} dB"));
        let (train, test) = records(&t, NoiseKind::White, snr, scale, seed)?;
        pb.inc(1);
        pb.set_message(format!("identify {snr} dB"));
        fits.push(fit_case(
            &format!("white {snr} dB"),
            train,
            &test,
            &tb,
            &cfg,
        )?);
        pb.inc(1);
    }
    pb.set_message("tables and figures");
    table1(st, &t, &fits)?;
    // ---- BOA errors and MED.
    boa_table(st, &fits)?;
    st.table(med_table(
        "med_white",
        "Minimum-energy deployment S1 → S2 (Eq. 17) from the BOA maps",
        vec![
            ("truth".into(), Ok(tb.med.clone())),
            (fits[0].label.clone(), fits[0].med.clone()),
            (fits[1].label.clone(), fits[1].med.clone()),
        ],
    ))?;
    st.set("truth", json!({"coefs": t.coefs, "zeta": t.zeta, "stable": t.wells.stable(), "unstable": t.wells.unstable(), "med": med_json(&tb.med), "basin_shares": tb.map.shares}));
    st.set("grid", json!({"nx": cfg.nx, "ny": cfg.ny, "x_range": [cfg.x_range.0, cfg.x_range.1], "v_range": [cfg.v_range.0, cfg.v_range.1], "dt": cfg.dt, "t_max": cfg.t_max}));
    st.set("white_60db", fit_json(&fits[0]));
    st.set("white_30db", fit_json(&fits[1]));
    // ---- Fig. 3.
    fig3(st, &fits)?;
    pb.inc(1);
    // ---- Fig. 4.
    let refs: Vec<&SdofFit> = fits.iter().collect();
    force_figures(st, "fig4", "Fig. 4", &t, &refs)?;
    basin_figures(st, "fig4", "Fig. 4", &t, &tb, &refs)?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}

/// Fig. 3 (c–f) from the criteria traces.
fn fig3(st: &mut Study, fits: &[SdofFit]) -> Result<()> {
    // (c) κ vs added-noise SNR with κ0.
    let mut c = LineChart::new(
        "Fig. 3c: Criterion 1 — noise level index κ vs SNR of added noise",
        "SNR of noise added to the data (dB)",
        "κ (standardised, decades)",
    );
    let mut calib = Vec::new();
    for (k, f) in fits.iter().enumerate() {
        let Some(c1) = f.trace.dofs.first().and_then(|d| d.criterion1.as_ref()) else {
            continue;
        };
        let pts: Vec<(f64, f64)> = c1
            .curve
            .iter()
            .filter_map(|p| p.added_snr_db.map(|s| (s, p.kappa.get(c1.variant))))
            .collect();
        let (lo, hi) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
            (a.0.min(p.0), a.1.max(p.0))
        });
        c = c
            .with_series(
                Series::line(
                    format!("κ after adding noise, {} data", f.label),
                    pts.clone(),
                )
                .color(2 * k + 1),
            )
            .with_series(
                Series::dashed(
                    format!("κ0 = {:.2} ({})", c1.kappa0, f.label),
                    vec![(lo, c1.kappa0), (hi, c1.kappa0)],
                )
                .color(2 * k + 2),
            );
        calib.push(json!({"case": f.label, "curve": pts.iter().map(|p| json!([p.0, num(p.1)])).collect::<Vec<_>>(), "kappa0": num(c1.kappa0), "kappa_data": num(c1.kappa.get(c1.variant)), "knee_snr_db": c1.knee_snr_db, "high_snr": c1.high_snr}));
        c = c.with_marker(
            if f.label.contains("60") { 60.0 } else { 30.0 },
            c1.kappa.get(c1.variant),
            format!("data as given ({})", f.label),
        );
    }
    st.set("fig3c_kappa", json!(calib));
    st.figure("fig3c_kappa", "Fig. 3c: κ of the data after adding white noise at each SNR, with the calibrated threshold κ0 (knee of the curve); the marker is κ of the data as given", c)?;
    // (d) pruning trace: Criterion 2 on the time-domain data of each case.
    let mut d = LineChart::new(
        "Fig. 3d: Criterion 2 — κ during backward elimination",
        "number of library terms removed",
        "κ of the remaining library (decades)",
    );
    let mut prune = Vec::new();
    for (k, f) in fits.iter().enumerate() {
        let c2 = prune_trace(&f.train)?;
        let mut pts = vec![(0.0, c2.kappa_start)];
        pts.extend(
            c2.trace
                .iter()
                .enumerate()
                .map(|(i, s)| ((i + 1) as f64, s.kappa_after)),
        );
        d = d
            .with_series(Series::line(f.label.clone(), pts.clone()).color(2 * k + 1))
            .with_series(
                Series::dashed(
                    format!("κ1 = {:.2} ({})", c2.kappa1, f.label),
                    vec![(0.0, c2.kappa1), (c2.trace.len() as f64, c2.kappa1)],
                )
                .color(2 * k + 2),
            );
        if k == 0 {
            for (i, s) in c2.trace.iter().enumerate() {
                d = d.with_marker((i + 1) as f64, s.kappa_after, format!("−{}", s.name));
            }
        }
        let names: Vec<String> = c2
            .kept
            .iter()
            .map(|&j| TFS_LIBRARY_NAMES[j].to_string())
            .collect();
        prune.push(json!({"case": f.label, "kappa_start": num(c2.kappa_start), "kappa1": num(c2.kappa1), "kappa1_reason": c2.kappa1_reason, "removed": c2.trace.iter().map(|s| json!({"name": s.name, "kappa_after": num(s.kappa_after)})).collect::<Vec<_>>(), "kept": names}));
    }
    st.set("fig3d_pruning", json!(prune));
    st.figure("fig3d_pruning", "Fig. 3d: Criterion 2 (tfs_criteria::prune_library) on the time-domain training data (Savitzky–Golay derivatives): κ after each backward-elimination step (labels: term removed at 60 dB); dashed: κ1, the value before the abrupt drop", d)?;
    // (e) spectrum with the kept band.
    let mut e = LineChart::new(
        "Fig. 3e: Criterion 3 — spectrum of the measured displacement and the kept band",
        "f (Hz)",
        "amplitude of x (log)",
    )
    .log_y(true);
    e.x_range = Some((0.0, 8.0));
    let mut bands = Vec::new();
    for (k, f) in fits.iter().enumerate().rev() {
        let r = &f.train[0];
        let x = r.column("x").unwrap_or_default();
        let (fr, amp) = tfs::signal::amplitude_spectrum(x, r.dt())?;
        let pts: Vec<(f64, f64)> = fr
            .iter()
            .zip(&amp)
            .filter(|p| *p.0 <= 8.0)
            .map(|(a, b)| (*a, *b))
            .collect();
        e = e.with_series(
            Series::line(format!("measured x, {} (train1)", f.label), pts).color(k + 1),
        );
        if let Some(b) = f.trace.dofs.first().and_then(|d| d.bins.first()) {
            let top = amp.iter().cloned().fold(0.0, f64::max);
            let low = amp
                .iter()
                .cloned()
                .filter(|v| *v > 0.0)
                .fold(f64::INFINITY, f64::min);
            e = e.with_series(
                Series::dashed(
                    format!("top of kept band, {}: {:.2} Hz", f.label, b.band_hz[1]),
                    vec![(b.band_hz[1], low), (b.band_hz[1], top)],
                )
                .color(k + 3),
            );
        }
        bands.push(json!({"case": f.label, "bins": f.trace.dofs.first().map(|d| d.bins.iter().map(|b| json!({"record": b.record, "kept_bins": b.kept_bins, "band_hz": [num(b.band_hz[0]), num(b.band_hz[1])], "cutoff_hz": num(b.cutoff_hz), "in_band_noise_share": num(b.in_band_noise_share)})).collect::<Vec<_>>()), "delta": f.trace.dofs.first().map(|d| d.settings.delta), "windows": f.trace.dofs.first().map(|d| d.settings.windows)}));
    }
    st.set("fig3e_bins", json!(bands));
    st.figure("fig3e_spectrum", "Fig. 3e: amplitude spectrum of the measured displacement (first training sweep); dashed vertical lines: top of the band of bins kept by Criterion 3 (first record)", e)?;
    // (f) (μ, σ) trajectory.
    let mut ff = LineChart::new(
        "Fig. 3f: Criterion 4 — held-out residual statistics during data assembly",
        "records assembled",
        "relative μ and σ of the residual (log)",
    )
    .log_y(true);
    let mut steps = 1;
    for (k, f) in fits.iter().enumerate() {
        let Some(d) = f.trace.dofs.first() else {
            continue;
        };
        let mu: Vec<(f64, f64)> = d
            .assembly
            .iter()
            .enumerate()
            .map(|(i, s)| ((i + 1) as f64, s.mu.abs()))
            .collect();
        let sg: Vec<(f64, f64)> = d
            .assembly
            .iter()
            .enumerate()
            .map(|(i, s)| ((i + 1) as f64, s.sigma))
            .collect();
        steps = steps.max(sg.len());
        // each assembly step marked: with two or three steps the lines alone read as flat bars
        ff = ff
            .with_series(Series::line(format!("σ, {}", f.label), sg.clone()).color(2 * k + 1))
            .with_series(Series::points("", sg).color(2 * k + 1))
            .with_series(Series::dashed(format!("|μ|, {}", f.label), mu.clone()).color(2 * k + 2))
            .with_series(Series::points("", mu).color(2 * k + 2));
    }
    ff.x_range = Some((0.7, steps as f64 + 0.3));
    ff.x_labels = Some(steps);
    st.figure("fig3f_mu_sigma", "Fig. 3f: mean |μ| and spread σ of the held-out residual (relative to the spread of x'') as training records are assembled", ff)?;
    Ok(())
}

/// Criterion 2 on `[Θ | x'']` of the training records in the time domain (Savitzky–Golay
/// derivatives of the measured displacement, ends trimmed).
fn prune_trace(train: &[Record]) -> Result<tfs::criteria::Criterion2> {
    const HALF: usize = 12;
    let sg = tfs::signal::Differentiator::SavitzkyGolay {
        half_window: HALF,
        poly_order: 3,
    };
    let lib = Library::parse(&format!("{TFS_LIBRARY}, x_acc_sg"), &["x"])?;
    let mut blocks = Vec::new();
    for r in train {
        let x = r
            .column("x")
            .ok_or_else(|| anyhow!("record {} has no x", r.source()))?;
        let mut rec = r.clone();
        rec.set_column("x'", sg.apply(x, r.dt(), 1)?)?;
        rec.set_column("x_acc_sg", sg.apply(x, r.dt(), 2)?)?;
        let rec = rec.slice(HALF..r.len() - HALF)?;
        blocks.push(lib.evaluate(&rec)?);
    }
    let names: Vec<String> = TFS_LIBRARY_NAMES.iter().map(|s| s.to_string()).collect();
    let m: usize = blocks.iter().map(|b| b.nrows()).sum();
    let mut all = faer::Mat::<f64>::zeros(m, names.len() + 1);
    let mut i0 = 0;
    for b in &blocks {
        all.as_mut()
            .submatrix_mut(i0, 0, b.nrows(), b.ncols())
            .copy_from(b.as_ref());
        i0 += b.nrows();
    }
    Ok(tfs::criteria::prune_library(
        all.as_ref(),
        &names,
        tfs::criteria::KappaVariant::Standardised,
        None,
        1.0,
    )?)
}
