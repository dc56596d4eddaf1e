//! Criterion 1: the noise level index κ of `B = [Θ | x'']` on the measured data of every record,
//! its threshold κ0 (given, or calibrated by adding known noise to the user's own data) and the
//! verdict high/low SNR. κ numerics in [`kappa`], the κ0 calibration in [`calibration`].

pub(crate) mod calibration;
pub(crate) mod cause;
pub(crate) mod kappa;

use faer::Mat;
use rayon::prelude::*;
use tfs_data::Record;
use tfs_library::Library;
use tfs_regress::Compressed;

use crate::blocks::{OwnedColumns, Prepared};
use crate::error::{CriteriaError, Result, invalid};
use crate::options::{Checked, Kappa0Choice};
use crate::trace::Support;
use kappa::{Criterion1, noise_level_index_factor};

/// Criterion 1 of one DOF: the verdict, the centred factor Criterion 2 prunes on (empty unless
/// pruning) and the library's non-constant columns.
pub(crate) struct Criterion1Out {
    /// The verdict.
    pub verdict: Criterion1,
    /// The small centred factor of `[Θ | x'']` over the non-constant columns.
    pub factor: Mat<f64>,
    /// The library's non-constant columns.
    pub nonconst: Vec<usize>,
}

/// The library's non-constant columns.
pub(crate) fn nonconstant_columns(lib: &Library) -> Vec<usize> {
    (0..lib.len())
        .filter(|&j| !lib.terms()[j].is_constant())
        .collect()
}

/// The error for library term `j` of `dof`'s equation, which takes the single value `value` on
/// every row of every record: nothing can be identified about it (the classical fit checks the
/// same).
pub(crate) fn single_valued<T>(lib: &Library, j: usize, dof: &str, value: f64) -> Result<T> {
    invalid(format!(
        "library term '{}' of the equation of '{dof}' takes the single value {value} on every record (for a stop below(x, c) or above(x, c): the data never reach c); drop it from the library",
        lib.terms()[j]
    ))
}

