//! Errors-in-variables correction of the final coefficients (corrected least squares).
//!
//! The frequency-domain rows are built from the band-limited reconstruction `x̂ = x + e`, and the
//! noise `e` left in the band enters both sides of the regression: the `x''` row and every column
//! that uses `x̂` or `x̂'`. The Hermite debiasing of single powers removes the *mean* bias of
//! `x̂^k`, but not the noise *variance* in the normal equations:
//! `E[AᵀA] = A₀ᵀA₀ + D` and `E[Aᵀy] = A₀ᵀy₀ + d`, with `D = E[δAᵀδA]` and `d = E[δAᵀδy]` the
//! second moments of the noise part `δ` of the rows. Least squares on `AᵀA` therefore shrinks the
//! coefficients, and most for high powers, whose noise `k·x^{k−1}·e` is `k` times that of `x`
//! relative to the signal.
//!
//! The correction estimates `D` and `d` by simulation: draws of each record's own noise model
//! (its fitted noise floor, limited to its cut-off; see [`tfs_signal::band::noise_draw`]) are pushed through the
//! same term evaluation, windows, kept bins and bin weights as the data, and the coefficients of
//! the selected structure solve `(AᵀA − D)β = Aᵀy − d`. Each draw is used as an antithetic pair
//! (`x̂ ± δ`, half the difference), which keeps the part of every row that is odd in the noise —
//! its first-order effect — and cancels the even part exactly. The correction is skipped when the
//! estimated noise accounts for half or more of the data's energy in some direction of the normal
//! equations (`AᵀA − 2D` not positive definite): there the first-order picture fails and the
//! trace says the data are too noisy to correct.

use std::borrow::Cow;
use std::sync::OnceLock;

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use rayon::prelude::*;
use tfs_library::{Library, Var};
use tfs_regress::Compressed;
use tfs_signal::Complex;

use crate::blocks::Prepared;
use crate::criterion3::rows::{WindowTransform, rows_for};
use crate::criterion3::series::{
    RecordSeries, Series, TransformForm, decimate, decimated_inputs, decimated_series,
    record_series, window,
};
use crate::error::Result;
use crate::options::TfsOptions;
use tfs_signal::band::noise_spectrum;
use tfs_signal::{Band, NoiseSpectrum, Smoothed, bin_omegas, window_layout};

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

/// The noise draws of [`noise_moments`] (one per record, draw and DOF), made on first use and
/// kept: they depend on the records' noise models and the seeds only, not on the library, so the
/// passes of the backward elimination (which re-fit on fewer terms) share them. A draw is kept
/// as its in-band Fourier coefficients ([`NoiseSpectrum`]); each use takes its samples at the
/// decimation it needs.
pub(crate) struct NoiseDraws {
    draws: usize,
    dofs: usize,
    /// Whether the draws carry their second derivative (only forms other than the weak one
    /// read it).
    with_acc: bool,
    slots: Vec<OnceLock<Option<NoiseSpectrum>>>,
}

impl NoiseDraws {
    /// Room for `draws` draws of `dofs` DOFs in each of `records` records, for the transform
    /// `form` (which decides whether the draws need their second derivative).
    pub(crate) fn new(records: usize, dofs: usize, draws: usize, form: TransformForm) -> Self {
        Self {
            draws,
            dofs,
            with_acc: form != TransformForm::Weak,
            slots: (0..records * draws * dofs)
                .map(|_| OnceLock::new())
                .collect(),
        }
    }

    /// Makes, in parallel, every draw that [`noise_moments`] would ask for on `preps` with the
    /// options `opt`, so that they can be made while other work runs (they do not depend on the
    /// library). Nothing is drawn where [`noise_moments`] would not draw: no draws asked for, a
    /// form without a noise model, or a band whose floor is not a noise estimate.
    pub(crate) fn prefill(&self, preps: &[Prepared<'_>], dofs: &[String], opt: &TfsOptions) {
        if no_noise_model(preps, dofs, opt, self.draws).is_some() {
            return;
        }
        let jobs: Vec<(usize, usize, usize)> = (0..preps.len())
            .flat_map(|r| {
                let dofs = preps[r].smooth.len().min(self.dofs);
                (0..self.draws).flat_map(move |m| (0..dofs).map(move |i| (r, m, i)))
            })
            .collect();
        jobs.par_iter().with_max_len(1).for_each(|&(r, m, i)| {
            drop(self.get(&preps[r].smooth[i].band, r, m, i));
        });
    }

    /// Draw `m` of DOF `i` of record `r` (whose band is `band`).
    fn get(&self, band: &Band, r: usize, m: usize, i: usize) -> Cow<'_, Option<NoiseSpectrum>> {
        let make = || noise_spectrum(band, seed(r, m, i));
        if m >= self.draws || i >= self.dofs {
            return Cow::Owned(make());
        }
        match self.slots.get((r * self.draws + m) * self.dofs + i) {
            Some(slot) => Cow::Borrowed(slot.get_or_init(make)),
            None => Cow::Owned(make()),
        }
    }
}

