//! Errors-in-variables correction of the final coefficients (corrected least squares).
//!
//! The frequency-domain rows are built from the band-limited reconstruction `x̂ = x + e`, and the
//! noise `e` left in the band enters both sides of the regression: the `x''` row and every column
//! that uses `x̂` or `x̂'`. The Hermite debiasing of single powers removes the *mean* bias of
//! `x̂^k`, but not the noise *variance* in the normal equations:
//! `E[AᵀA] = A₀ᵀA₀ + D` and `E[Aᵀy] = A₀ᵀy₀ + d`, with `D = E[δAᵀδA]` and `d = E[δAᵀδy]` the
//! second moments of the noise part `δ` of the rows. Least squares on `AᵀA` therefore shrinks the
//! coefficients, and most for high powers, whose noise `k·x^{k−1}·e` is `k` times that of `x`
//! relative to the signal: on the paper's cell at 20 dB every stiffness coefficient came out
//! 1–2 % small, which lowers the barrier between the wells.
//!
//! The correction estimates `D` and `d` by simulation: draws of each record's own noise model
//! (its fitted noise floor, limited to its cut-off; see [`band_noise`]) are pushed through the
//! same term evaluation, windows, kept bins and bin weights as the data, and the coefficients of
//! the selected structure solve `(AᵀA − D)β = Aᵀy − d`. Each draw is used as an antithetic pair
//! (`x̂ ± δ`, half the difference), which keeps the part of every row that is odd in the noise —
//! its first-order effect — and cancels the even part exactly. The correction is skipped when the
//! estimated noise accounts for half or more of the data's energy in some direction of the normal
//! equations (`AᵀA − 2D` not positive definite): there the first-order picture fails and the
//! trace says the data are too noisy to correct.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use rayon::prelude::*;
use realfft::num_complex::Complex;
use tfs_library::{Library, Var};
use tfs_regress::Compressed;

use crate::error::Result;
use crate::pipeline::TfsOptions;
use crate::prepare::{Prepared, Series, TransformForm, WindowTransform, record_series};
use crate::spectral::{
    Smoothed, band_noise, bin_omegas, weak_first_derivative, weak_second_derivative, window,
    window_layout, windowed_fft,
};

/// Second moments of the noise part of the regression rows, over the columns of one support.
#[derive(Debug, Clone)]
pub(crate) struct NoiseMoments {
    /// `E[δAᵀδA]` (columns in the order of the support).
    pub d: Mat<f64>,
    /// `E[δAᵀδy]`.
    pub dy: Vec<f64>,
    /// Noise draws averaged per record.
    pub draws: usize,
}

/// Does `t` depend on a DOF's displacement or velocity (and so carry its noise)?
fn noisy(t: &tfs_library::Term) -> bool {
    t.vars().iter().any(|v| {
        matches!(
            v,
            Var::Disp(_) | Var::Vel(_) | Var::RelDisp(_, _) | Var::RelVel(_, _)
        )
    })
}

/// A seed per (record, draw, DOF): the correction is deterministic.
fn seed(record: usize, draw: usize, dof: usize) -> u64 {
    0x5eed_0000 + 1_000_003 * record as u64 + 1_009 * draw as u64 + dof as u64
}

/// The outcome of [`noise_moments`].
#[derive(Debug, Clone)]
pub(crate) enum Moments {
    /// The noise moments were estimated.
    Estimated(NoiseMoments),
    /// No usable noise model; the reason, for the trace.
    Unavailable(String),
}

