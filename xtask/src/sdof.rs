//! §3.1 (white noise, Table 1, Figs 3–4), §3.1 pink noise (Fig. 5) and Appendix B (Table B1):
//! the bistable Kresling cell under its surrogate truth.

use std::time::Instant;

use anyhow::{Context, Result, anyhow};
use serde_json::{Value, json};
use tfs::basin::{
    BasinConfig, BasinMap, BoaComparison, Med, WellInfo, basin_sdof, compare, med_sdof,
};
use tfs::criteria::{IdentifySpec, Trace, identify_sindy, identify_tfs};
use tfs::data::Record;
use tfs::library::{Library, Model};
use tfs::origami::{
    CellForce, CellSpec, Chain, DatasetConfig, Excitation, NoiseKind, SystemSpec, Truth,
    build_system, generate,
};
use tfs::plot::{LineChart, Series};

use crate::common::{
    Opts, basin_figure, coef, curve, dev, f4, fixed, model_json, model_wells, num, pct, progress,
    rel, sim_rmse, terms,
};
use crate::report::{Study, Table};

/// Training sweeps of base acceleration (f0 Hz, f1 Hz, duration s, amplitude), from the issue.
pub const TRAIN: [(f64, f64, f64, f64); 4] = [
    (0.05, 1.5, 100.0, 3.0),
    (0.05, 1.5, 60.0, 4.0),
    (0.1, 1.2, 80.0, 5.0),
    (0.05, 2.0, 120.0, 6.0),
];
/// Test sweep.
pub const TEST: (f64, f64, f64, f64) = (0.08, 1.4, 90.0, 4.5);
/// Sampling interval (200 Hz).
pub const DT: f64 = 0.005;
/// T-F-S library (the paper's seventh-order polynomial library with damping and input).
pub const TFS_LIBRARY: &str = "x^1..7, x', xb_acc";
/// Classical SINDy library of Appendix B: every monomial of x, x' of degree 1..7 plus the input
/// (35 + 1 = 36 columns, the paper's width).
pub const SINDY_LIBRARY: &str = "poly(x, x'; 1..7), xb_acc";
/// Names of the T-F-S library columns, in order.
const TFS_LIBRARY_NAMES: [&str; 9] = [
    "x", "x^2", "x^3", "x^4", "x^5", "x^6", "x^7", "x'", "xb_acc",
];
/// Equilibrium search range.
const SEARCH: (f64, f64) = (-0.6, 2.6);
/// Paper Table 1 (ζ, α, β, γ).
pub const PAPER_T1_60: [f64; 4] = [1.99, 12.12, -18.03, 6.56];
/// Paper Table 1 at 30 dB.
pub const PAPER_T1_30: [f64; 4] = [1.98, 10.66, -16.05, 5.88];

/// The surrogate truth: system, force law, wells and its coefficients.
pub struct SdofTruth {
    /// The simulated system (a one-cell chain).
    pub sys: Chain,
    /// The force law.
    pub law: CellForce,
    /// Wells of the truth.
    pub wells: WellInfo,
    /// Surrogate coefficients of h^5, h^6, h^7.
    pub coefs: Vec<f64>,
    /// Damping per unit mass.
    pub zeta: f64,
    spec: SystemSpec,
}

/// Builds the §3.1 cell with the surrogate truth.
pub fn truth() -> Result<SdofTruth> {
    let spec = SystemSpec::Kresling(CellSpec {
        truth: Truth::Surrogate,
        ..Default::default()
    });
    let sys = build_system(&spec)?;
    let cell = &sys.cells()[0];
    let law = cell.force_law().clone();
    let coefs = match &law {
        CellForce::Surrogate(s) => s.coefs.clone(),
        CellForce::Truss(_) => Vec::new(),
    };
    let zeta = cell.damping() / cell.mass();
    let (l1, l2) = (law.clone(), law.clone());
    let wells = WellInfo::from_force(
        move |x| l1.force(x),
        move |x| l2.potential(x),
        SEARCH,
        cell.mass(),
    )?;
    Ok(SdofTruth {
        sys,
        law,
        wells,
        coefs,
        zeta,
        spec,
    })
}

fn renamed(r: &Record, name: &str) -> Result<Record> {
    let cols = r
        .names()
        .iter()
        .map(|n| (n.clone(), r.column(n).unwrap_or_default().to_vec()))
        .collect();
    Ok(Record::new(name, r.t().to_vec(), cols)?)
}