/// Why no noise draws can be made on `preps` with `draws` draws under the options `opt` (none
/// asked for, a form without a noise model, or a band whose floor is not a noise estimate), or
/// `None` when they can. Shared by [`noise_moments`] and [`NoiseDraws::prefill`].
fn no_noise_model(
    preps: &[Prepared<'_>],
    dofs: &[String],
    opt: &TfsOptions,
    draws: usize,
) -> Option<String> {
    if draws == 0 {
        return Some("tfs.noise_correction_draws = 0".into());
    }
    if opt.criterion3.form == TransformForm::PlainSavitzkyGolay {
        return Some("the plain Savitzky–Golay form has no noise model".into());
    }
    for p in preps {
        for (s, name) in p.smooth.iter().zip(dofs) {
            if !s.band.floor_is_noise_only() {
                return Some(format!(
                    "the band of '{name}' in record '{}' reaches {:.3} Hz, into the upper half of the spectrum where its noise floor is fitted, so the floor is partly signal and not a noise estimate",
                    p.rec.source(),
                    s.band.cutoff_hz
                ));
            }
        }
    }
    None
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
/// decimation, `delta` the chosen bin threshold, `cache` the draws (made here on first use).
/// Unavailable for forms without a noise model, and
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
    cache: &NoiseDraws,
) -> Result<Moments> {
    if let Some(why) = no_noise_model(preps, dofs, opt, draws) {
        return Ok(Moments::Unavailable(why));
    }
    let k = cols.len();
    // Only terms that use a DOF carry its noise; the others have δ = 0.
    let noisy_at: Vec<usize> = (0..k).filter(|&j| noisy(&lib.terms()[cols[j]])).collect();
    if noisy_at.is_empty() {
        return Ok(Moments::Unavailable("no kept term uses a DOF".into()));
    }
    let sub = Library::new(
        dofs,
        noisy_at
            .iter()
            .map(|&j| lib.terms()[cols[j]].clone())
            .collect(),
    )?;
    let job = DrawJob {
        preps,
        dofs,
        dof,
        sub: &sub,
        noisy_at: &noisy_at,
        k,
        transforms,
        qs,
        delta,
        opt,
        cache,
    };
    let jobs: Vec<(usize, usize)> = (0..preps.len().min(transforms.len()))
        .flat_map(|r| (0..draws).map(move |m| (r, m)))
        .collect();
    let parts: Vec<(Mat<f64>, Vec<f64>)> = jobs
        .par_iter()
        .with_max_len(1)
        .map(|&(r, m)| job.moments(r, m))
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

/// One DOF's noise-moment estimate: what every (record, draw) job reads.
struct DrawJob<'a> {
    preps: &'a [Prepared<'a>],
    dofs: &'a [String],
    dof: usize,
    /// The noisy terms of the support, as a library.
    sub: &'a Library,
    /// Their positions among the support's `k` columns.
    noisy_at: &'a [usize],
    k: usize,
    transforms: &'a [Vec<WindowTransform>],
    qs: &'a [usize],
    delta: f64,
    opt: &'a TfsOptions,
    cache: &'a NoiseDraws,
}

