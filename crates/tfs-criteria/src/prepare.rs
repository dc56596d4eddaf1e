//! Per-record preparation shared by the pipelines: validation, band-limited reconstruction of
//! every DOF, evaluation of library terms on the reconstruction, and windowed transforms.

use faer::Mat;
use tfs_data::{Columns, Record};
use tfs_library::{ColumnSet, Factor, Library, Term, Var, evaluate_term};
use tfs_signal::band::{low_pass, reconstruct_guarded};
use tfs_signal::{
    Band, Complex, Smoothed, Weighting, Window, WindowSamples, bin_omegas, window_layout,
    windowed_bins,
};

use crate::error::{CriteriaError, Result, invalid};

/// Unbiased powers under Gaussian noise: with `y = x + e`, `e ~ N(0, s2)`, the scaled Hermite
/// polynomial `m_k(y) = s^k He_k(y/s)` satisfies `E[m_k(y)] = x^k` (recursion
/// `m_{k+1} = y·m_k − k·s2·m_{k−1}`, `m_0 = 1`, `m_1 = y`).
pub fn hermite_power(y: &[f64], k: u32, s2: f64) -> Vec<f64> {
    if k == 0 {
        return vec![1.0; y.len()];
    }
    // The recurrence `He_{j+1} = y·He_j − j·s²·He_{j−1}` a whole column at a time (the same
    // operations on every sample as one sample at a time, in a loop the compiler vectorises).
    let mut a = vec![1.0; y.len()];
    let mut b = y.to_vec();
    for j in 1..k {
        let js2 = j as f64 * s2;
        for ((a, b), &v) in a.iter_mut().zip(b.iter_mut()).zip(y) {
            let c = v * *b - js2 * *a;
            *a = *b;
            *b = c;
        }
    }
    b
}

/// The periodic `sin⁴` window of `len` samples at step `dt` with its time derivatives (see
/// [`Window::sample_periodic`]); `len ≥ 2` and `dt > 0` hold for every window of a checked record.
pub(crate) fn window(len: usize, dt: f64) -> WindowSamples {
    Window::HannSquared
        .sample_periodic(len, dt)
        .expect("windows of checked records have at least 8 samples and a positive step")
}

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

/// Checks a record has the DOF columns, enough samples and a usable time step.
pub(crate) fn check_record(rec: &Record, dofs: &[String]) -> Result<f64> {
    let dt = rec.dt();
    if rec.len() < 64 {
        return invalid(format!(
            "record '{}' has {} samples; at least 64 are needed",
            rec.source(),
            rec.len()
        ));
    }
    if !(dt.is_finite() && dt > 0.0) {
        return invalid(format!(
            "record '{}': the time column 't' must increase uniformly (dt = {dt})",
            rec.source()
        ));
    }
    for d in dofs {
        let Some(c) = rec.column(d) else {
            return invalid(format!(
                "record '{}' has no column '{d}' for DOF '{d}'; columns are {:?}",
                rec.source(),
                rec.names()
            ));
        };
        if let Some(i) = c.iter().position(|v| !v.is_finite()) {
            return invalid(format!(
                "record '{}', column '{d}', row {}: value {} is not finite",
                rec.source(),
                i + 1,
                c[i]
            ));
        }
    }
    Ok(dt)
}

/// A record with every DOF reconstructed in its data-chosen band.
pub(crate) struct Prepared<'a> {
    pub rec: &'a Record,
    pub dt: f64,
    pub smooth: Vec<Smoothed>,
}

/// Validates a record and reconstructs every DOF: band-limited at `cutoff_hz`, or at the
/// data-chosen cut-off raised by `guard_octaves` (see [`reconstruct_guarded`]).
pub(crate) fn prepare<'a>(
    rec: &'a Record,
    dofs: &[String],
    cutoff_hz: Option<f64>,
    guard_octaves: f64,
) -> Result<Prepared<'a>> {
    let dt = check_record(rec, dofs)?;
    let smooth = dofs
        .iter()
        .map(|d| {
            reconstruct_guarded(
                rec.column(d).expect("checked"),
                dt,
                cutoff_hz,
                guard_octaves,
            )
        })
        .collect();
    Ok(Prepared { rec, dt, smooth })
}

