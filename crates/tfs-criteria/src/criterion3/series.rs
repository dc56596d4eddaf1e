//! Criterion 3's series: every library term (and the left-hand side) of one DOF of one record
//! as a time series ready for the windowed transform — on the band-limited reconstruction
//! (weak or plain spectral form) or on the raw data with Savitzky–Golay derivatives (the paper's
//! plain form) — decimated where the kept bins allow.

use tfs_data::Columns;
use tfs_library::{ColumnSet, Factor, Library, Term, Var, evaluate_term};
use tfs_signal::band::low_pass_every;
use tfs_signal::{Band, Complex, Smoothed, Weighting, Window, WindowSamples, windowed_bins};

use crate::blocks::{OwnedColumns, Prepared, raw_columns_sg, smoothed_columns};
use crate::error::Result;

/// How the frequency-domain rows are formed (Criterion 3 variants).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, Default)]
pub enum TransformForm {
    /// Derivative transfer onto the window (no numerical differentiation), nonlinear terms on the
    /// band-limited reconstruction. The default.
    #[default]
    Weak,
    /// Plain windowed transform of spectrally differentiated band-limited data.
    PlainSpectral,
    /// The paper's plain transform: Savitzky–Golay derivatives of the raw data, terms on raw data.
    PlainSavitzkyGolay,
}

/// One scaled Hermite power alone ([`HermitePowers`] asked for one degree), the reference the
/// shared powers are tested against.
#[cfg(test)]
pub(crate) fn hermite_power(y: &[f64], k: u32, s2: f64) -> Vec<f64> {
    HermitePowers::new(y, s2).power(k)
}

/// Unbiased powers under Gaussian noise: with `y = x + e`, `e ~ N(0, s2)`, the scaled Hermite
/// polynomial `m_k(y) = s^k He_k(y/s)` satisfies `E[m_k(y)] = x^k` (recursion
/// `m_{k+1} = y·m_k − k·s2·m_{k−1}`, `m_0 = 1`, `m_1 = y`). The powers of one signal are made in
/// order of degree and shared: asking for `m_k` after `m_j` (`j ≤ k`) continues the recurrence
/// from `m_j` instead of running it from `m_0` again, so a library's powers 1..7 cost six passes
/// of the recurrence over the signal, not twenty-one. Each power is the same bits as the
/// recurrence run alone from `m_0` gives (the same operations in the same order).
pub(crate) struct HermitePowers<'y> {
    y: &'y [f64],
    s2: f64,
    /// The degree `j ≥ 1` reached, `m_{j−1}` and `m_j`; `None` before the first power.
    at: Option<(u32, Vec<f64>, Vec<f64>)>,
}

impl<'y> HermitePowers<'y> {
    /// The powers of `y` under noise of variance `s2`.
    pub(crate) fn new(y: &'y [f64], s2: f64) -> Self {
        Self { y, s2, at: None }
    }

    /// `m_k(y)`: continued from the last power asked for when `k` is not below it, else made
    /// from the start.
    pub(crate) fn power(&mut self, k: u32) -> Vec<f64> {
        if k == 0 {
            return vec![1.0; self.y.len()];
        }
        let (y, s2) = (self.y, self.s2);
        if self.at.as_ref().is_none_or(|(j, _, _)| *j > k) {
            self.at = Some((1, vec![1.0; y.len()], y.to_vec()));
        }
        let (j, a, b) = self.at.as_mut().expect("just set");
        // The recurrence `He_{j+1} = y·He_j − j·s²·He_{j−1}` a whole column at a time (the same
        // operations on every sample as one sample at a time, in a loop the compiler vectorises).
        while *j < k {
            let js2 = *j as f64 * s2;
            for ((a, b), &v) in a.iter_mut().zip(b.iter_mut()).zip(y) {
                let c = v * *b - js2 * *a;
                *a = *b;
                *b = c;
            }
            *j += 1;
        }
        b.clone()
    }
}

/// Each DOF's [`HermitePowers`] over the reconstructions `smooth` (its displacement, its band's
/// in-band noise variance), made on first use: the terms of one series share them.
struct DofPowers<'s> {
    smooth: &'s [Smoothed],
    powers: Vec<Option<HermitePowers<'s>>>,
}