/// `D` and `d` of DOF `dof` for the library columns `cols` (the support, in order), estimated from
/// `draws` antithetic noise draws per record. `transforms[r]` are the windows of record `r` at the
/// chosen window count (their kept bins and weights are the rows the fit used), `qs[r]` its
/// decimation, `delta` the chosen bin threshold. Unavailable for forms without a noise model, and
/// when some record's band reaches into the part of the spectrum its noise floor is fitted on
/// (the floor is then partly signal, and a correction by it would overshoot).
#[allow(clippy::too_many_arguments)]
pub(crate) fn noise_moments(
    preps: &[Prepared<'_>],
    dofs: &[String],
    dof: usize,
    lib: &Library,
    cols: &[usize],
    transforms: &[Vec<WindowTransform>],
    qs: &[usize],
    delta: f64,
    opt: &TfsOptions,
    draws: usize,
) -> Result<Moments> {
    let none = |why: &str| Ok(Moments::Unavailable(why.to_string()));
    if draws == 0 {
        return none("tfs.noise_correction_draws = 0");
    }
    if opt.form == TransformForm::PlainSavitzkyGolay {
        return none("the plain Savitzky–Golay form has no noise model");
    }
    let k = cols.len();
    // Only terms that use a DOF carry its noise; the others have δ = 0.
    let noisy_at: Vec<usize> = (0..k).filter(|&j| noisy(&lib.terms()[cols[j]])).collect();
    if noisy_at.is_empty() {
        return none("no kept term uses a DOF");
    }
    for p in preps {
        for (s, name) in p.smooth.iter().zip(dofs) {
            if !s.band.floor_is_noise_only() {
                return Ok(Moments::Unavailable(format!(
                    "the band of '{name}' in record '{}' reaches {:.3} Hz, into the upper half of the spectrum where its noise floor is fitted, so the floor is partly signal and not a noise estimate",
                    p.rec.source(),
                    s.band.cutoff_hz
                )));
            }
        }
    }
    let sub = Library::new(
        dofs,
        noisy_at
            .iter()
            .map(|&j| lib.terms()[cols[j]].clone())
            .collect(),
    )?;
    let jobs: Vec<(usize, usize)> = (0..preps.len().min(transforms.len()))
        .flat_map(|r| (0..draws).map(move |m| (r, m)))
        .collect();
    let parts: Vec<(Mat<f64>, Vec<f64>)> = jobs
        .par_iter()
        .map(|&(r, m)| -> Result<(Mat<f64>, Vec<f64>)> {
            let p = &preps[r];
            let n = p.rec.len();
            let noise: Vec<Option<Smoothed>> = p
                .smooth
                .iter()
                .enumerate()
                .map(|(i, s)| band_noise(&s.band, n, seed(r, m, i)))
                .collect();
            let shifted = |sign: f64| -> Prepared<'_> {
                let smooth = p
                    .smooth
                    .iter()
                    .zip(&noise)
                    .map(|(s, e)| match e {
                        None => s.clone(),
                        Some(e) => {
                            let add = |a: &[f64], b: &[f64]| -> Vec<f64> {
                                a.iter().zip(b).map(|(u, v)| u + sign * v).collect()
                            };
                            Smoothed {
                                x: add(&s.x, &e.x),
                                v: add(&s.v, &e.v),
                                a: add(&s.a, &e.a),
                                band: s.band,
                            }
                        }
                    })
                    .collect();
                Prepared {
                    rec: p.rec,
                    dt: p.dt,
                    smooth,
                }
            };
            let series = |sign: f64| {
                record_series(
                    &shifted(sign),
                    dofs,
                    dof,
                    &sub,
                    opt.form,
                    opt.savitzky_golay,
                    qs[r],
                    opt.debias,
                )
            };
            let (plus, minus) = (series(1.0)?, series(-1.0)?);
            let half = |a: &[f64], b: &[f64]| -> Vec<f64> {
                a.iter().zip(b).map(|(u, v)| 0.5 * (u - v)).collect()
            };
            let d_lhs = half(&plus.lhs, &minus.lhs);
            let d_terms: Vec<Series> = plus
                .terms
                .iter()
                .zip(&minus.terms)
                .map(|(a, b)| match (a, b) {
                    (Series::Plain(a), Series::Plain(b)) => Series::Plain(half(a, b)),
                    (Series::Transfer(a), Series::Transfer(b)) => Series::Transfer(half(a, b)),
                    _ => unreachable!("the same term gives the same form"),
                })
                .collect();
            let wins = &transforms[r];
            let (starts, len) = window_layout(d_lhs.len(), wins.len());
            let dt = plus.dt;
            let win = window(len, dt);
            let om = bin_omegas(len, dt);
            let df = 1.0 / (len as f64 * dt);
            let mut dd = Mat::<f64>::zeros(k, k);
            let mut dy = vec![0.0; k];
            let mut row = vec![0.0; k];
            for (w, &st) in wins.iter().zip(&starts) {
                let sl = |v: &[f64]| v[st..st + len].to_vec();
                let lhs = if plus.weak_lhs {
                    weak_second_derivative(&sl(&d_lhs), &win, &om, dt)
                } else {
                    windowed_fft(&sl(&d_lhs), &win.0, dt)
                };
                let full: Vec<Vec<Complex<f64>>> = d_terms
                    .iter()
                    .map(|t| match t {
                        Series::Plain(v) => windowed_fft(&sl(v), &win.0, dt),
                        Series::Transfer(g) => weak_first_derivative(&sl(g), &win, &om, dt),
                    })
                    .collect();
                for b in 0..w.lhs.len() {
                    if w.rel_amp[b] < delta {
                        continue;
                    }
                    let kb = ((w.freq[b] / df).round() as usize).min(lhs.len() - 1);
                    let wt = w.weight[b];
                    let parts: &[bool] = if w.freq[b] > 0.0 {
                        &[false, true]
                    } else {
                        &[false]
                    };
                    for &im in parts {
                        let pick = |c: Complex<f64>| if im { c.im } else { c.re };
                        row.iter_mut().for_each(|v| *v = 0.0);
                        for (s, &j) in noisy_at.iter().enumerate() {
                            row[j] = wt * pick(full[s][kb]);
                        }
                        let y = wt * pick(lhs[kb]);
                        for &i in &noisy_at {
                            dy[i] += row[i] * y;
                            for &j in &noisy_at {
                                dd[(i, j)] += row[i] * row[j];
                            }
                        }
                    }
                }
            }
            Ok((dd, dy))
        })
        .collect::<Result<_>>()?;
    let mut d = Mat::<f64>::zeros(k, k);
    let mut dy = vec![0.0; k];
    for (pd, py) in &parts {
        d += pd;
        dy.iter_mut().zip(py).for_each(|(a, b)| *a += b);
    }
    let scale = 1.0 / draws as f64;
    d *= faer::Scale(scale);
    dy.iter_mut().for_each(|v| *v *= scale);
    Ok(Moments::Estimated(NoiseMoments { d, dy, draws }))
}

