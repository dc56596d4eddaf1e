//! §3.1 (white noise, Table 1, Figs 3–4), §3.1 pink noise (Fig. 5) and Appendix B (Table B1):
//! the bistable Kresling cell under its surrogate truth.
//!
//! The studies live in one file each ([`white`], [`pink`], [`table_b1`]); this module holds what
//! they share: the truth, the records, the fits, the tables and the figures they all draw.

mod b1_pysindy;
mod pink;
mod table_b1;
mod white;

pub use pink::study_pink;
pub use table_b1::study_table_b1;
pub use white::study_white;

use std::time::Instant;

use anyhow::{Context, Result, anyhow};
use serde_json::{Value, json};
use tfs::basin::{
    BasinConfig, BasinMap, BoaComparison, Med, WellInfo, basin_sdof, compare, med_sdof,
};
use tfs::criteria::{IdentifySpec, Trace, identify_tfs};
use tfs::data::Record;
use tfs::library::Model;
use tfs::origami::{
    CellForce, CellSpec, Chain, DatasetConfig, Excitation, NoiseKind, SystemSpec, Truth,
    build_system, generate,
};
use tfs::plot::{LineChart, Series};

use crate::common::{
    Opts, basin_figure, coef, curve, f4, fixed, model_json, model_wells, num, pct, sim_rmse, terms,
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