impl<'s> DofPowers<'s> {
    fn new(smooth: &'s [Smoothed]) -> Self {
        Self {
            smooth,
            powers: smooth.iter().map(|_| None).collect(),
        }
    }

    /// `m_k` of DOF `i`'s displacement.
    fn power(&mut self, i: usize, k: u32) -> Vec<f64> {
        let s = &self.smooth[i];
        self.powers[i]
            .get_or_insert_with(|| HermitePowers::new(&s.x, s.band.noise_var))
            .power(k)
    }
}

/// The periodic `sin⁴` window of `len` samples at step `dt` with its time derivatives (see
/// [`Window::sample_periodic`]); `len ≥ 2` and `dt > 0` hold for every window of a checked record.
pub(crate) fn window(len: usize, dt: f64) -> WindowSamples {
    Window::HannSquared
        .sample_periodic(len, dt)
        .expect("windows of checked records have at least 8 samples and a positive step")
}

/// One library column in time, as it enters the windowed transform.
pub(crate) enum Series {
    /// Transform `θ·w`.
    Plain(Vec<f64>),
    /// The term is `G'`: transform `−(G·w' − iωG·w)`.
    Transfer(Vec<f64>),
}

/// Time series of every library term (and the left-hand side) for one DOF of one record.
pub(crate) struct RecordSeries {
    /// Sampling step of the series (after decimation).
    pub dt: f64,
    pub lhs: Vec<f64>,
    pub weak_lhs: bool,
    pub terms: Vec<Series>,
    /// Noise model of the DOF's displacement and the sampling step it was estimated at (`None`
    /// for raw-data forms).
    pub noise: Option<(Band, f64)>,
}

impl RecordSeries {
    /// Transform of the left-hand side over the window of `win.w.len()` samples starting at
    /// `st`, at the bins `bins`; `win` and `om` are that length's window and bin frequencies.
    pub(crate) fn lhs_spectrum_at(
        &self,
        st: usize,
        win: &WindowSamples,
        om: &[f64],
        bins: &[usize],
    ) -> Vec<Complex<f64>> {
        let x = &self.lhs[st..st + win.w.len()];
        let weighting = if self.weak_lhs {
            Weighting::Second
        } else {
            Weighting::Plain
        };
        windowed_bins(x, self.dt, om, bins, weighting)
    }