/// Training and test records at `snr` dB of `kind` noise; `scale` shortens every sweep.
pub fn records(
    t: &SdofTruth,
    kind: NoiseKind,
    snr: f64,
    scale: f64,
    seed: u64,
) -> Result<(Vec<Record>, Record)> {
    let mut all = Vec::new();
    for (i, &(f0, f1, d, a)) in TRAIN.iter().chain(std::iter::once(&TEST)).enumerate() {
        let cfg = DatasetConfig {
            system: t.spec.clone(),
            excitations: vec![Excitation::Sweep {
                f0,
                f1,
                amplitude: a,
                log: false,
                ramp: 0.0,
            }],
            duration: d * scale,
            dt: DT,
            snr_db: Some(snr),
            noise: kind,
            seed: seed + 17 * i as u64,
            x0: None,
            v0: None,
            rtol: 1e-9,
        };
        let ds = generate(&cfg).with_context(|| format!("simulating sweep {}", i + 1))?;
        let name = if i < TRAIN.len() {
            format!("train{}", i + 1)
        } else {
            "test".to_string()
        };
        all.push(renamed(&ds.records[0], &name)?);
    }
    let test = all.pop().ok_or_else(|| anyhow!("no test record"))?;
    Ok((all, test))
}

/// Basin grid of the S-DOF studies.
pub fn basin_cfg(o: &Opts) -> BasinConfig {
    let n = o.pick(41, 161);
    BasinConfig::new(n, n, (-0.25, 2.0), (-3.0, 3.0))
}

/// One identified S-DOF model with everything derived from it.
pub struct SdofFit {
    /// Case label, e.g. "white 60 dB".
    pub label: String,
    /// The model.
    pub model: Model,
    /// Its criteria trace.
    pub trace: Trace,
    /// Identification wall time (s).
    pub seconds: f64,
    /// Basin map, comparison with the truth and MED (errors as text).
    pub basin: std::result::Result<(WellInfo, BasinMap, BoaComparison), String>,
    /// MED of the model.
    pub med: std::result::Result<Med, String>,
    /// Test R-MSE (against the measured test displacement) and the simulated response.
    pub r_mse: std::result::Result<(f64, Vec<f64>), String>,
    /// The training records (for spectra).
    pub train: Vec<Record>,
}

/// Truth basin map and MED.
pub struct TruthBasin {
    /// The map.
    pub map: BasinMap,
    /// Its MED.
    pub med: Med,
}

/// Computes the truth's basin map and MED.
pub fn truth_basin(t: &SdofTruth, cfg: &BasinConfig) -> Result<TruthBasin> {
    let map = basin_sdof(&t.sys, &t.wells, cfg, None).context("truth basin map")?;
    let med = med_sdof(&t.sys, &t.wells, &map, cfg, 0, 1).context("truth MED")?;
    Ok(TruthBasin { map, med })
}

/// Identifies with T-F-S on `train`, then basin, BOA error, MED and test R-MSE.
pub fn fit_case(
    label: &str,
    train: Vec<Record>,
    test: &Record,
    tb: &TruthBasin,
    cfg: &BasinConfig,
) -> Result<SdofFit> {
    let spec = IdentifySpec::new(&["x"], TFS_LIBRARY);
    let t0 = Instant::now();
    let id =
        identify_tfs(&train, &spec).with_context(|| format!("T-F-S identification ({label})"))?;
    let seconds = t0.elapsed().as_secs_f64();
    let model = id.model;
    let basin = (|| -> Result<(WellInfo, BasinMap, BoaComparison)> {
        let wells = model_wells(&model, "x", SEARCH)?;
        let sys = model.compile()?;
        let map = basin_sdof(&sys, &wells, cfg, None)?;
        let cmp = compare(&map, &tb.map)?;
        Ok((wells, map, cmp))
    })()
    .map_err(|e| format!("{e:#}"));
    let med = match &basin {
        Ok((wells, map, _)) => model
            .compile()
            .map_err(|e| e.to_string())
            .and_then(|sys| med_sdof(&sys, wells, map, cfg, 0, 1).map_err(|e| e.to_string())),
        Err(e) => Err(format!("no basin map: {e}")),
    };
    let r_mse = sim_rmse(&model, test, "x");
    Ok(SdofFit {
        label: label.to_string(),
        model,
        trace: id.trace,
        seconds,
        basin,
        med,
        r_mse,
        train,
    })
}