/// The outcome of [`corrected_fit`].
#[derive(Debug, Clone)]
pub(crate) enum Correction {
    /// Coefficients of the support from the corrected normal equations, with each column's
    /// noise share of its energy (`D_jj / (AᵀA)_jj`).
    Applied { coef: Vec<f64>, share: Vec<f64> },
    /// The noise is too large for a first-order correction (largest share given).
    TooNoisy { share: Vec<f64> },
}

/// Solves `(AᵀA − D)β = Aᵀy − d` on the columns `support` (indices into the columns of `rows`),
/// with `m` the noise moments over the same columns in the same order.
pub(crate) fn corrected_fit(
    rows: &Compressed,
    support: &[usize],
    m: &NoiseMoments,
) -> Option<Correction> {
    let k = support.len();
    if k == 0 || m.d.nrows() != k {
        return None;
    }
    let (g, c) = rows.gram();
    // Scale to a unit diagonal so columns of very different size (x^7 next to x') are treated
    // alike by the factorisations.
    let s: Vec<f64> = support.iter().map(|&j| g[(j, j)].sqrt()).collect();
    if s.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    let gs = Mat::<f64>::from_fn(k, k, |i, j| g[(support[i], support[j])] / (s[i] * s[j]));
    let ds = Mat::<f64>::from_fn(k, k, |i, j| m.d[(i, j)] / (s[i] * s[j]));
    let share: Vec<f64> = (0..k).map(|i| ds[(i, i)]).collect();
    if share.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // AᵀA − 2D ≻ 0 ⇔ the noise is less than half the energy in every direction.
    let margin = &gs - &ds * faer::Scale(2.0);
    if margin.llt(Side::Lower).is_err() {
        return Some(Correction::TooNoisy { share });
    }
    let rhs = Mat::<f64>::from_fn(k, 1, |i, _| (c[support[i]] - m.dy[i]) / s[i]);
    let z = (&gs - &ds).llt(Side::Lower).ok()?.solve(&rhs);
    let coef: Vec<f64> = (0..k).map(|i| z[(i, 0)] / s[i]).collect();
    coef.iter()
        .all(|v| v.is_finite())
        .then_some(Correction::Applied { coef, share })
}