    /// Transform of term `j` over the same window (see [`RecordSeries::lhs_spectrum_at`]), in
    /// the term's form (plain, or derivative transfer onto the window), at the bins `bins`.
    pub(crate) fn term_spectrum_at(
        &self,
        j: usize,
        st: usize,
        win: &WindowSamples,
        om: &[f64],
        bins: &[usize],
    ) -> Vec<Complex<f64>> {
        let len = win.w.len();
        match &self.terms[j] {
            Series::Plain(v) => {
                windowed_bins(&v[st..st + len], self.dt, om, bins, Weighting::Plain)
            }
            Series::Transfer(g) => {
                windowed_bins(&g[st..st + len], self.dt, om, bins, Weighting::First)
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn record_series(
    p: &Prepared<'_>,
    dofs: &[String],
    dof: usize,
    lib: &Library,
    form: TransformForm,
    sg: (usize, usize),
    q: usize,
    debias: bool,
) -> Result<RecordSeries> {
    if q <= 1 || form == TransformForm::PlainSavitzkyGolay {
        return record_series_full(p, dofs, dof, lib, form, sg, debias);
    }
    // Decimated: terms built only from the band-limited DOF signals are pointwise functions of
    // them, so evaluating them on every q-th sample equals decimating the full-rate series.
    let smooth: Vec<Smoothed> = p
        .smooth
        .iter()
        .map(|s| Smoothed {
            x: decimate(&s.x, q),
            v: decimate(&s.v, q),
            a: decimate(&s.a, q),
            band: s.band,
        })
        .collect();
    decimated_series(
        p,
        &decimated_inputs(p, lib, q),
        smooth,
        dofs,
        dof,
        lib,
        form == TransformForm::Weak,
        q,
        debias,
    )
}

/// Every `q`-th sample of `v`, from the first.
pub(crate) fn decimate(v: &[f64], q: usize) -> Vec<f64> {
    v.iter().step_by(q).copied().collect()
}

/// The record columns the library reads (inputs), at every `q`-th sample.
pub(crate) fn decimated_inputs(p: &Prepared<'_>, lib: &Library, q: usize) -> OwnedColumns {
    OwnedColumns {
        rows: p.rec.len().div_ceil(q),
        cols: lib
            .required_columns()
            .into_iter()
            .filter_map(|c| p.rec.column(&c).map(|v| (c.clone(), decimate(v, q))))
            .collect(),
    }
}

/// [`record_series`] at decimation `q > 1` (a transform form with a reconstruction, `weak` or
/// plain spectral) from the DOF reconstructions `smooth` and the input columns `base`, both
/// already decimated. Inputs are broadband: a term that uses one is evaluated on `p` at the full
/// rate and low-passed below the new Nyquist before decimating.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decimated_series(
    p: &Prepared<'_>,
    base: &OwnedColumns,
    smooth: Vec<Smoothed>,
    dofs: &[String],
    dof: usize,
    lib: &Library,
    weak: bool,
    q: usize,
    debias: bool,
) -> Result<RecordSeries> {
    let mut cs = ColumnSet::new(base as &dyn Columns);
    for (d, s) in dofs.iter().zip(&smooth) {
        cs.insert(d.clone(), s.x.clone())?;
        cs.insert(format!("{d}'"), s.v.clone())?;
    }
    let nyq = 0.5 / (p.dt * q as f64);
    let mut full_cs = None;
    let (mut full_powers, mut powers) = (DofPowers::new(&p.smooth), DofPowers::new(&smooth));
    let mut terms = Vec::with_capacity(lib.len());
    for t in lib.terms() {
        if t.uses_input() {
            if full_cs.is_none() {
                full_cs = Some(smoothed_columns(p, dofs)?);
            }
            let fcs = full_cs.as_ref().expect("just set");
            let ser = term_series(t, fcs, &mut full_powers, dofs, weak, debias)?;
            let lp = |v: &[f64]| low_pass_every(v, p.dt, 0.8 * nyq, q);
            terms.push(match ser {
                Series::Plain(v) => Series::Plain(lp(&v)),
                Series::Transfer(v) => Series::Transfer(lp(&v)),
            });
        } else {
            terms.push(term_series(t, &cs, &mut powers, dofs, weak, debias)?);
        }
    }
    let lhs = if weak {
        smooth[dof].x.clone()
    } else {
        smooth[dof].a.clone()
    };
    Ok(RecordSeries {
        dt: p.dt * q as f64,
        lhs,
        weak_lhs: weak,
        terms,
        // The noise model stays tied to the step it was estimated at.
        noise: Some((p.smooth[dof].band, p.dt)),
    })
}

/// One library term as it enters the transform (weak: `G'` terms by derivative transfer; single
/// displacement powers noise-debiased when asked), from columns `cs` and the Hermite powers of
/// the reconstructions `powers` (shared by the terms of one series).
fn term_series(
    t: &Term,
    cs: &ColumnSet<'_>,
    powers: &mut DofPowers<'_>,
    dofs: &[String],
    weak: bool,
    debias: bool,
) -> Result<Series> {
    // A single power of one DOF's displacement, evaluated without the noise bias.
    let mut debiased = |t: &Term| -> Option<Vec<f64>> {
        if !debias {
            return None;
        }
        match t.factors() {
            [Factor::Pow(Var::Disp(d), k)] => {
                let i = dofs.iter().position(|n| n == d)?;
                Some(powers.power(i, *k))
            }
            _ => None,
        }
    };
    if weak && let Some(ed) = t.exact_derivative() {
        let anti = ed.antiderivative();
        let mut g = match debiased(&anti) {
            Some(g) => g,
            None => evaluate_term(&anti, cs)?,
        };
        g.iter_mut().for_each(|v| *v *= ed.scale);
        Ok(Series::Transfer(g))
    } else if let Some(v) = debiased(t) {
        Ok(Series::Plain(v))
    } else {
        Ok(Series::Plain(evaluate_term(t, cs)?))
    }
}

/// Bins of the shortest window between the highest kept bin and the nearest alias of the
/// integrand's band (see [`decimation`]): the window's own spread (two bins either side, twice)
/// and 20 bins of leakage decay (`20⁻⁵ ≈ 3e-7`).
const DECIMATION_CLEARANCE_BINS: f64 = 24.0;

/// The decimation factor that keeps the windowed integrals at the kept bins as they are at the
/// full rate, for layouts of up to `max_windows` windows per record. A polynomial term of degree
/// `p` in signals band-limited to `f_c` (the reconstruction is a trigonometric polynomial) has
/// its spectrum within `p·f_c`, and the kept bins, set by the windowed `x''`, lie within `f_c`
/// (plus the window's spread). Decimating to the rate `f_s` folds the windowed transform's bins
/// `f_s` apart onto each other, so a kept bin receives the integrand's transform at
/// `f_s − p·f_c − f_c` and beyond, where only the window's leakage is left: `sin⁴` vanishes to
/// fourth order at its ends and its leakage falls as the fifth power of the distance in bins.
/// The rate is the least above `(p+1)·f_c` plus [`DECIMATION_CLEARANCE_BINS`] bins of the
/// shortest window (leakage ~1e-7 of the signal there). Non-polynomial terms give 1 (no
/// decimation).
pub(crate) fn decimation(
    p: &Prepared<'_>,
    lib: &Library,
    form: TransformForm,
    max_windows: usize,
) -> usize {
    if form == TransformForm::PlainSavitzkyGolay {
        return 1;
    }
    let Some(deg) = lib
        .terms()
        .iter()
        .map(|t| t.degree())
        .try_fold(0u32, |a, d| d.map(|d| a.max(d)))
    else {
        return 1;
    };
    let fc = p
        .smooth
        .iter()
        .map(|s| s.band.cutoff_hz)
        .fold(0.0, f64::max);
    if fc.is_nan() || fc <= 0.0 {
        return 1;
    }
    // The shortest window: `window_layout`'s length for the most windows.
    let t_w = 2.0 * p.rec.len() as f64 * p.dt / (max_windows.max(1) + 1) as f64;
    let need = (deg.max(1) + 1) as f64 * fc + DECIMATION_CLEARANCE_BINS / t_w;
    ((1.0 / p.dt) / need).floor().max(1.0) as usize
}

fn record_series_full(
    p: &Prepared<'_>,
    dofs: &[String],
    dof: usize,
    lib: &Library,
    form: TransformForm,
    sg: (usize, usize),
    debias: bool,
) -> Result<RecordSeries> {
    match form {
        TransformForm::Weak | TransformForm::PlainSpectral => {
            let cs = smoothed_columns(p, dofs)?;
            let weak = form == TransformForm::Weak;
            let mut powers = DofPowers::new(&p.smooth);
            let terms = lib
                .terms()
                .iter()
                .map(|t| term_series(t, &cs, &mut powers, dofs, weak, debias))
                .collect::<Result<Vec<_>>>()?;
            let lhs = if weak {
                p.smooth[dof].x.clone()
            } else {
                p.smooth[dof].a.clone()
            };
            Ok(RecordSeries {
                dt: p.dt,
                lhs,
                weak_lhs: weak,
                terms,
                noise: Some((p.smooth[dof].band, p.dt)),
            })
        }
        TransformForm::PlainSavitzkyGolay => {
            let (cs, a) = raw_columns_sg(p.rec, dofs, dof, p.dt, sg)?;
            let terms = lib
                .terms()
                .iter()
                .map(|t| evaluate_term(t, &cs).map(Series::Plain))
                .collect::<std::result::Result<Vec<_>, _>>()?;
            Ok(RecordSeries {
                dt: p.dt,
                lhs: a,
                weak_lhs: false,
                terms,
                noise: None,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::prepare;
    use tfs_data::Record;
    use tfs_signal::bin_omegas;

    /// At the rate `decimation` chooses, the windowed transforms of a degree-7 term of the
    /// band-limited reconstruction agree with the full-rate ones at every bin up to the cut-off
    /// (the integrand's aliases land beyond the clearance); below `(p+1)·f_c` they do not.
    #[test]
    fn decimated_window_transforms_match_the_full_rate() {
        let (n, dt, fc) = (40_000, 0.005, 2.0);
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|&t| {
                let w = 2.0 * std::f64::consts::PI;
                0.6 * (w * 0.37 * t).sin()
                    + 0.5 * (w * 1.1 * t + 0.3).sin()
                    + 0.3 * (w * 1.83 * t + 1.0).cos()
            })
            .collect();
        let rec = Record::new("r", t, vec![("x".into(), x)]).unwrap();
        let dofs = vec!["x".to_string()];
        let p = prepare(&rec, &dofs, Some(fc), 0.0, true).unwrap();
        let lib = Library::parse("x^7, x^6*x'", &dofs).unwrap();
        let q = decimation(&p, &lib, TransformForm::Weak, 7);
        // (7+1)·2 Hz plus 24 bins of a 50 s window: 16.48 Hz, so every 12th sample of 200 Hz.
        assert_eq!(q, 12);
        let xs = &p.smooth[0].x;
        let g: Vec<f64> = xs.iter().map(|v| v.powi(7)).collect();
        // One window of 48 s at the full rate and at the decimated ones.
        let len_full = 9600;
        let at = |step: usize, weighting: Weighting| {
            let len = len_full / step;
            let gd: Vec<f64> = g[..len_full].iter().step_by(step).copied().collect();
            let om = bin_omegas(len, dt * step as f64);
            let bins: Vec<usize> = (0..om.len())
                .filter(|&k| om[k] <= 2.0 * std::f64::consts::PI * fc)
                .collect();
            windowed_bins(&gd, dt * step as f64, &om, &bins, weighting)
        };
        for weighting in [Weighting::Plain, Weighting::First, Weighting::Second] {
            let full = at(1, weighting);
            let scale = full.iter().fold(0.0f64, |m, c| m.max(c.norm()));
            let err = |d: &[Complex<f64>]| {
                d.iter()
                    .zip(&full)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).norm()))
                    / scale
            };
            let good = err(&at(q, weighting));
            assert!(
                good < 1e-6,
                "{weighting:?}: relative error {good:e} at q = {q}"
            );
            // 200/16 = 12.5 Hz < 16 Hz: the band folds onto the kept bins.
            let bad = err(&at(16, weighting));
            assert!(
                bad > 1e-3,
                "{weighting:?}: aliasing went unnoticed ({bad:e})"
            );
        }
    }

    /// The Hermite powers are `He_k(y; s²)`: `He_2 = y² − s²`, `He_3 = y³ − 3s²y`, and the column
    /// recurrence gives the same bits as the recurrence run one sample at a time.
    #[test]
    fn hermite_powers_follow_the_recurrence() {
        let y: Vec<f64> = (0..37).map(|i| (i as f64 * 0.37).sin() * 1.7).collect();
        let s2 = 0.013;
        for k in 0..9u32 {
            let got = hermite_power(&y, k, s2);
            for (&v, &g) in y.iter().zip(&got) {
                let (mut a, mut b) = (1.0, v);
                for j in 1..k {
                    let c = v * b - j as f64 * s2 * a;
                    a = b;
                    b = c;
                }
                let want = if k == 0 { 1.0 } else { b };
                assert_eq!(g.to_bits(), want.to_bits(), "k = {k}");
            }
        }
        // Shared powers asked for in any order (ascending, repeated, descending, skipping) are
        // the same bits as each made alone.
        let mut shared = HermitePowers::new(&y, s2);
        for k in [1u32, 2, 2, 5, 3, 0, 7, 8, 1, 6] {
            let want: Vec<u64> = hermite_power(&y, k, s2)
                .iter()
                .map(|v| v.to_bits())
                .collect();
            let got: Vec<u64> = shared.power(k).iter().map(|v| v.to_bits()).collect();
            assert_eq!(got, want, "k = {k}");
        }
        let h2 = hermite_power(&y, 2, s2);
        let h3 = hermite_power(&y, 3, s2);
        for ((&v, a), b) in y.iter().zip(h2).zip(h3) {
            assert!((a - (v * v - s2)).abs() < 1e-14);
            assert!((b - (v * v * v - 3.0 * s2 * v)).abs() < 1e-13);
        }
    }
}