/// (ζ, α, β, γ) of a model in the paper's Eq. 16 form, plus the other terms kept.
pub fn table1_coefs(m: &Model) -> ([f64; 4], Vec<(String, f64)>, f64) {
    let z = -coef(m, "x", "x'");
    let a = -coef(m, "x", "x^5");
    let b = -coef(m, "x", "x^6");
    let g = -coef(m, "x", "x^7");
    let others = terms(m, "x")
        .into_iter()
        .filter(|(n, _)| !["x'", "x^5", "x^6", "x^7", "xb_acc"].contains(&n.as_str()))
        .collect();
    ([z, a, b, g], others, coef(m, "x", "xb_acc"))
}

fn fit_json(f: &SdofFit) -> Value {
    let ([z, a, b, g], others, xb) = table1_coefs(&f.model);
    let d = f.trace.dofs.first();
    json!({
        "equation": f.model.equation_string(),
        "model": model_json(&f.model),
        "zeta": num(z), "alpha": num(a), "beta": num(b), "gamma": num(g),
        "xb_acc_coef": num(xb),
        "other_terms": others.iter().map(|(n, c)| json!({"term": n, "coef": num(*c)})).collect::<Vec<_>>(),
        "identify_seconds": f.seconds,
        "kappa": d.and_then(|d| d.criterion1.as_ref()).map(|c| json!({"raw": num(c.kappa.raw), "standardised": num(c.kappa.standardised), "kappa0": num(c.kappa0), "high_snr": c.high_snr})),
        "pruned_to": d.map(|d| d.regression_library.clone()),
        "assembly": d.map(|d| d.assembly.iter().map(|s| json!({"records": s.records.len(), "rows": s.rows, "mu": num(s.mu), "sigma": num(s.sigma)})).collect::<Vec<_>>()),
        "assembly_verdict": d.map(|d| d.assembly_verdict.clone()),
        "boa_error": f.basin.as_ref().ok().map(|b| num(b.2.error)),
        "basin_error": f.basin.as_ref().err(),
        "stable": f.basin.as_ref().ok().map(|b| b.0.stable().to_vec()),
        "unstable": f.basin.as_ref().ok().map(|b| b.0.unstable().to_vec()),
        "med": f.med.as_ref().ok().map(med_json),
        "med_error": f.med.as_ref().err(),
        "test_r_mse": f.r_mse.as_ref().ok().map(|r| num(r.0)),
        "test_r_mse_error": f.r_mse.as_ref().err(),
    })
}

/// MED as JSON.
pub fn med_json(m: &Med) -> Value {
    json!({"energy": num(m.energy), "x0": num(m.x0), "v0": num(m.v0), "kinetic": num(m.kinetic),
           "potential": num(m.potential), "quasi_static_barrier": num(m.quasi_static_barrier)})
}

fn truth_note(t: &SdofTruth) -> String {
    format!(
        "Truth: the §3.1 Kresling cell (a0 = 1.6, c0 = 1, γ0 = 30°, k_a = k_b = 9.30, m = 1, c = 2) simulated with the **surrogate** force law — the uniform least-squares {{h^5, h^6, h^7}} fit of the truss force over 0 ≤ h ≤ 1.7, computed at run time — which is the paper's setting. Surrogate: F(h) = {} h^5 {:+.4} h^6 {:+.4} h^7, c/m = {}; stable states {:?}, unstable {:?}. Training: four linear sweeps of base acceleration (f0, f1, T, a) = {:?}, test sweep {:?}, sampled at 200 Hz; noise added to x and xb_acc.",
        f4(t.coefs.first().copied().unwrap_or(f64::NAN)),
        t.coefs.get(1).copied().unwrap_or(f64::NAN),
        t.coefs.get(2).copied().unwrap_or(f64::NAN),
        t.zeta,
        t.wells
            .stable()
            .iter()
            .map(|v| (v * 1e4).round() / 1e4)
            .collect::<Vec<_>>(),
        t.wells
            .unstable()
            .iter()
            .map(|v| (v * 1e4).round() / 1e4)
            .collect::<Vec<_>>(),
        TRAIN,
        TEST
    )
}

