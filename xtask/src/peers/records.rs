//! The truth of the peers comparison and the CSV records both sides read, and the scores of one model.

use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};
use tfs::basin::{BasinConfig, WellInfo, basin_sdof, compare};
use tfs::data::{Record, write_csv};
use tfs::dynamics::{SimulateOptions, rmse_ratio, simulate_model_on_record};
use tfs::library::{Equation, Model, ModelTerm, Term};
use tfs::origami::{
    CellForce, CellSpec, DatasetConfig, Excitation, NoiseKind, SystemSpec, Truth, build_system,
    generate,
};

use super::{Case, DT, FORCE_RANGE, RAMP, SEARCH, Score, TEST, TRAIN, TruthSet};

pub(super) fn truth_set(cfg: &BasinConfig) -> Result<TruthSet> {
    let spec = SystemSpec::Kresling(CellSpec {
        truth: Truth::Surrogate,
        ..Default::default()
    });
    let sys = build_system(&spec)?;
    let cell = &sys.cells()[0];
    let law = cell.force_law().clone();
    let mass = cell.mass();
    let (l1, l2) = (law.clone(), law.clone());
    let wells = WellInfo::from_force(move |x| l1.force(x), move |x| l2.potential(x), SEARCH, mass)?;
    let map = basin_sdof(&sys, &wells, cfg, None).context("truth basin map")?;
    Ok(TruthSet {
        spec,
        law,
        mass,
        map,
    })
}

/// The truth written as a model (`x'' = −(c/m)·x' − F(x)/m − xb_acc`, the surrogate's powers and
/// coefficients as computed at run time): scored beside the identified models, its test R-MSE
/// is the floor that the measured (noisy) test input alone sets.
pub(super) fn truth_model(truth: &TruthSet) -> Result<Model> {
    let sys = build_system(&truth.spec)?;
    let cell = &sys.cells()[0];
    let CellForce::Surrogate(sur) = &truth.law else {
        bail!("the peers truth is the surrogate force law");
    };
    let m = cell.mass();
    let dofs = ["x".to_string()];
    let term = |t: &str| Term::parse(t, &dofs).map_err(anyhow::Error::from);
    let mut terms = vec![
        ModelTerm::new(term("x'")?, -cell.damping() / m),
        ModelTerm::new(term("xb_acc")?, -1.0),
    ];
    for (&p, &c) in sur.spec.powers.iter().zip(&sur.coefs) {
        terms.push(ModelTerm::new(term(&format!("x^{p}"))?, -c / m));
    }
    Ok(Model::new(
        dofs.to_vec(),
        vec![Equation {
            dof: "x".into(),
            terms,
        }],
        "truth",
    )?)
}

/// Simulates the five records of `case`, writes `train1..4.csv` and `test.csv` (t, x, xb_acc:
/// the measured columns only) into `dir`; returns the noise-free test displacement.
pub(super) fn write_records(
    truth: &TruthSet,
    case: Case,
    scale: f64,
    seed: u64,
    dir: &Path,
) -> Result<Vec<f64>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut clean_test = Vec::new();
    for (i, &(f0, f1, d, a)) in TRAIN.iter().chain(std::iter::once(&TEST)).enumerate() {
        let cfg = DatasetConfig {
            system: truth.spec.clone(),
            excitations: vec![Excitation::Sweep {
                f0,
                f1,
                amplitude: a,
                log: false,
                ramp: RAMP,
            }],
            duration: d * scale,
            dt: DT,
            snr_db: Some(case.snr),
            noise: if case.pink {
                NoiseKind::Pink
            } else {
                NoiseKind::White
            },
            seed: seed + 17 * i as u64,
            x0: None,
            v0: None,
            rtol: 1e-9,
        };
        let ds = generate(&cfg).with_context(|| format!("simulating sweep {}", i + 1))?;
        let r = &ds.records[0];
        let col = |n: &str| {
            r.column(n)
                .map(<[f64]>::to_vec)
                .ok_or_else(|| anyhow!("generated record has no column '{n}'"))
        };
        let name = if i < TRAIN.len() {
            format!("train{}", i + 1)
        } else {
            "test".to_string()
        };
        let rec = Record::new(
            &name,
            r.t().to_vec(),
            vec![("x".into(), col("x")?), ("xb_acc".into(), col("xb_acc")?)],
        )?;
        write_csv(dir.join(format!("{name}.csv")), &rec)?;
        if i == TRAIN.len() {
            clean_test = col("x_clean")?;
        }
    }
    Ok(clean_test)
}

/// The three scores of `model` (same code for every method).
pub(super) fn score(
    model: &Model,
    truth: &TruthSet,
    cfg: &BasinConfig,
    test: &Record,
    clean_test: &[f64],
) -> Score {
    let force_error = (|| -> Result<f64> {
        let r = model.restoring("x")?;
        let (mut num, mut den) = (0.0, 0.0);
        let n = 361;
        for i in 0..n {
            let h = FORCE_RANGE.0 + (FORCE_RANGE.1 - FORCE_RANGE.0) * i as f64 / (n - 1) as f64;
            let ft = truth.law.force(h) / truth.mass;
            num += (r.force(h) - ft).powi(2);
            den += ft * ft;
        }
        Ok((num / den).sqrt())
    })()
    .unwrap_or(f64::NAN);
    let boa_error = (|| -> Result<f64> {
        let r = model.restoring("x")?;
        let r2 = r.clone();
        let wells =
            WellInfo::from_force(move |x| r.force(x), move |x| r2.potential(x), SEARCH, 1.0)
                .context("equilibria of the model")?;
        let sys = model.compile()?;
        // The early exit needs a dissipative model; one with velocity-dependent stiffness may not
        // be, and is then integrated to t_max instead (same labels, slower).
        let map = match basin_sdof(&sys, &wells, cfg, None) {
            Ok(m) => m,
            Err(_) if cfg.early_exit => {
                let mut full = cfg.clone();
                full.early_exit = false;
                basin_sdof(&sys, &wells, &full, None)?
            }
            Err(e) => return Err(e.into()),
        };
        Ok(compare(&map, &truth.map)?.error)
    })()
    .map_err(|e| format!("{e:#}"));
    let r_mse = (|| -> Result<f64> {
        let tr = simulate_model_on_record(model, test, &SimulateOptions::default())?;
        Ok(rmse_ratio(clean_test, &tr.x[0])?)
    })()
    .map_err(|e| format!("{e:#}"));
    Score {
        force_error,
        boa_error,
        r_mse,
    }
}
