//! The classical SINDy baseline (Appendix B): numerical derivatives of the raw data, the library
//! in the time domain, STLSQ with the threshold chosen on the last record held out (or given).

use std::time::Instant;

use faer::{ColRef, MatMut};
use rayon::prelude::*;
use tfs_data::Record;
use tfs_library::{Equation, Library, ModelTerm};
use tfs_regress::{Compressed, PathOptions, Regressor, Stlsq, lambda_path, lstsq_support};

use crate::blocks::{blocks_of, check_record, raw_columns_sg};
use crate::criterion3::TransformForm;
use crate::error::Result;
use crate::fit::path_opts;
use crate::options::IdentifySpec;
use crate::pipeline::{finish, ms};
use crate::trace::{
    AssemblyVerdict, ChosenSettings, Criterion4Outcome, DofTrace, Identified, Method,
};

/// Classical SINDy (Appendix B): numerical derivatives of the raw data, the library in the time
/// domain, STLSQ with the threshold chosen on the last record held out (or given).
pub fn identify_sindy(records: &[Record], spec: &IdentifySpec) -> Result<Identified> {
    let t_all = Instant::now();
    let libs = spec.libraries()?;
    let blocks = blocks_of(records)?;
    let opt = &spec.sindy;
    let mut equations = Vec::new();
    let mut dof_traces = Vec::new();
    let mut timing = Vec::new();
    for (d, lib) in libs.iter().enumerate() {
        let t0 = Instant::now();
        // Each record is compressed on its own, so the records go in parallel (collected in
        // order, the first error in record order: the same result on any number of threads).
        check_terms_vary(&blocks, spec, d, lib)?;
        let comps: Vec<Result<Compressed>> = blocks
            .par_iter()
            .map(|r| record_compressed(r, spec, d, lib))
            .collect();
        let comps = comps.into_iter().collect::<Result<Vec<_>>>()?;
        timing.push((format!("{}: library and compression", spec.dofs[d]), ms(t0)));
        let t0 = Instant::now();
        let nb = comps.len();
        let (coef, thr, why) = match opt.threshold {
            Some(t) => {
                let all = Compressed::merge(&comps)?;
                let f = Stlsq {
                    threshold: t,
                    ..Stlsq::default()
                }
                .fit_compressed(&all)?;
                (f.coef, t, "STLSQ threshold given by the user".to_string())
            }
            None => {
                let train = Compressed::merge(&comps[..nb - 1])?;
                // The paper's baseline keeps the plain grid: on clean records its derivative
                // error is systematic, and a grid reaching below the largest share lets BIC
                // pick up tiny spurious powers (the extension is T-F-S's own).
                let opts = PathOptions {
                    extend_when_cancelling: false,
                    ..path_opts(opt.n_thresholds)
                };
                let path = lambda_path(&train, &comps[nb - 1], &opts)?;
                let b = path.best();
                let all = Compressed::merge(&comps)?;
                let f = lstsq_support(&all, &b.support)?;
                (
                    f.coef,
                    b.threshold,
                    format!(
                        "STLSQ threshold {:.4} (scaled): BIC on held-out '{}', coefficients refit on all records",
                        b.threshold,
                        blocks[nb - 1].source()
                    ),
                )
            }
        };
        timing.push((format!("{}: regression", spec.dofs[d]), ms(t0)));
        let terms = lib
            .terms()
            .iter()
            .zip(&coef)
            .filter(|(_, c)| **c != 0.0)
            .map(|(t, c)| ModelTerm::new(t.clone(), *c))
            .collect();
        equations.push(Equation {
            dof: spec.dofs[d].clone(),
            terms,
        });
        dof_traces.push(DofTrace {
            dof: spec.dofs[d].clone(),
            library: lib.names(),
            offered_library: None,
            criterion1: None,
            criterion2: None,
            regression_library: lib.names(),
            bins: Vec::new(),
            settings: ChosenSettings {
                form: TransformForm::PlainSavitzkyGolay,
                delta: 0.0,
                windows: 0,
                threshold: thr,
                candidates: Vec::new(),
                coefficient_candidates: Vec::new(),
                why: vec![why],
            },
            assembly: Vec::new(),
            assembly_verdict: AssemblyVerdict::new(Criterion4Outcome::NotUsed),
            held_out_record: blocks[nb - 1].source().to_string(),
            term_test: None,
        });
    }
    finish(
        Method::Sindy,
        &spec.dofs,
        equations,
        dof_traces,
        timing,
        t_all,
    )
}