/// Criterion 1 for DOF `d` as a pass reports it: `given` (the elimination's re-runs keep the
/// first pass's verdict, its support verdict cleared for this pass to fill) or computed by
/// [`criterion1_dof`].
pub(crate) fn criterion1_stage(
    given: Option<&Criterion1>,
    blocks: &[Record],
    preps: &[Prepared<'_>],
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
) -> Result<Criterion1Out> {
    Ok(match given {
        Some(given) => {
            let mut given = given.clone();
            given.support = Support::Undecided;
            Criterion1Out {
                verdict: given,
                factor: Mat::<f64>::zeros(0, 0),
                nonconst: nonconstant_columns(lib),
            }
        }
        None => criterion1_dof(blocks, preps, spec, d, lib)?,
    })
}

/// Small centred factor of `[Θ | y]` over several blocks: compress `[1 | Θ]` against `y` and drop
/// the constant's row and column.
fn centred_factor(blocks: &[(Mat<f64>, Vec<f64>)], cols: &[usize]) -> Result<Mat<f64>> {
    let comps = blocks
        .par_iter()
        .map(|(a, y)| {
            let aa = Mat::<f64>::from_fn(a.nrows(), cols.len() + 1, |i, j| {
                if j == 0 { 1.0 } else { a[(i, cols[j - 1])] }
            });
            Compressed::from_rows(aa.as_ref(), y)
        })
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let c = Compressed::merge(&comps)?;
    let n = cols.len() + 1;
    let r = c.r();
    let cv = c.c();
    let rho = c.rss0().max(0.0).sqrt();
    Ok(Mat::<f64>::from_fn(n, n, |i, j| {
        let (ii, jj) = (i + 1, j + 1);
        if jj < n {
            if ii <= jj { r[(ii, jj)] } else { 0.0 }
        } else if ii < n {
            cv[ii]
        } else {
            rho
        }
    }))
}

/// Criterion 1's raw block of one record (see [`raw_columns`]): 2 % trimmed at each end and
/// at most ~2000 rows (enough for κ against the verdict's margin; see `docs/DECISIONS.md`).
fn criterion1_block(
    r: &Record,
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
) -> Result<(Mat<f64>, Vec<f64>)> {
    let (cols, acc) = criterion1_columns(r, spec, d, lib)?;
    Ok((lib.evaluate(&cols)?, acc))
}

/// The columns [`criterion1_block`] evaluates the library on, and its `x''` (see
/// [`raw_columns`]).
pub(crate) fn criterion1_columns(
    r: &Record,
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
) -> Result<(OwnedColumns, Vec<f64>)> {
    raw_columns(
        r,
        &spec.dofs,
        d,
        lib,
        spec.tfs.criterion3.savitzky_golay,
        (r.len() / 50).max(4),
        (r.len() / 2000).max(1),
    )
}

/// Criterion 1 for DOF `d`: κ of the time-domain blocks `(Θ, x'')` of every record built from
/// the measured data (see [`raw_columns`]; constant columns excluded), κ0 (given or
/// calibrated by adding noise to the same kind of block) and the verdict, with the centred factor
/// Criterion 2 prunes on and the non-constant columns. Shared by [`identify_tfs`] and the tied
/// chain fit.
pub(crate) fn criterion1_dof(
    blocks: &[Record],
    preps: &[Prepared<'_>],
    spec: &Checked<'_>,
    d: usize,
    lib: &Library,
) -> Result<Criterion1Out> {
    let opt = &spec.tfs;
    let nonconst = nonconstant_columns(lib);
    let td: Vec<(Mat<f64>, Vec<f64>)> = blocks
        .par_iter()
        .with_max_len(1)
        .map(|r| criterion1_block(r, spec, d, lib))
        .collect::<Result<_>>()?;
    // A column that takes one value on every row (a stop the data never reach, an input that
    // does not move) can be identified from nothing: say which term it is.
    for &j in &nonconst {
        let (lo, hi) = td
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, _)| {
                a.col_as_slice(j)
                    .iter()
                    .fold((lo, hi), |(lo, hi), &v| (lo.min(v), hi.max(v)))
            });
        if lo == hi {
            return single_valued(lib, j, &spec.dofs[d], lo);
        }
    }
    // The centred factor is needed only by Criterion 2's pruning; κ alone has a cheaper route.
    // The calibration's noisy copies do not depend on the records' κ: both run at once.
    let (records, points) = rayon::join(
        || -> Result<_> {
            Ok(if opt.criterion2.prune {
                criterion1_blocks(&td, &nonconst)?
            } else {
                (criterion1_kappa(&td, &nonconst)?, Mat::<f64>::zeros(0, 0))
            })
        },
        || match opt.criterion1.kappa0 {
            Kappa0Choice::Fixed(_) => Ok(None),
            Kappa0Choice::Calibrate => {
                calibration::calibration_points(blocks, spec, d, lib, &nonconst).map(Some)
            }
        },
    );
    let (kappa, factor) = records?;
    let cal = match (opt.criterion1.kappa0, points?) {
        (Kappa0Choice::Fixed(k), _) => calibration::Calibration {
            kappa0: k,
            source: kappa::Kappa0Source::Given,
            curve: Vec::new(),
            knee_snr_db: None,
        },
        (_, Some((seg_kappa, points))) => calibration::calibrate(kappa, seg_kappa, points, opt),
        (_, None) => return invalid("κ0 calibration gave no points"),
    };
    let kappa0 = cal.kappa0;
    let kv = kappa.get(opt.criterion1.kappa_variant);
    let high_snr = kv >= kappa0;
    // Below κ0, the records' own noise estimate says whether noise or the library is the cause.
    let snr = if high_snr {
        cause::SnrVerdict::High
    } else {
        cause::low_kappa_cause(
            &td,
            &nonconst,
            preps,
            (&spec.dofs, d, lib),
            opt.criterion3.savitzky_golay,
        )
        .unwrap_or(cause::SnrVerdict::Undetermined {
            reason: "the least-squares residual or the band-limited blocks failed",
        })
    };
    let c1 = Criterion1 {
        kappa,
        variant: opt.criterion1.kappa_variant,
        kappa0,
        kappa0_source: cal.source,
        high_snr,
        snr,
        curve: cal.curve,
        knee_snr_db: cal.knee_snr_db,
        estimated_snr_db: estimated_snr_db(preps, &spec.dofs[d], d),
        support: Support::Undecided,
    };
    Ok(Criterion1Out {
        verdict: c1,
        factor,
        nonconst,
    })
}