fn med_table(
    name: &str,
    caption: &str,
    rows: Vec<(String, std::result::Result<Med, String>)>,
) -> Table {
    let mut t = Table::new(
        name,
        caption,
        &[
            "system",
            "E_MED",
            "x0",
            "v0",
            "kinetic",
            "potential",
            "quasi-static barrier",
            "E_MED / barrier",
        ],
    );
    for (label, m) in rows {
        match m {
            Ok(m) => t.row(vec![
                label,
                f4(m.energy),
                f4(m.x0),
                f4(m.v0),
                f4(m.kinetic),
                f4(m.potential),
                f4(m.quasi_static_barrier),
                f4(m.energy / m.quasi_static_barrier),
            ]),
            Err(e) => t.row(vec![
                label,
                format!("failed: {e}"),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
            ]),
        }
    }
    t
}

/// Fig. 4/5 (a, b): potential and restoring force, truth vs models.
fn force_figures(
    st: &mut Study,
    prefix: &str,
    what: &str,
    t: &SdofTruth,
    fits: &[&SdofFit],
) -> Result<()> {
    let (lo, hi, n) = (-0.2, 1.9, 211);
    let mut pot = LineChart::new(
        format!("{what}: potential energy, truth vs models"),
        "h (length unit c0)",
        "potential V(h) per unit mass (c0²/s²)",
    )
    .with_series(
        Series::line(
            "truth (surrogate)",
            curve(lo, hi, n, |h| t.law.potential(h)),
        )
        .color(0),
    );
    let mut frc = LineChart::new(
        format!("{what}: restoring force, truth vs models"),
        "h (length unit c0)",
        "restoring force F(h) per unit mass (c0/s²)",
    )
    .with_series(Series::line("truth (surrogate)", curve(lo, hi, n, |h| t.law.force(h))).color(0));
    for (k, f) in fits.iter().enumerate() {
        let r = f.model.restoring("x")?;
        pot = pot.with_series(
            Series::dashed(
                format!("model {}", f.label),
                curve(lo, hi, n, |h| r.potential(h)),
            )
            .color(k + 1),
        );
        frc = frc.with_series(
            Series::dashed(
                format!("model {}", f.label),
                curve(lo, hi, n, |h| r.force(h)),
            )
            .color(k + 1),
        );
    }
    for (k, s) in t.wells.stable().iter().enumerate() {
        frc = frc.with_marker(*s, 0.0, format!("S{}", k + 1));
    }
    st.figure(
        &format!("{prefix}a_potential"),
        &format!("{what} (a): potential energy of the truth and the identified models"),
        pot,
    )?;
    st.figure(
        &format!("{prefix}b_force"),
        &format!("{what} (b): restoring force of the truth and the identified models"),
        frc,
    )?;
    Ok(())
}

fn state_names(w: &WellInfo) -> Vec<String> {
    w.stable()
        .iter()
        .enumerate()
        .map(|(k, s)| format!("S{} (h = {})", k + 1, fixed(*s, 3)))
        .collect()
}

/// Basin figures: truth, then each model with disagreement marks and the MED point.
fn basin_figures(
    st: &mut Study,
    prefix: &str,
    what: &str,
    t: &SdofTruth,
    tb: &TruthBasin,
    fits: &[&SdofFit],
) -> Result<()> {
    let axes = (
        "initial displacement x0 (length unit c0)",
        "initial velocity v0 (c0/s)",
    );
    let pts = vec![(tb.med.x0, tb.med.v0, format!("MED {:.3}", tb.med.energy))];
    let fig = basin_figure(
        &tb.map,
        &format!("{what}: BOA of the truth"),
        axes,
        &state_names(&t.wells),
        None,
        pts,
    );
    st.figure(
        &format!("{prefix}c_boa_truth"),
        &format!("{what}: basins of attraction of the truth (MED point marked)"),
        fig,
    )?;
    for (k, f) in fits.iter().enumerate() {
        if let Ok((w, map, cmp)) = &f.basin {
            let mut pts = Vec::new();
            if let Ok(m) = &f.med {
                pts.push((m.x0, m.v0, format!("MED {:.3}", m.energy)));
            }
            let fig = basin_figure(
                map,
                &format!(
                    "{what}: BOA of the {} model — BOA error {}",
                    f.label,
                    pct(cmp.error)
                ),
                axes,
                &state_names(w),
                Some(&cmp.disagree),
                pts,
            );
            let letter = (b'd' + k as u8) as char;
            st.figure(
                &format!("{prefix}{letter}_boa_{}", f.label.replace(' ', "_")),
                &format!("{what}: basins of attraction of the {} model; dark cells disagree with the truth (BOA error {})", f.label, pct(cmp.error)),
                fig,
            )?;
        }
    }
    Ok(())
}