impl DrawJob<'_> {
    /// The noise part of the series of record `r` in draw `m`: the series of the reconstruction
    /// plus and minus the draw, half their difference (the part odd in the noise).
    fn noise_series(&self, r: usize, m: usize) -> Result<RecordSeries> {
        let (preps, dofs, dof, sub, opt, cache) = (
            self.preps, self.dofs, self.dof, self.sub, self.opt, self.cache,
        );
        let p = &preps[r];
        let n = p.rec.len();
        let q = self.qs[r];
        // Decimated series read only every q-th sample of the reconstruction: the shifted
        // copy is made at those samples alone (the same sums as shifting, then decimating),
        // and the noise is drawn at them alone. A term that uses an input reads the
        // reconstruction at the full rate.
        let decimated = q > 1 && !sub.terms().iter().any(|t| t.uses_input());
        let inputs = decimated.then(|| decimated_inputs(p, sub, q));
        let step = if decimated { q } else { 1 };
        let noise: Vec<Option<Smoothed>> = p
            .smooth
            .iter()
            .enumerate()
            .map(|(i, s)| {
                cache
                    .get(&s.band, r, m, i)
                    .as_ref()
                    .as_ref()
                    .and_then(|d| d.series(n, step, cache.with_acc))
            })
            .collect();
        let shifted = |sign: f64| -> Vec<Smoothed> {
            let add = |a: &[f64], b: &[f64]| -> Vec<f64> {
                a.iter()
                    .step_by(step)
                    .zip(b)
                    .map(|(u, v)| u + sign * v)
                    .collect()
            };
            p.smooth
                .iter()
                .zip(&noise)
                .map(|(s, e)| match e {
                    None => Smoothed {
                        x: decimate(&s.x, step),
                        v: decimate(&s.v, step),
                        a: decimate(&s.a, step),
                        band: s.band,
                    },
                    Some(e) => Smoothed {
                        x: add(&s.x, &e.x),
                        v: add(&s.v, &e.v),
                        a: add(&s.a, &e.a),
                        band: s.band,
                    },
                })
                .collect()
        };
        let series = |sign: f64| match &inputs {
            Some(base) => decimated_series(
                p,
                base,
                shifted(sign),
                dofs,
                dof,
                sub,
                opt.criterion3.form == TransformForm::Weak,
                q,
                opt.criterion3.debias,
            ),
            None => record_series(
                &Prepared {
                    rec: p.rec,
                    dt: p.dt,
                    smooth: shifted(sign),
                    input_bands: Default::default(),
                    spectra: Default::default(),
                },
                dofs,
                dof,
                sub,
                opt.criterion3.form,
                opt.criterion3.savitzky_golay,
                q,
                opt.criterion3.debias,
            ),
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
        let delta_series = RecordSeries {
            dt: plus.dt,
            lhs: d_lhs,
            weak_lhs: plus.weak_lhs,
            terms: d_terms,
            noise: None,
        };
        Ok(delta_series)
    }

    /// The contribution of draw `m` of record `r` to `D` and `d`: the noise part of its rows,
    /// in the same windows, bins and weights as the data's.
    fn moments(&self, r: usize, m: usize) -> Result<(Mat<f64>, Vec<f64>)> {
        let delta_series = self.noise_series(r, m)?;
        let (k, noisy_at, delta) = (self.k, self.noisy_at, self.delta);
        let wins = &self.transforms[r];
        let (starts, len) = window_layout(delta_series.lhs.len(), wins.len());
        let win = window(len, delta_series.dt);
        let om = bin_omegas(len, delta_series.dt);
        let df = 1.0 / (len as f64 * delta_series.dt);
        let all: Vec<usize> = (0..k).collect();
        let mut dd = Mat::<f64>::zeros(k, k);
        let mut dy = vec![0.0; k];
        for (w, &st) in wins.iter().zip(&starts) {
            // The noise part of this window's rows: same bins and weights as the data's.
            let at: Vec<usize> = w
                .freq
                .iter()
                .map(|f| ((f / df).round() as usize).min(len / 2))
                .collect();
            let lhs = delta_series.lhs_spectrum_at(st, &win, &om, &at);
            let mut cols = vec![vec![Complex::new(0.0, 0.0); at.len()]; k];
            for (s, &j) in noisy_at.iter().enumerate() {
                cols[j] = delta_series.term_spectrum_at(s, st, &win, &om, &at);
            }
            let noise_rows = WindowTransform {
                freq: w.freq.clone(),
                rel_amp: w.rel_amp.clone(),
                lhs,
                cols,
                weight: w.weight.clone(),
            };
            let (a, y, _) = rows_for(&noise_rows, delta, &all);
            dd += a.transpose() * &a;
            for (i, v) in dy.iter_mut().enumerate() {
                *v += (0..a.nrows()).map(|m| a[(m, i)] * y[m]).sum::<f64>();
            }
        }
        Ok((dd, dy))
    }
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
/// with `m` the noise moments over the same columns in the same order, jointly with the
/// noise-free columns `exact` (the constant: no noise moments, solved for but not returned). A
/// constant left out of these equations would leave its leakage into the kept low bins to the
/// terms it is collinear with there (a displacement recorded with a sensor offset).
pub(crate) fn corrected_fit(
    rows: &Compressed,
    support: &[usize],
    exact: &[usize],
    m: &NoiseMoments,
) -> Option<Correction> {
    let k = support.len();
    if k == 0 || m.d.nrows() != k {
        return None;
    }
    let all: Vec<usize> = support.iter().chain(exact).copied().collect();
    let n = all.len();
    let (g, c) = rows.gram();
    // Scale to a unit diagonal so columns of very different size (x^7 next to x') are treated
    // alike by the factorisations.
    let s: Vec<f64> = all.iter().map(|&j| g[(j, j)].sqrt()).collect();
    if s.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    let gs = Mat::<f64>::from_fn(n, n, |i, j| g[(all[i], all[j])] / (s[i] * s[j]));
    let ds = Mat::<f64>::from_fn(n, n, |i, j| {
        if i < k && j < k {
            m.d[(i, j)] / (s[i] * s[j])
        } else {
            0.0
        }
    });
    let share: Vec<f64> = (0..k).map(|i| ds[(i, i)]).collect();
    if share.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // AᵀA − 2D ≻ 0 ⇔ the noise is less than half the energy in every direction.
    let margin = &gs - &ds * faer::Scale(2.0);
    if margin.llt(Side::Lower).is_err() {
        return Some(Correction::TooNoisy { share });
    }
    let dy = |i: usize| if i < k { m.dy[i] } else { 0.0 };
    let rhs = Mat::<f64>::from_fn(n, 1, |i, _| (c[all[i]] - dy(i)) / s[i]);
    let z = (&gs - &ds).llt(Side::Lower).ok()?.solve(&rhs);
    let coef: Vec<f64> = (0..k).map(|i| z[(i, 0)] / s[i]).collect();
    coef.iter()
        .all(|v| v.is_finite())
        .then_some(Correction::Applied { coef, share })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows `[x, 1, u]` whose `x` carries an offset `c` (a sensor offset: `x = s + c`) and whose
    /// target is `−k·s + g·u`, i.e. `−k·x + k·c + g·u`: the constant's column is what takes up
    /// `k·c`. With no noise moments the corrected equations are plain least squares.
    #[test]
    fn the_constant_is_solved_with_the_corrected_terms() {
        let (k, g, c) = (6.0, 1.0, 0.25);
        let n = 200;
        let mut a = Mat::<f64>::zeros(n, 3);
        let mut y = vec![0.0; n];
        for i in 0..n {
            let t = i as f64 * 0.05;
            // A constant's windowed transform is not zero in the low bins: the rows here are
            // time samples, where it is plainly 1.
            let s = (1.3 * t).sin() + 0.2 * (0.4 * t).cos();
            let u = (0.9 * t).cos();
            a[(i, 0)] = s + c;
            a[(i, 1)] = 1.0;
            a[(i, 2)] = u;
            y[i] = -k * s + g * u;
        }
        let rows = Compressed::from_rows(a.as_ref(), &y).unwrap();
        let m = NoiseMoments {
            d: Mat::zeros(2, 2),
            dy: vec![0.0; 2],
            draws: 1,
        };
        let coef = |exact: &[usize]| match corrected_fit(&rows, &[0, 2], exact, &m) {
            Some(Correction::Applied { coef, .. }) => coef,
            other => panic!("not applied: {other:?}"),
        };
        let with = coef(&[1]);
        assert!(
            (with[0] + k).abs() < 1e-9 && (with[1] - g).abs() < 1e-9,
            "{with:?}"
        );
        // Without the constant the offset's share goes to the terms it overlaps.
        let without = coef(&[]);
        assert!((without[0] + k).abs() > 0.1, "{without:?}");
    }
}