/// Refuses a library term of DOF `d`'s equation that takes one value on every row of every
/// record (a stop the data never reach, an input that does not move): nothing can be identified
/// about it, and the regression would otherwise stop in its own words.
fn check_terms_vary(blocks: &[Record], spec: &IdentifySpec, d: usize, lib: &Library) -> Result<()> {
    let mut range = vec![(f64::INFINITY, f64::NEG_INFINITY); lib.len()];
    for r in blocks {
        let dt = check_record(r, &spec.dofs)?;
        let mut cs = tfs_library::ColumnSet::new(r as &dyn tfs_data::Columns);
        for dn in &spec.dofs {
            let x = r.column(dn).expect("checked");
            cs.insert(format!("{dn}'"), tfs_signal::central_difference(x, dt, 1)?)?;
        }
        let a = lib.evaluate(&cs)?;
        for (j, (lo, hi)) in range.iter_mut().enumerate() {
            for &v in a.col_as_slice(j) {
                *lo = lo.min(v);
                *hi = hi.max(v);
            }
        }
    }
    for (j, &(lo, hi)) in range.iter().enumerate() {
        if lo == hi && !lib.terms()[j].is_constant() {
            return crate::criterion1::single_valued(lib, j, &spec.dofs[d], lo);
        }
    }
    Ok(())
}

/// The compression of one record's rows for DOF `d`: numerical derivatives, then the library
/// built a chunk of rows at a time straight into the compression (the whole library matrix of
/// the record never exists; same factor, to the bit), or whole when a term has an internal
/// state (which needs the record's history).
fn record_compressed(
    r: &Record,
    spec: &IdentifySpec,
    d: usize,
    lib: &Library,
) -> Result<Compressed> {
    let opt = &spec.sindy;
    let dt = check_record(r, &spec.dofs)?;
    let (cs, acc) = match opt.savitzky_golay {
        Some(sg) => raw_columns_sg(r, &spec.dofs, d, dt, sg)?,
        None => {
            let mut cs = tfs_library::ColumnSet::new(r as &dyn tfs_data::Columns);
            let mut acc = Vec::new();
            for (i, dn) in spec.dofs.iter().enumerate() {
                let x = r.column(dn).expect("checked");
                cs.insert(format!("{dn}'"), tfs_signal::central_difference(x, dt, 1)?)?;
                if i == d {
                    acc = tfs_signal::central_difference(x, dt, 2)?;
                }
            }
            (cs, acc)
        }
    };
    let trim = opt.savitzky_golay.map_or(1, |s| s.0);
    let m = r.len() - 2 * trim;
    if !lib.is_row_local() {
        let a = lib.evaluate(&cs)?;
        let at = a.as_ref().subrows(trim, m);
        return Ok(Compressed::from_rows(at, &acc[trim..trim + m])?);
    }
    let n = lib.len();
    Compressed::from_chunks(n, m, |start, mut chunk: MatMut<'_, f64>| -> Result<()> {
        let rows = trim + start..trim + start + chunk.nrows();
        lib.evaluate_rows(&cs, rows.clone(), chunk.as_mut().get_mut(.., ..n))?;
        chunk.col_mut(n).copy_from(ColRef::from_slice(&acc[rows]));
        Ok(())
    })
}