/// Every BOA error is judged against the truth's own map: below the bound the paper's §5 states
/// for all of its cases.
pub const BOA_BOUND: f64 = 0.03;
/// The rule of [`BOA_BOUND`] as printed in the summary.
pub const BOA_RULE: &str = "below 3% of the grid (the paper's bound for every case, §5)";

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
    // ---- Table 1.
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
    // ---- BOA errors and MED.
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

/// Study 2: pink noise at 30 dB (Fig. 5).
pub fn study_pink(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(4, "§3.1 pink");
    let scale = o.pick(0.5, 1.0);
    let t = truth()?;
    st.text(format!(
        "{} Noise: pink (1/f) Gaussian at 30 dB on x and xb_acc.",
        truth_note(&t)
    ));
    let cfg = basin_cfg(o);
    pb.set_message("truth basin");
    let tb = truth_basin(&t, &cfg)?;
    pb.inc(1);
    pb.set_message("data");
    let (train, test) = records(&t, NoiseKind::Pink, 30.0, scale, 300)?;
    pb.inc(1);
    pb.set_message("identify");
    let f = fit_case("pink 30 dB", train, &test, &tb, &cfg)?;
    pb.inc(1);
    let (c, others, xb) = table1_coefs(&f.model);
    let mut tab = Table::new(
        "table_pink",
        "Pink noise 30 dB: coefficients in the Eq. 16 form (the paper gives no table for this case)",
        &[
            "source",
            "ζ",
            "α",
            "β",
            "γ",
            "other terms kept",
            "xb_acc coef",
        ],
    );
    tab.row(vec![
        "truth (our surrogate)".into(),
        f4(t.zeta),
        f4(t.coefs[0]),
        f4(t.coefs[1]),
        f4(t.coefs[2]),
        "none".into(),
        "-1".into(),
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
    tab.row(vec![
        "ours (T-F-S)".into(),
        f4(c[0]),
        f4(c[1]),
        f4(c[2]),
        f4(c[3]),
        oth,
        f4(xb),
    ]);
    st.table(tab)?;
    st.text(format!(
        "Equation identified: `{}`",
        f.model.equation_string()
    ));
    let e = f.basin.as_ref().map(|b| b.2.error).unwrap_or(f64::NAN);
    st.compare(
        "BOA error pink 30 dB",
        "0% (the truth's map)",
        &pct(e),
        "< 3% (§5: all BOA errors below 3%)",
        Some(e.is_finite() && e < BOA_BOUND),
        BOA_RULE,
    );
    st.table(med_table(
        "med_pink",
        "Minimum-energy deployment S1 → S2, pink noise 30 dB",
        vec![
            ("truth".into(), Ok(tb.med.clone())),
            (f.label.clone(), f.med.clone()),
        ],
    ))?;
    st.set("pink_30db", fit_json(&f));
    st.set("truth_med", med_json(&tb.med));
    force_figures(st, "fig5", "Fig. 5", &t, &[&f])?;
    basin_figures(st, "fig5", "Fig. 5", &t, &tb, &[&f])?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}

/// Study 4: Appendix B, Table B1 — classical SINDy vs T-F-S on the same 30 dB data.
pub fn study_table_b1(st: &mut Study, o: &Opts) -> Result<()> {
    let pb = progress(4, "App. B");
    let scale = o.pick(0.5, 1.0);
    let t = truth()?;
    pb.set_message("data");
    let (train, test) = records(&t, NoiseKind::White, 30.0, scale, 200)?;
    pb.inc(1);
    let samples: usize = train.iter().map(|r| r.len()).sum();
    st.text(format!(
        "Same 30 dB white-noise training data for both methods ({} records, {samples} samples; the paper had 200,020). T-F-S library `{TFS_LIBRARY}` (pipeline defaults); classical SINDy library `{SINDY_LIBRARY}` (36 columns as in the paper) on Savitzky–Golay derivatives, STLSQ with the threshold chosen on the last record held out. Time = wall time of the whole identification call on this machine (2 cores), median of three calls. R-MSE = Eq. B.2 on the test sweep, against the measured (noisy) displacement.",
        train.len()
    ));
    pb.set_message("T-F-S");
    // Each method is timed as the median of three calls on the same data, so neither pays a
    // one-off cost (FFT planning, thread-pool start) that the other does not.
    fn timed<T>(mut f: impl FnMut() -> Result<T>) -> Result<(T, f64)> {
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            last = Some(f()?);
            times.push(t0.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        Ok((last.expect("three runs"), times[1]))
    }
    let spec = IdentifySpec::new(&["x"], TFS_LIBRARY);
    let (a, t_tfs) = timed(|| identify_tfs(&train, &spec).context("T-F-S identification"))?;
    pb.inc(1);
    pb.set_message("classical SINDy");
    let spec_s = IdentifySpec::new(&["x"], SINDY_LIBRARY);
    let (b, t_sindy) =
        timed(|| identify_sindy(&train, &spec_s).context("classical SINDy identification"))?;
    pb.inc(1);
    let da = &a.trace.dofs[0];
    let tfs_rows = da.assembly.last().map_or(0, |s| s.rows);
    let tfs_cols = da.regression_library.len();
    // Classical SINDy regresses on every sample except the Savitzky–Golay trims at both ends.
    let trim = spec_s.sindy.savitzky_golay.map_or(1, |s| s.0);
    let sindy_rows: usize = train.iter().map(|r| r.len() - 2 * trim).sum();
    let sindy_cols = b.trace.dofs[0].library.len();
    let ra = sim_rmse(&a.model, &test, "x");
    let rb = sim_rmse(&b.model, &test, "x");
    let mut tab = Table::new(
        "table_b1",
        "Table B1: cost and accuracy of T-F-S vs classical SINDy on the same 30 dB data",
        &[
            "method",
            "library matrix (ours)",
            "time (ours)",
            "test R-MSE (ours)",
            "library matrix (paper)",
            "time (paper)",
            "R-MSE (paper)",
        ],
    );
    let show = |r: &std::result::Result<(f64, Vec<f64>), String>| {
        r.as_ref()
            .map(|r| f4(r.0))
            .unwrap_or_else(|e| format!("simulation failed: {e}"))
    };
    tab.row(vec![
        "T-F-S SINDy".into(),
        format!("{tfs_rows}×{tfs_cols}"),
        format!("{t_tfs:.3} s"),
        show(&ra),
        "2143×28".into(),
        "4.4 s".into(),
        "0.0045".into(),
    ]);
    tab.row(vec![
        "classical SINDy".into(),
        format!("{sindy_rows}×{sindy_cols}"),
        format!("{t_sindy:.3} s"),
        show(&rb),
        "200,020×36".into(),
        "120.72 s".into(),
        "0.0332".into(),
    ]);
    st.table(tab)?;
    st.text(format!(
        "T-F-S model: `{}`\n\nClassical SINDy model: `{}`\n\nT-F-S rows are the frequency-domain rows (real and imaginary parts of the kept bins) of the records used by the final fit; its columns are the library after Criterion 2 ({} of {}).\n\nThe paper's cost argument is that T-F-S regresses on a much smaller matrix, which its sparsification solves again for every threshold; that is the check above. The times are shown, not judged: both methods take well under a second here, and our classical SINDy folds its rows into a small triangular factor in one pass before it sparsifies, so its regression no longer grows with the 200,020 rows that cost the paper's implementation two minutes. Most of T-F-S's time goes to its criteria (the noise curve of Criterion 1 and the transforms of Criterion 3), not to regression.",
        a.model.equation_string(),
        b.model.equation_string(),
        tfs_cols,
        da.library.len()
    ));
    let (ea, eb) = (ra.as_ref().map(|r| r.0).ok(), rb.as_ref().map(|r| r.0).ok());
    let better = match (ea, eb) {
        (Some(x), Some(y)) => x < y,
        (Some(_), None) => true,
        _ => false,
    };
    st.compare(
        "Table B1: test R-MSE, T-F-S vs classical",
        "0 (the measured test sweep)",
        &format!(
            "{} vs {}",
            ea.map_or("—".into(), f4),
            eb.map_or("blew up".into(), f4)
        ),
        "0.0045 vs 0.0332",
        Some(better),
        "T-F-S lower than classical SINDy",
    );
    // The paper's cost claim is its mechanism: the criteria shrink the regression problem that
    // the sparsification solves again and again. That is what is checked. The wall times are
    // shown beside the paper's but judge nothing: a timing on a shared machine is not a pass or
    // fail (the report's exit code must not depend on the load), and our classical SINDy folds
    // its rows into a small triangle in one pass before sparsifying, so it no longer pays for
    // its row count the way the paper's did.
    st.compare(
        "Table B1: regression matrix, T-F-S vs classical",
        "—",
        &format!("{tfs_rows}×{tfs_cols} vs {sindy_rows}×{sindy_cols}"),
        "2143×28 vs 200,020×36",
        Some(tfs_rows * tfs_cols < sindy_rows * sindy_cols),
        "T-F-S regresses on a smaller matrix than classical SINDy",
    );
    st.compare(
        "Table B1: fit time, T-F-S vs classical",
        "—",
        &format!("{t_tfs:.3} s vs {t_sindy:.3} s"),
        "4.4 s vs 120.72 s",
        None,
        "informational: wall time on this machine, not a check",
    );
    st.set("tfs", json!({"rows": tfs_rows, "cols": tfs_cols, "seconds": t_tfs, "test_r_mse": ea.map(num), "r_mse_error": ra.as_ref().err(), "equation": a.model.equation_string()}));
    st.set("sindy", json!({"rows": sindy_rows, "cols": sindy_cols, "seconds": t_sindy, "test_r_mse": eb.map(num), "blew_up": eb.is_none(), "r_mse_error": rb.as_ref().err(), "equation": b.model.equation_string()}));
    st.set("paper", json!({"tfs": {"rows": 2143, "cols": 28, "seconds": 4.4, "r_mse": 0.0045}, "sindy": {"rows": 200020, "cols": 36, "seconds": 120.72, "r_mse": 0.0332}}));
    // Figure: test responses.
    let tt = test.t();
    let meas = test.column("x").unwrap_or_default();
    let step = (tt.len() / 3000).max(1);
    let sub = |y: &[f64]| -> Vec<(f64, f64)> {
        tt.iter()
            .zip(y)
            .step_by(step)
            .map(|(a, b)| (*a, *b))
            .collect()
    };
    let mut ch = LineChart::new(
        "Appendix B: test sweep, measured vs simulated models",
        "t (s)",
        "x (length unit c0)",
    )
    .with_series(Series::line("measured (30 dB)", sub(meas)).color(0));
    if let Ok((_, p)) = &ra {
        ch = ch.with_series(Series::dashed("T-F-S model", sub(p)).color(1));
    }
    // A classical fit that kept no term (`x'' = 0`) simulates as uniform motion from its fitted
    // start: a straight line, which the legend and the text say instead of leaving unexplained.
    let empty = b.model.equations.iter().all(|e| e.terms.is_empty());
    if let Ok((_, p)) = &rb {
        let name = if empty {
            "classical SINDy model (x'' = 0: a straight line from its start)"
        } else {
            "classical SINDy model"
        };
        ch = ch.with_series(Series::dashed(name, sub(p)).color(3));
    }
    if empty {
        st.text("The classical SINDy fit kept no term at this noise level (`x'' = 0`): on Savitzky–Golay derivatives of 30 dB data, the threshold chosen on the held-out record removes every column, so its simulation keeps the starting state fitted to the record's first periods, moving at that constant velocity — the straight (or, with zero starting velocity, flat) line in the figure below, and its large test R-MSE.");
    }
    st.figure(
        "figB1_test_response",
        "Appendix B: the test sweep simulated by both models beside the measured response",
        ch,
    )?;
    pb.inc(1);
    pb.finish_and_clear();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table1_coefs_reads_the_paper_form() {
        let lib = tfs::library::Library::parse(TFS_LIBRARY, &["x"]).unwrap();
        // x^1..7, x', xb_acc
        let m = Model::from_coefficients(
            &lib,
            &[vec![0.0, 0.0, 0.5, 0.0, -12.0, 18.0, -6.5, -2.0, -1.0]],
            "t",
        )
        .unwrap();
        let (c, others, xb) = table1_coefs(&m);
        assert_eq!(c, [2.0, 12.0, -18.0, 6.5]);
        assert_eq!(others, vec![("x^3".to_string(), 0.5)]);
        assert_eq!(xb, -1.0);
    }
}