/// κ alone of time-domain blocks `(Θ, x'')` (constant columns excluded): from the Gram matrix
/// of the centred, standardised columns where that is accurate (see
/// [`kappa::kappa_by_gram`]), otherwise from the centred factor as
/// [`criterion1_blocks`].
pub(crate) fn criterion1_kappa(
    blocks: &[(Mat<f64>, Vec<f64>)],
    cols: &[usize],
) -> Result<kappa::Kappa> {
    match kappa::kappa_by_gram(blocks, cols)? {
        Some(k) => Ok(k),
        None => Ok(criterion1_blocks(blocks, cols)?.0),
    }
}

/// Criterion 1 on time-domain blocks `(Θ, x'')` (constant columns excluded).
fn criterion1_blocks(
    blocks: &[(Mat<f64>, Vec<f64>)],
    cols: &[usize],
) -> Result<(kappa::Kappa, Mat<f64>)> {
    let f = centred_factor(blocks, cols)?;
    Ok((noise_level_index_factor(f.as_ref())?, f))
}

/// The SNR (dB) of DOF `d`'s displacement over all records, estimated from the fitted noise
/// floors: total signal power over total noise power (`None` without a noise estimate). Where a
/// record's spectrum shows no noise floor (its upper half is the signal's own tail), its noise is
/// bounded from above by white noise at the lowest level the spectrum reaches, and the result is
/// a lower bound (an extrapolated floor would read clean records as 25–45 dB).
pub(crate) fn estimated_snr_db(
    preps: &[Prepared<'_>],
    dof: &str,
    d: usize,
) -> Option<crate::trace::SnrEstimate> {
    let channels: Vec<(&[f64], &tfs_signal::Band)> = preps
        .iter()
        .map(|p| Some((p.rec.column(dof)?, &p.smooth[d].band)))
        .collect::<Option<_>>()?;
    tfs_signal::estimate::snr_db(channels)
}

/// The columns of Criterion 1's time-domain block `(Θ, x'')` of DOF `dof` on the *measured*
/// data, as the paper builds it (the library is then evaluated on them): the recorded
/// displacements and inputs, velocities and `x''` by Savitzky–Golay differentiation (`sg` = half
/// window, order), `trim` samples cut at both ends and every `stride`-th row kept. Returns the
/// columns (every DOF, its velocity and the inputs the library reads) and `x''` of DOF `dof`.
/// The noise of the measurement (amplified by the differentiation) is what κ is meant to see;
/// the band-limited reconstruction removes most of it, so κ on the reconstruction hardly moves
/// when noise is added and cannot calibrate κ0. Every column is linear in the record's columns:
/// the columns of a record plus `s` times another are those of the first plus `s` times those
/// of the second.
pub(crate) fn raw_columns(
    rec: &Record,
    dofs: &[String],
    dof: usize,
    lib: &Library,
    sg: (usize, usize),
    trim: usize,
    stride: usize,
) -> Result<(OwnedColumns, Vec<f64>)> {
    let dt = rec.dt();
    let n = rec.len();
    let trim = trim.max(sg.0 + 1);
    if n <= 2 * trim + lib.len() + 2 {
        return Err(CriteriaError::Invalid(format!(
            "record '{}' is too short ({n} samples) for a library of {} terms",
            rec.source(),
            lib.len()
        )));
    }
    let stride = stride.max(1);
    let at: Vec<usize> = (trim..n - trim).step_by(stride).collect();
    // The derivatives are needed only at the kept rows, all at least a half window from the ends:
    // centred Savitzky–Golay weights applied there (the same values `savitzky_golay` gives).
    let (h, order) = sg;
    let w1 = tfs_signal::savitzky_golay_weights(h, order, 1, h)?;
    let w2 = tfs_signal::savitzky_golay_weights(h, order, 2, h)?;
    let apply = |w: &[f64], x: &[f64], scale: f64| -> Vec<f64> {
        at.iter()
            .map(|&i| {
                w.iter()
                    .zip(&x[i - h..=i + h])
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
                    / scale
            })
            .collect()
    };
    let sub = |v: &[f64]| -> Vec<f64> { at.iter().map(|&i| v[i]).collect() };
    let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
    let mut acc = Vec::new();
    for (i, d) in dofs.iter().enumerate() {
        let x = rec.column(d).expect("checked");
        cols.push((d.clone(), sub(x)));
        cols.push((format!("{d}'"), apply(&w1, x, dt)));
        if i == dof {
            acc = apply(&w2, x, dt * dt);
        }
    }
    for name in lib.required_columns() {
        if cols.iter().any(|(c, _)| *c == name) {
            continue;
        }
        if let Some(v) = rec.column(&name) {
            cols.push((name.clone(), sub(v)));
        }
    }
    Ok((
        OwnedColumns {
            rows: at.len(),
            cols,
        },
        acc,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::raw_columns_sg;
    use tfs_data::Columns;
    use tfs_signal::NoiseKind;
    use tfs_signal::noise::noise_for;

    /// Criterion 1's block evaluates Savitzky–Golay derivatives only at the kept rows; it equals
    /// the full-length derivatives of `raw_columns_sg` (with asymmetric end fits) sampled there.
    #[test]
    fn raw_block_matches_full_savitzky_golay_at_the_kept_rows() {
        let n = 3000;
        let dt = 0.01;
        let e = gauss(n, 5);
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let x: Vec<f64> = t
            .iter()
            .zip(&e)
            .map(|(t, e)| (1.3 * t).sin() + 0.2 * (4.1 * t).cos() + 0.01 * e)
            .collect();
        let u: Vec<f64> = t.iter().map(|t| (0.7 * t).cos()).collect();
        let rec = Record::new("r", t, vec![("x".into(), x), ("xb_acc".into(), u)]).unwrap();
        let dofs = vec!["x".to_string()];
        let lib = Library::parse("x^1..3, x', x*x', xb_acc", &["x"]).unwrap();
        let (trim, stride) = (60, 7);
        let (cols, y) = raw_columns(&rec, &dofs, 0, &lib, (12, 3), trim, stride).unwrap();
        let a = lib.evaluate(&cols).unwrap();
        let (cs, acc) = raw_columns_sg(&rec, &dofs, 0, dt, (12, 3)).unwrap();
        let full = lib
            .evaluate(&OwnedColumns {
                rows: n,
                cols: lib
                    .required_columns()
                    .into_iter()
                    .map(|c| (c.clone(), cs.column(&c).unwrap().to_vec()))
                    .collect(),
            })
            .unwrap();
        let rows: Vec<usize> = (trim..n - trim).step_by(stride).collect();
        assert_eq!(a.nrows(), rows.len());
        for (r, &i) in rows.iter().enumerate() {
            assert!((y[r] - acc[i]).abs() <= 1e-9 * acc[i].abs().max(1.0));
            for j in 0..lib.len() {
                let (p, q) = (a[(r, j)], full[(i, j)]);
                assert!(
                    (p - q).abs() <= 1e-9 * q.abs().max(1.0),
                    "row {i}, column {j}: {p} vs {q}"
                );
            }
        }
    }

    /// Unit-variance white noise (seeded).
    fn gauss(n: usize, seed: u64) -> Vec<f64> {
        noise_for(&vec![1.0; n], 0.0, NoiseKind::White, seed).expect("noise")
    }
}