/// Columns of a prepared record: the DOFs and their velocities replaced by the reconstruction.
pub(crate) fn smoothed_columns<'a>(p: &'a Prepared<'_>, dofs: &[String]) -> Result<ColumnSet<'a>> {
    let mut cs = ColumnSet::new(p.rec as &dyn Columns);
    for (d, s) in dofs.iter().zip(&p.smooth) {
        cs.insert(d.clone(), s.x.clone())?;
        cs.insert(format!("{d}'"), s.v.clone())?;
    }
    Ok(cs)
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
    let mut terms = Vec::with_capacity(lib.len());
    for t in lib.terms() {
        if t.uses_input() {
            if full_cs.is_none() {
                full_cs = Some(smoothed_columns(p, dofs)?);
            }
            let fcs = full_cs.as_ref().expect("just set");
            let ser = term_series(t, fcs, &p.smooth, dofs, weak, debias)?;
            let lp = |v: &[f64]| decimate(&low_pass(v, p.dt, 0.8 * nyq), q);
            terms.push(match ser {
                Series::Plain(v) => Series::Plain(lp(&v)),
                Series::Transfer(v) => Series::Transfer(lp(&v)),
            });
        } else {
            terms.push(term_series(t, &cs, &smooth, dofs, weak, debias)?);
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
/// displacement powers noise-debiased when asked), from columns `cs` and reconstructions `smooth`.
fn term_series(
    t: &Term,
    cs: &ColumnSet<'_>,
    smooth: &[Smoothed],
    dofs: &[String],
    weak: bool,
    debias: bool,
) -> Result<Series> {
    // A single power of one DOF's displacement, evaluated without the noise bias.
    let debiased = |t: &Term| -> Option<Vec<f64>> {
        if !debias {
            return None;
        }
        match t.factors() {
            [Factor::Pow(Var::Disp(d), k)] => {
                let i = dofs.iter().position(|n| n == d)?;
                Some(hermite_power(&smooth[i].x, *k, smooth[i].band.noise_var))
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
/// shortest window (leakage ~1e-7 of the signal there; a fixed 25 % margin gave 100+ bins on the
/// peers records but could leave a handful on short ones). Non-polynomial terms give 1 (no
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
            let terms = lib
                .terms()
                .iter()
                .map(|t| term_series(t, &cs, &p.smooth, dofs, weak, debias))
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

/// Raw columns with Savitzky–Golay velocities, and the SG acceleration of DOF `dof`.
pub(crate) fn raw_columns_sg<'a>(
    rec: &'a Record,
    dofs: &[String],
    dof: usize,
    dt: f64,
    sg: (usize, usize),
) -> Result<(ColumnSet<'a>, Vec<f64>)> {
    let mut cs = ColumnSet::new(rec as &dyn Columns);
    let mut acc = Vec::new();
    for (i, d) in dofs.iter().enumerate() {
        let x = rec.column(d).expect("checked");
        let v = tfs_signal::savitzky_golay(x, dt, sg.0, sg.1, 1)?;
        cs.insert(format!("{d}'"), v)?;
        if i == dof {
            acc = tfs_signal::savitzky_golay(x, dt, sg.0, sg.1, 2)?;
        }
    }
    Ok((cs, acc))
}

/// Windowed transforms of one DOF of one record, at the bins that can be selected.
#[derive(Clone)]
pub(crate) struct WindowTransform {
    /// Frequencies (Hz) of the stored bins.
    pub freq: Vec<f64>,
    /// |LHS| relative to its maximum over the window's bins.
    pub rel_amp: Vec<f64>,
    /// LHS transform at the stored bins.
    pub lhs: Vec<Complex<f64>>,
    /// Term transforms at the stored bins (`cols[j][b]`).
    pub cols: Vec<Vec<Complex<f64>>>,
    /// Row weight of each stored bin (1 = unweighted; see [`reweight`]).
    pub weight: Vec<f64>,
}

/// Variance of the weak-form (or plain) transform of `x''` at each bin that the displacement
/// noise alone produces: for noise of two-sided density `S(f)` the windowed integral of
/// `n·(w'' − 2iωw' − ω²w)` has variance `S(f)·∫|w'' − 2iωw' − ω²w|² dt`
/// `= S(f)·(∫w''² − 2ω²∫w w'' + ω⁴∫w² + 4ω²∫w'²)`.
fn lhs_noise_var(win: &WindowSamples, om: &[f64], dt: f64, noise: &(Band, f64)) -> Vec<f64> {
    let (w, w1, w2) = (&win.w, &win.dw, &win.ddw);
    let int = |f: &dyn Fn(usize) -> f64| (0..w.len()).map(f).sum::<f64>() * dt;
    let i0 = int(&|i| w[i] * w[i]);
    let i1 = int(&|i| w1[i] * w1[i]);
    let i2 = int(&|i| w2[i] * w2[i]);
    let i02 = int(&|i| w[i] * w2[i]);
    om.iter()
        .map(|&w| {
            let f = w / (2.0 * std::f64::consts::PI);
            let g = (i2 - 2.0 * w * w * i02 + w.powi(4) * i0 + 4.0 * w * w * i1).max(0.0);
            noise.0.noise_psd(f, noise.1) * g
        })
        .collect()
}

/// Transforms of `count` overlapping windows; bins with |LHS| < `delta_min`·max are not stored,
/// nor (when `min_bin_snr` is given) bins whose |LHS|² is below `min_bin_snr` times the variance
/// the estimated displacement noise gives there — in those bins the noise of `x` on both sides
/// of the regression would bias the coefficients (errors in variables).
pub(crate) fn window_transforms(
    s: &RecordSeries,
    count: usize,
    delta_min: f64,
    min_bin_snr: Option<f64>,
) -> Vec<WindowTransform> {
    let dt = s.dt;
    let n = s.lhs.len();
    let (starts, len) = window_layout(n, count);
    let win = window(len, dt);
    let om = bin_omegas(len, dt);
    let df = 1.0 / (len as f64 * dt);
    let gate: Option<Vec<f64>> = match (min_bin_snr, &s.noise) {
        (Some(g), Some(nm)) if g > 0.0 => Some(
            lhs_noise_var(&win, &om, dt, nm)
                .into_iter()
                .map(|v| g * v)
                .collect(),
        ),
        _ => None,
    };
    starts
        .iter()
        .map(|&st| {
            let all: Vec<usize> = (0..om.len()).collect();
            let lhs_full = s.lhs_spectrum_at(st, &win, &om, &all);
            let max = lhs_full.iter().fold(0.0f64, |a, c| a.max(c.norm()));
            // The strongest bin is always kept so no window is left without rows.
            let top = (0..lhs_full.len())
                .max_by(|&a, &b| lhs_full[a].norm().total_cmp(&lhs_full[b].norm()))
                .unwrap_or(0);
            let bins: Vec<usize> = (0..lhs_full.len())
                .filter(|&k| max > 0.0 && lhs_full[k].norm() >= delta_min * max)
                .filter(|&k| {
                    k == top || gate.as_ref().is_none_or(|g| lhs_full[k].norm_sqr() >= g[k])
                })
                .collect();
            let cols = (0..s.terms.len())
                .map(|j| s.term_spectrum_at(j, st, &win, &om, &bins))
                .collect();
            WindowTransform {
                freq: bins.iter().map(|&k| k as f64 * df).collect(),
                rel_amp: bins.iter().map(|&k| lhs_full[k].norm() / max).collect(),
                lhs: bins.iter().map(|&k| lhs_full[k]).collect(),
                cols,
                weight: vec![1.0; bins.len()],
            }
        })
        .collect()
}

/// Real rows (real and imaginary parts stacked) of the bins with relative amplitude ≥ `delta`,
/// restricted to the columns `keep`, each bin's rows multiplied by its weight. Returns (A, b,
/// kept bin frequencies).
pub(crate) fn rows_for(
    w: &WindowTransform,
    delta: f64,
    keep: &[usize],
) -> (Mat<f64>, Vec<f64>, Vec<f64>) {
    rows_for_band(w, delta, f64::INFINITY, keep)
}

/// The rows of [`rows_for`] of every window of `wins`, stacked in order (written straight into
/// one matrix).
fn stacked_rows<'w>(
    wins: impl Iterator<Item = &'w WindowTransform> + Clone,
    delta: f64,
    keep: &[usize],
) -> (Mat<f64>, Vec<f64>) {
    let rows: Vec<Vec<(usize, bool)>> = wins
        .clone()
        .map(|w| bin_rows(w, delta, f64::INFINITY))
        .collect();
    let total: usize = rows.iter().map(Vec::len).sum();
    let mut a = Mat::<f64>::zeros(total, keep.len());
    let mut y = Vec::with_capacity(total);
    for (w, rows) in wins.zip(&rows) {
        write_rows(w, rows, keep, &mut a, &mut y);
    }
    (a, y)
}

/// The rows of the bins of `w` with `lo ≤` relative amplitude `< hi`: `(bin, imaginary part)`,
/// a real row for every bin and an imaginary one unless it is DC.
fn bin_rows(w: &WindowTransform, lo: f64, hi: f64) -> Vec<(usize, bool)> {
    let mut rows = Vec::new();
    for b in (0..w.lhs.len()).filter(|&b| w.rel_amp[b] >= lo && w.rel_amp[b] < hi) {
        rows.push((b, false));
        if w.freq[b] > 0.0 {
            rows.push((b, true));
        }
    }
    rows
}

/// Writes the weighted rows `rows` of `w` over the columns `keep` into `a` from row `y.len()`
/// on, and their left-hand sides onto `y`.
fn write_rows(
    w: &WindowTransform,
    rows: &[(usize, bool)],
    keep: &[usize],
    a: &mut Mat<f64>,
    y: &mut Vec<f64>,
) {
    let start = y.len();
    let part = |c: Complex<f64>, im: bool| if im { c.im } else { c.re };
    for (k, &j) in keep.iter().enumerate() {
        let col = &w.cols[j];
        let out = &mut a.col_as_slice_mut(k)[start..start + rows.len()];
        for (o, &(b, im)) in out.iter_mut().zip(rows) {
            *o = part(col[b] * w.weight[b], im);
        }
    }
    y.extend(rows.iter().map(|&(b, im)| part(w.lhs[b] * w.weight[b], im)));
}

/// [`rows_for`] restricted to the bins with `lo ≤` relative amplitude `< hi`: the rows a smaller
/// δ adds to a larger one's (the kept sets are nested in δ).
pub(crate) fn rows_for_band(
    w: &WindowTransform,
    lo: f64,
    hi: f64,
    keep: &[usize],
) -> (Mat<f64>, Vec<f64>, Vec<f64>) {
    let rows = bin_rows(w, lo, hi);
    let mut a = Mat::<f64>::zeros(rows.len(), keep.len());
    let mut y = Vec::with_capacity(rows.len());
    write_rows(w, &rows, keep, &mut a, &mut y);
    let freqs = rows
        .iter()
        .filter(|(_, im)| !im)
        .map(|&(b, _)| w.freq[b])
        .collect();
    (a, y, freqs)
}

/// Owned columns of equal length (a strided subsample of a [`ColumnSet`]).
pub(crate) struct OwnedColumns {
    rows: usize,
    cols: Vec<(String, Vec<f64>)>,
}

impl OwnedColumns {
    /// These columns plus `s` times the column of the same name in `other` (a column `other`
    /// lacks is kept as it is).
    pub(crate) fn plus_scaled(&self, s: f64, other: &OwnedColumns) -> OwnedColumns {
        OwnedColumns {
            rows: self.rows,
            cols: self
                .cols
                .iter()
                .map(|(name, v)| {
                    let v = match other.column(name) {
                        Some(o) => v.iter().zip(o).map(|(a, b)| a + s * b).collect(),
                        None => v.clone(),
                    };
                    (name.clone(), v)
                })
                .collect(),
        }
    }
}

impl Columns for OwnedColumns {
    fn column(&self, name: &str) -> Option<&[f64]> {
        self.cols
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
    fn rows(&self) -> usize {
        self.rows
    }
}

/// Time-domain library matrix and target on the band-limited reconstruction (ends trimmed, every
/// `stride`-th sample). Only the sampled rows are evaluated.
pub(crate) fn time_domain(
    p: &Prepared<'_>,
    dofs: &[String],
    dof: usize,
    lib: &Library,
    trim: usize,
    stride: usize,
) -> Result<(Mat<f64>, Vec<f64>)> {
    let cs = smoothed_columns(p, dofs)?;
    let n = p.rec.len();
    if n <= 2 * trim + lib.len() + 2 {
        return Err(CriteriaError::Invalid(format!(
            "record '{}' is too short ({n} samples) for a library of {} terms",
            p.rec.source(),
            lib.len()
        )));
    }
    let stride = stride.max(1);
    let sub =
        |v: &[f64]| -> Vec<f64> { v[trim..n - trim].iter().step_by(stride).copied().collect() };
    let rows = (n - 2 * trim).div_ceil(stride);
    // Columns the library needs; a missing one is left out so the evaluation names it.
    let cols = lib
        .required_columns()
        .into_iter()
        .filter_map(|c| cs.column(&c).map(|v| (c.clone(), sub(v))))
        .collect();
    let a = lib.evaluate(&OwnedColumns { rows, cols })?;
    let y = sub(&p.smooth[dof].a);
    Ok((a, y))
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

/// Stored bins on each side of a bin whose residual powers are averaged by [`reweight`].
pub(crate) const REWEIGHT_HALF: usize = 16;

/// Feasible generalised least squares on the frequency-domain rows of one window layout (`recs`:
/// the windows of every record). The rows of different bins carry very different noise — the
/// weak-form `x''` row carries `ω²` times the displacement noise, and coloured (e.g. pink) noise
/// has a density that changes by orders of magnitude across the band — so equal weights let the
/// noisiest bins dominate. Each pass fits every column of `keep` by least squares on the bins with
/// relative amplitude ≥ `delta`, takes the residual power `|ê_b|²` of every stored bin, averages
/// it over the `2·REWEIGHT_HALF + 1` neighbouring stored bins of the same window (a local noise
/// level that does not follow one bin's chance residual), and sets the bin's weight to
/// `1/√(that power)`. Weights are normalised to unit mean square; a fit that fails leaves the
/// weights as they were.
pub(crate) fn reweight(
    recs: &mut [Vec<WindowTransform>],
    delta: f64,
    keep: &[usize],
    passes: usize,
) -> Result<()> {
    use tfs_regress::{Compressed, lstsq_support};
    if keep.is_empty() {
        return Ok(());
    }
    for _ in 0..passes {
        // Every window's rows stacked and compressed in one call (its cache-sized chunks are
        // far cheaper than one small QR per window).
        let (a, y) = stacked_rows(recs.iter().flatten(), delta, keep);
        if y.is_empty() {
            return Ok(());
        }
        let all = Compressed::from_rows(a.as_ref(), &y)?;
        let Ok(fit) = lstsq_support(&all, &vec![true; keep.len()]) else {
            return Ok(());
        };
        if fit.coef.iter().any(|c| !c.is_finite()) {
            return Ok(());
        }
        let mut power: Vec<Vec<f64>> = Vec::new();
        for w in recs.iter().flatten() {
            let e: Vec<f64> = (0..w.lhs.len())
                .map(|b| {
                    let mut r = w.lhs[b];
                    for (j, &c) in keep.iter().zip(&fit.coef) {
                        r -= w.cols[*j][b] * c;
                    }
                    r.norm_sqr()
                })
                .collect();
            let n = e.len();
            power.push(
                (0..n)
                    .map(|b| {
                        let lo = b.saturating_sub(REWEIGHT_HALF);
                        let hi = (b + REWEIGHT_HALF + 1).min(n);
                        e[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
                    })
                    .collect(),
            );
        }
        let mut all_p: Vec<f64> = power.iter().flatten().copied().collect();
        if all_p.is_empty() {
            return Ok(());
        }
        let mid = all_p.len() / 2;
        let med = *all_p.select_nth_unstable_by(mid, f64::total_cmp).1;
        if !(med.is_finite() && med > 0.0) {
            return Ok(());
        }
        // A floor keeps a bin the fit happens to match exactly from taking all the weight.
        let floor = 1e-6 * med;
        for (w, p) in recs.iter_mut().flatten().zip(&power) {
            w.weight = p.iter().map(|v| 1.0 / v.max(floor).sqrt()).collect();
        }
    }
    // Unit mean square over the stored bins (the scale does not change any fit; it keeps the
    // rows' magnitudes comparable with the unweighted ones in traces).
    let (ss, n) = recs
        .iter()
        .flatten()
        .flat_map(|w| w.weight.iter())
        .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n > 0 && ss > 0.0 {
        let k = (n as f64 / ss).sqrt();
        recs.iter_mut()
            .flatten()
            .for_each(|w| w.weight.iter_mut().for_each(|v| *v *= k));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use tfs_regress::{Compressed, lstsq_support};
    use tfs_signal::NoiseKind;
    use tfs_signal::noise::noise_for;

    /// The reweighting's stacked rows are exactly the rows of every window one after another,
    /// with DC bins giving one row and an infinite relative amplitude none (as `rows_for`).
    #[test]
    fn stacked_rows_are_the_windows_rows_in_order() {
        let win = |k: usize, seed: f64| {
            let c = |b: usize, j: usize| {
                Complex::new(
                    (seed + b as f64 * 0.7 + j as f64).sin(),
                    (b as f64 - seed).cos(),
                )
            };
            let rel_amp: Vec<f64> = (0..k)
                .map(|b| match b {
                    3 => f64::INFINITY,
                    5 => f64::NAN,
                    _ => ((b as f64 + seed) * 1.3).sin().abs(),
                })
                .collect();
            WindowTransform {
                freq: (0..k).map(|b| b as f64 * 0.1).collect(),
                rel_amp,
                lhs: (0..k).map(|b| c(b, 9)).collect(),
                cols: (0..4).map(|j| (0..k).map(|b| c(b, j)).collect()).collect(),
                weight: (0..k).map(|b| 1.0 + 0.01 * b as f64).collect(),
            }
        };
        let wins = [win(12, 0.2), win(7, 1.1), win(20, 2.5)];
        let keep = [0, 2, 3];
        let (a, y) = stacked_rows(wins.iter(), 0.3, &keep);
        let mut row = 0;
        for w in &wins {
            let (wa, wy, _) = rows_for(w, 0.3, &keep);
            for i in 0..wa.nrows() {
                assert_eq!(y[row + i], wy[i]);
                for j in 0..keep.len() {
                    assert_eq!(a[(row + i, j)], wa[(i, j)]);
                }
            }
            row += wa.nrows();
        }
        assert_eq!((row, a.nrows(), y.len()), (a.nrows(), row, row));
        assert!(row > 0);
    }

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
        let p = prepare(&rec, &dofs, Some(fc), 0.0).unwrap();
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

    /// Unit-variance white noise (seeded).
    fn gauss(n: usize, seed: u64) -> Vec<f64> {
        noise_for(&vec![1.0; n], 0.0, NoiseKind::White, seed).expect("noise")
    }

    /// Two windows of 200 bins, `y = 1.5·θ0 − 0.7·θ1 + e` with noise sd 1 in the lower half of
    /// the bins and 10 in the upper half.
    fn windows() -> Vec<Vec<WindowTransform>> {
        let nb = 200;
        (0..2u64)
            .map(|w| {
                let g: Vec<Vec<f64>> = (0..6).map(|k| gauss(nb, 10 * w + k)).collect();
                let c = |a: usize, b: usize| -> Vec<Complex<f64>> {
                    (0..nb).map(|i| Complex::new(g[a][i], g[b][i])).collect()
                };
                let cols = vec![c(0, 1), c(2, 3)];
                let lhs = (0..nb)
                    .map(|i| {
                        let s = if i < nb / 2 { 1.0 } else { 10.0 };
                        cols[0][i] * 1.5 - cols[1][i] * 0.7 + Complex::new(g[4][i], g[5][i]) * s
                    })
                    .collect();
                vec![WindowTransform {
                    freq: (1..=nb).map(|k| k as f64 * 0.1).collect(),
                    rel_amp: vec![1.0; nb],
                    lhs,
                    cols,
                    weight: vec![1.0; nb],
                }]
            })
            .collect()
    }

    fn fit(recs: &[Vec<WindowTransform>]) -> Vec<f64> {
        let parts: Vec<Compressed> = recs
            .iter()
            .flatten()
            .map(|w| {
                let (a, y, _) = rows_for(w, 0.5, &[0, 1]);
                Compressed::from_rows(a.as_ref(), &y).expect("rows")
            })
            .collect();
        let all = Compressed::merge(&parts).expect("merge");
        lstsq_support(&all, &[true, true]).expect("fit").coef
    }

    #[test]
    fn reweight_follows_the_noise_level_and_sharpens_the_fit() {
        let mut recs = windows();
        let plain = fit(&recs);
        reweight(&mut recs, 0.5, &[0, 1], 2).expect("reweight");
        // Weights ≈ 1/noise sd: the noisy half gets about a tenth of the weight (away from the
        // boundary, where the smoothing mixes the halves).
        let w = &recs[0][0].weight;
        let lo = w[10..90].iter().sum::<f64>() / 80.0;
        let hi = w[110..190].iter().sum::<f64>() / 80.0;
        let ratio = hi / lo;
        assert!((0.05..0.2).contains(&ratio), "weight ratio {ratio}");
        // Unit mean square.
        let ms = recs
            .iter()
            .flatten()
            .flat_map(|t| t.weight.iter())
            .map(|v| v * v)
            .sum::<f64>()
            / 400.0;
        assert!((ms - 1.0).abs() < 1e-9, "mean square weight {ms}");
        let gls = fit(&recs);
        let err = |c: &[f64]| ((c[0] - 1.5).powi(2) + (c[1] + 0.7).powi(2)).sqrt();
        assert!(
            err(&gls) < err(&plain),
            "weighted error {} vs equal weights {}",
            err(&gls),
            err(&plain)
        );
    }

    #[test]
    fn rows_scale_with_the_bin_weight() {
        let mut recs = windows();
        let (a1, y1, _) = rows_for(&recs[0][0], 0.5, &[0, 1]);
        recs[0][0].weight = (0..200).map(|i| 1.0 + i as f64).collect();
        let (a2, y2, _) = rows_for(&recs[0][0], 0.5, &[0, 1]);
        for i in 0..a1.nrows() {
            let wt = 1.0 + (i / 2) as f64;
            assert!((y2[i] - wt * y1[i]).abs() <= 1e-12 * (1.0 + y2[i].abs()));
            for j in 0..2 {
                assert!((a2[(i, j)] - wt * a1[(i, j)]).abs() <= 1e-12 * (1.0 + a2[(i, j)].abs()));
            }
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
        let h2 = hermite_power(&y, 2, s2);
        let h3 = hermite_power(&y, 3, s2);
        for ((&v, a), b) in y.iter().zip(h2).zip(h3) {
            assert!((a - (v * v - s2)).abs() < 1e-14);
            assert!((b - (v * v * v - 3.0 * s2 * v)).abs() < 1e-13);
        }
    }
}
