//! Smoothed states (x, x', x'') of measured records, and the block/fold layout used for held-out
//! evaluation.
//!
//! Derivatives come from the spectral differentiator of `tfs-signal` with a cut-off chosen from the
//! displacement spectrum: the noise floor is the median amplitude of the upper half of the band
//! (oversampled vibration data has no signal there; `tfs_signal`'s [`NoiseFloor`] with one
//! sub-band), and the cut-off is 10 % above the highest
//! frequency whose amplitude is at least [`DiagnoseOptions::floor_factor`] times that floor.
//! Rows within three cut-off periods of either end are not used (end effects of the transform).

use tfs_data::{Columns, Record};
use tfs_library::Model;
use tfs_signal::{NoiseFloor, amplitude_spectrum, spectral_derivative};

use crate::{DiagnoseError, Result};

/// Measured here ([`DataScales::measure`]), defined beside the effects it is told to.
pub(crate) use crate::effects::DataScales;

/// Options shared by compare, localise, explain and refit.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseOptions {
    /// Low-pass cut-off (Hz) for the smoothed states; `None` chooses it from the spectrum.
    pub cutoff_hz: Option<f64>,
    /// A spectral bin is signal when its amplitude is at least this many times the noise floor.
    pub floor_factor: f64,
    /// Target number of held-out blocks over all records (for the paired test and bootstrap).
    pub blocks: usize,
    /// Contiguous time folds when there is only one record.
    pub time_folds: usize,
    /// Family-wise significance level (Bonferroni over every candidate variant tested).
    pub alpha: f64,
    /// Minimum size of an effect: RMS change of the fitted force over the RMS of `x''`, or, on
    /// the motion, the drop of the held-out RMS prediction error over the displacement's RMS.
    pub min_share: f64,
    /// Bootstrap resamples of blocks for coefficient intervals.
    pub bootstrap: usize,
    /// Seed of the bootstrap.
    pub seed: u64,
    /// Time windows per record for the windowed R-MSE and residual RMS.
    pub windows: usize,
    /// Bins per axis of the (x, x') residual map.
    pub bins: usize,
    /// Highest stiffness power offered by the catalogue.
    pub max_power: u32,
    /// Simulate refitted candidates on held-out data (`r_mse_after`); off saves time.
    pub simulate: bool,
    /// Synthetic draws of the calibrated null (the start model's own simulations with the
    /// estimated measurement noise) that every candidate passing the block tests is scanned on
    /// again (`null.rs`); below 2 switches the null off. Needs `simulate`.
    pub null_draws: usize,
    /// After an effect is added ([`crate::add_effect_with`]), also re-estimate the extended
    /// model's coefficients by simulation error on the records (multiple shooting, as
    /// `tfs refit --refine` does) and keep that fit when its free runs predict the records
    /// better. Off by default (the diagnosis's own refits of every candidate stay equation-error
    /// fits, fast); `tfs refit` and the Python `refit` switch it on for the effects they add.
    pub refine_added: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            cutoff_hz: None,
            floor_factor: 10.0,
            blocks: 32,
            time_folds: 4,
            alpha: 0.01,
            min_share: 0.02,
            bootstrap: 200,
            seed: 1,
            windows: 10,
            bins: 12,
            max_power: 7,
            simulate: true,
            null_draws: 8,
            refine_added: false,
        }
    }
}

impl DiagnoseOptions {
    /// Checks every field.
    pub fn validate(&self) -> Result<()> {
        let bad = |name, reason: &str| {
            Err(DiagnoseError::InvalidParameter {
                name,
                reason: reason.to_string(),
            })
        };
        if let Some(fc) = self.cutoff_hz
            && !(fc.is_finite() && fc > 0.0)
        {
            return bad("cutoff_hz", "must be a positive frequency in Hz or None");
        }
        if !(self.floor_factor.is_finite() && self.floor_factor > 1.0) {
            return bad("floor_factor", "must be a finite number above 1");
        }
        if self.blocks < 8 {
            return bad("blocks", "must be at least 8");
        }
        if self.time_folds < 2 {
            return bad("time_folds", "must be at least 2");
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return bad("alpha", "must be in (0, 1)");
        }
        if !(self.min_share.is_finite() && self.min_share >= 0.0) {
            return bad("min_share", "must be finite and >= 0");
        }
        if self.windows == 0 || self.bins < 2 {
            return bad("windows/bins", "need at least 1 window and 2 bins");
        }
        Ok(())
    }
}

/// Checks that every record has the model's DOF and input columns (computed effect columns are
/// exempt: they are derived from the record).
pub fn check_records(model: &Model, records: &[Record]) -> Result<()> {
    if records.is_empty() {
        return Err(DiagnoseError::NoRecords);
    }
    let computed = crate::effects::computed_columns(model);
    for r in records {
        for c in model.dofs.iter().chain(model.inputs.iter()) {
            if computed.iter().any(|cc| cc.name() == *c) {
                continue;
            }
            if r.column(c).is_none() {
                return Err(DiagnoseError::DofMismatch {
                    record: r.source().to_string(),
                    column: c.clone(),
                    dofs: model.dofs.join(", "),
                    inputs: model.inputs.join(", "),
                    available: r.names().join(", "),
                });
            }
        }
    }
    Ok(())
}

/// Chooses a low-pass cut-off for `x` from its spectrum (see the module docs).
pub fn choose_cutoff(x: &[f64], dt: f64, floor_factor: f64) -> Result<f64> {
    let n = x.len();
    if n < 16 {
        return Err(DiagnoseError::TooShort {
            what: "signal for the cut-off".into(),
            got: n,
            needed: 16,
        });
    }
    let slope = (x[n - 1] - x[0]) / (n - 1) as f64;
    let detrended: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(k, v)| v - x[0] - slope * k as f64)
        .collect();
    let (f, amp) = amplitude_spectrum(&detrended, dt)?;
    let floor = NoiseFloor::fit_with(&amp, 1, 1.0)
        .at(1)
        .max(f64::MIN_POSITIVE);
    let last = (1..amp.len())
        .rev()
        .find(|&k| amp[k] >= floor_factor * floor)
        .unwrap_or(1);
    let nyq = f[f.len() - 1];
    Ok((1.1 * f[last]).min(0.9 * nyq).max(f[1.min(f.len() - 1)]))
}

/// Smoothed columns of one record: low-passed displacements (named like the DOFs), velocities
/// (`"x'"`), low-passed inputs, and accelerations per DOF. Implements [`Columns`].
#[derive(Debug, Clone)]
pub struct RecordStates {
    /// The record as measured.
    pub record: Record,
    /// The cut-off used (Hz).
    pub cutoff_hz: f64,
    /// Rows skipped at each end.
    pub margin: usize,
    /// Smoothed accelerations, one vector per DOF (model order).
    pub acc: Vec<Vec<f64>>,
    /// The model's DOFs, in the order of `acc`.
    pub(crate) dofs: Vec<String>,
    cols: Vec<(String, Vec<f64>)>,
    /// Design columns made once and shared by every variant's design ([`BandCache`]).
    pub(crate) band_cache: BandCache,
}

/// The usable rows of the design columns of one record's plain monomials and states (`x^3`,
/// `x^2·x'`, `x'`, an input), and of its targets (the smoothed accelerations), made once per
/// record and shared by every variant's design: every variant's design holds the start
/// equation's terms, band-limiting a column is a forward and an inverse transform of the whole
/// record, and a copy per design would hold the record's rows once per variant alive. Only
/// monomials are kept (at most the library's own terms; an effect's parameter scan makes a new
/// column per value and is not kept). Each column is keyed by its term and the rows, cut-off and
/// record length it was made with; a copy of the states starts with an empty cache, and
/// [`RecordStates::set`] empties it.
#[derive(Default)]
pub(crate) struct BandCache {
    columns: std::sync::Mutex<Vec<(BandKey, std::sync::Arc<Vec<f64>>)>>,
    /// Per (DOF, first usable row, usable rows): the smoothed acceleration's usable rows.
    targets: std::sync::Mutex<Vec<(TargetKey, std::sync::Arc<Vec<f64>>)>>,
}

/// A cached target: its DOF, first usable row and usable rows.
type TargetKey = (usize, usize, usize);

/// What a cached column was made from: its term, first usable row, usable rows, the cut-off's
/// bits and the record's length.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BandKey(
    pub tfs_library::Term,
    pub usize,
    pub usize,
    pub u64,
    pub usize,
);

impl BandCache {
    /// The cached column of `key`, if made.
    pub(crate) fn get(&self, key: &BandKey) -> Option<std::sync::Arc<Vec<f64>>> {
        let slots = self.columns.lock().ok()?;
        slots.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone())
    }

    /// Keeps `values` as the column of `key` (the first kept stays when two threads made it).
    pub(crate) fn put(&self, key: BandKey, values: std::sync::Arc<Vec<f64>>) {
        if let Ok(mut slots) = self.columns.lock()
            && !slots.iter().any(|(k, _)| *k == key)
        {
            slots.push((key, values));
        }
    }

    /// Forgets every column and target (their memory is freed once no design holds them).
    fn clear(&self) {
        if let Ok(mut slots) = self.columns.lock() {
            slots.clear();
        }
        if let Ok(mut slots) = self.targets.lock() {
            slots.clear();
        }
    }
}

impl Clone for BandCache {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for BandCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.columns.lock().map_or(0, |s| s.len());
        let t = self.targets.lock().map_or(0, |s| s.len());
        write!(f, "BandCache({n} columns, {t} targets)")
    }
}

impl Columns for RecordStates {
    fn column(&self, name: &str) -> Option<&[f64]> {
        self.cols
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
            .or_else(|| self.record.column(name))
    }
    fn rows(&self) -> usize {
        self.record.len()
    }
}

impl RecordStates {
    /// Estimates the smoothed states of `record` for the DOFs and inputs of `model`.
    pub fn new(model: &Model, record: &Record, opts: &DiagnoseOptions) -> Result<Self> {
        let dt = record.dt();
        let mut fc = f64::INFINITY;
        let raw: Vec<&[f64]> = model
            .dofs
            .iter()
            .map(|d| {
                record
                    .column(d)
                    .ok_or_else(|| crate::prepare::missing(model, record, d))
            })
            .collect::<Result<_>>()?;
        match opts.cutoff_hz {
            Some(c) => fc = c,
            None => {
                let mut best: f64 = 0.0;
                for x in &raw {
                    best = best.max(choose_cutoff(x, dt, opts.floor_factor)?);
                }
                fc = fc.min(best);
            }
        }
        let mut cols = Vec::new();
        let mut acc = Vec::new();
        for (d, x) in model.dofs.iter().zip(&raw) {
            cols.push((d.clone(), spectral_derivative(x, dt, 0, Some(fc))?));
            cols.push((format!("{d}'"), spectral_derivative(x, dt, 1, Some(fc))?));
            acc.push(spectral_derivative(x, dt, 2, Some(fc))?);
        }
        let computed = crate::effects::computed_columns(model);
        for inp in &model.inputs {
            if computed.iter().any(|c| c.name() == *inp) {
                continue;
            }
            let u = record
                .column(inp)
                .ok_or_else(|| missing(model, record, inp))?;
            cols.push((inp.clone(), spectral_derivative(u, dt, 0, Some(fc))?));
        }
        // Inputs the record carries that the model lost, for the input effects to offer back.
        for inp in crate::effects::lost_inputs(model, |c| record.column(c).is_some()) {
            if let Some(u) = record.column(&inp) {
                cols.push((inp, spectral_derivative(u, dt, 0, Some(fc))?));
            }
        }
        for c in &computed {
            let src = c.source();
            if !cols.iter().any(|(n, _)| *n == src) {
                let u = record
                    .column(&src)
                    .ok_or_else(|| missing(model, record, &src))?;
                cols.push((src, spectral_derivative(u, dt, 0, Some(fc))?));
            }
        }
        let margin = ((3.0 / (fc * dt)).ceil() as usize).max(5);
        let mut out = Self {
            record: record.clone(),
            cutoff_hz: fc,
            margin,
            acc,
            dofs: model.dofs.clone(),
            cols,
            band_cache: BandCache::default(),
        };
        for c in computed {
            let v = c.compute(&out, dt)?;
            out.cols.push((c.name(), v));
        }
        Ok(out)
    }

    /// Adds (or replaces) a derived column.
    pub fn set(&mut self, name: String, values: Vec<f64>) {
        self.band_cache.clear();
        match self.cols.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 = values,
            None => self.cols.push((name, values)),
        }
    }

    /// Forgets the design columns and targets made so far ([`BandCache`]): for a stage after the
    /// scan, which reads none of them again (a design made later makes its own, to the bit the
    /// same), so that they do not outlive it; at 640,000 samples they are 5 MB a column.
    pub(crate) fn forget_designs(&self) {
        self.band_cache.clear();
    }

    /// Rows `lo..lo + n` of the smoothed acceleration of DOF `dof`, made once
    /// ([`BandCache`]).
    pub(crate) fn target(&self, dof: usize, lo: usize, n: usize) -> std::sync::Arc<Vec<f64>> {
        let key = (dof, lo, n);
        let slots = &self.band_cache.targets;
        if let Some(hit) = slots
            .lock()
            .ok()
            .and_then(|s| s.iter().find(|(k, _)| *k == key).map(|(_, v)| v.clone()))
        {
            return hit;
        }
        let out = std::sync::Arc::new(self.acc[dof][lo..lo + n].to_vec());
        if let Ok(mut s) = slots.lock()
            && !s.iter().any(|(k, _)| *k == key)
        {
            s.push((key, out.clone()));
        }
        out
    }

    /// Number of usable rows (record length minus both margins).
    pub fn usable(&self) -> usize {
        self.record.len().saturating_sub(2 * self.margin)
    }

    /// Minimum block length: four cut-off periods.
    pub fn min_block(&self) -> usize {
        ((4.0 / (self.cutoff_hz * self.record.dt())).ceil() as usize).max(10)
    }
}

pub(crate) fn missing(model: &Model, record: &Record, column: &str) -> DiagnoseError {
    DiagnoseError::DofMismatch {
        record: record.source().to_string(),
        column: column.to_string(),
        dofs: model.dofs.join(", "),
        inputs: model.inputs.join(", "),
        available: record.names().join(", "),
    }
}

/// One contiguous block of usable rows of one record.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// Record index.
    pub record: usize,
    /// First usable row (0 = the first row after the margin).
    pub start: usize,
    /// Number of rows.
    pub len: usize,
    /// The fold this block is held out in.
    pub fold: usize,
}

/// Blocks and folds for held-out evaluation: folds are records when there are several (at most
/// ten folds; records beyond that share folds round-robin), otherwise contiguous time segments.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// The blocks, record by record in time order.
    pub blocks: Vec<Block>,
    /// Number of folds.
    pub folds: usize,
    /// True when folds are records, false when they are time segments of one record.
    pub by_record: bool,
}

impl Layout {
    /// Builds the layout; errors when the records cannot hold 8 blocks of the minimum length.
    pub fn new(states: &[RecordStates], opts: &DiagnoseOptions) -> Result<Self> {
        let min_block = states.iter().map(|s| s.min_block()).max().unwrap_or(10);
        let total: usize = states.iter().map(|s| s.usable()).sum();
        let needed = 8 * min_block;
        if total < needed {
            return Err(DiagnoseError::TooShort {
                what: states
                    .iter()
                    .map(|s| s.record.source().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                got: total,
                needed,
            });
        }
        let by_record = states.len() >= 2;
        let folds = if by_record {
            states.len().min(10)
        } else {
            opts.time_folds
        };
        let mut blocks = Vec::new();
        for (r, s) in states.iter().enumerate() {
            let u = s.usable();
            let share = (opts.blocks as f64 * u as f64 / total as f64).round() as usize;
            let mut nb = share.max(1).min(u / min_block.max(1)).max(1);
            if !by_record {
                nb = nb.max(folds).div_ceil(folds) * folds;
                nb = nb.min((u / min_block).max(folds));
            }
            for b in 0..nb {
                let start = b * u / nb;
                let end = (b + 1) * u / nb;
                let fold = if by_record { r % folds } else { b * folds / nb };
                if end > start {
                    blocks.push(Block {
                        record: r,
                        start,
                        len: end - start,
                        fold,
                    });
                }
            }
        }
        Ok(Self {
            blocks,
            folds,
            by_record,
        })
    }
}

/// The variance of `x` about its mean.
pub(crate) fn variance(x: &[f64]) -> f64 {
    let n = x.len().max(1) as f64;
    let m = x.iter().sum::<f64>() / n;
    x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n
}

/// Root mean square of a slice (0 for an empty slice).
pub(crate) fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
    }
}

/// Dominant period (s) of a signal: the inverse of its spectral peak (DC excluded).
pub(crate) fn dominant_period(x: &[f64], dt: f64) -> Result<f64> {
    let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
    let centred: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let (f, a) = amplitude_spectrum(&centred, dt)?;
    let k = (1..a.len())
        .max_by(|&i, &j| a[i].total_cmp(&a[j]))
        .unwrap_or(1);
    Ok(1.0 / f[k.min(f.len() - 1)].max(f[1.min(f.len() - 1)]))
}

/// RMS-frequency period (s) of a signal: `1/f_rms` with `f_rms² = Σ f²·|X(f)|² / Σ |X(f)|²`
/// over its spectrum (mean removed). `‖u'‖ = 2π f_rms ‖u‖`, so this is the time scale on which a
/// shift or a smoothing of the signal changes it: a delay δ changes `u` by about `2π δ/T` of its
/// RMS. NaN for a constant signal.
pub(crate) fn rms_frequency_period(x: &[f64], dt: f64) -> Result<f64> {
    let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
    let centred: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let (f, a) = amplitude_spectrum(&centred, dt)?;
    let (mut num, mut den) = (0.0, 0.0);
    for (fi, ai) in f.iter().zip(&a).skip(1) {
        num += fi * fi * ai * ai;
        den += ai * ai;
    }
    Ok(if num > 0.0 {
        (den / num).sqrt()
    } else {
        f64::NAN
    })
}

impl DataScales {
    /// Measures the scales of DOF `idx` of `model`, whose equation has the terms `terms`, on
    /// `states`.
    pub(crate) fn measure(
        model: &Model,
        idx: usize,
        terms: &[tfs_library::Term],
        states: &[RecordStates],
    ) -> Result<Self> {
        let dof = &model.dofs[idx];
        let vname = format!("{dof}'");
        let mut vel = Vec::new();
        let mut periods = Vec::new();
        let mut input_periods = Vec::new();
        let mut inputs = crate::effects::linear_inputs(terms);
        let lost_inputs = if inputs.is_empty() {
            crate::effects::lost_inputs(model, |c| states.iter().all(|s| s.column(c).is_some()))
        } else {
            Vec::new()
        };
        if inputs.is_empty() {
            inputs = lost_inputs.clone();
        }
        let (mut xsum, mut xn) = (0.0, 0usize);
        let vars = crate::effects::coordinates(
            tfs_library::Var::Disp(dof.clone()),
            terms,
            tfs_library::Var::is_displacement,
        );
        let mut ranges: Vec<(tfs_library::Var, f64, f64)> = vars
            .iter()
            .map(|v| (v.clone(), f64::INFINITY, f64::NEG_INFINITY))
            .collect();
        // Per coordinate: count, sum and sum of squares over the usable rows.
        let mut moments = vec![(0usize, 0.0f64, 0.0f64); vars.len()];
        for s in states {
            let used = s.margin..s.margin + s.usable();
            let v = s.column(&vname).unwrap_or(&[]);
            vel.extend_from_slice(&v[used.start.min(v.len())..used.end.min(v.len())]);
            let x = s.column(dof).unwrap_or(&[]);
            periods.push(dominant_period(x, s.record.dt())?);
            for name in &inputs {
                if let Some(u) = s.column(name) {
                    let uu = &u[used.start.min(u.len())..used.end.min(u.len())];
                    let p = rms_frequency_period(uu, s.record.dt())?;
                    if p.is_finite() && p > 0.0 {
                        input_periods.push(p);
                    }
                }
            }
            let xu = &x[used.start.min(x.len())..used.end.min(x.len())];
            xsum += xu.iter().sum::<f64>();
            xn += xu.len();
            for ((var, lo, hi), m) in ranges.iter_mut().zip(&mut moments) {
                let q = tfs_library::evaluate_term(&tfs_library::Term::var(var.clone()), s)?;
                for &val in &q[used.start.min(q.len())..used.end.min(q.len())] {
                    *lo = lo.min(val);
                    *hi = hi.max(val);
                    m.0 += 1;
                    m.1 += val;
                    m.2 += val * val;
                }
            }
        }
        periods.sort_by(f64::total_cmp);
        input_periods.sort_by(f64::total_cmp);
        let shortest_record = states
            .iter()
            .map(|s| s.record.dt() * s.record.len().saturating_sub(1) as f64)
            .fold(f64::INFINITY, f64::min);
        Ok(Self {
            lost_inputs,
            shortest_record,
            input_period: input_periods
                .get(input_periods.len() / 2)
                .copied()
                .unwrap_or(f64::NAN),
            velocity: rms(&vel),
            period: periods.get(periods.len() / 2).copied().unwrap_or(f64::NAN),
            mean: if xn > 0 { xsum / xn as f64 } else { 0.0 },
            rms: vars
                .iter()
                .zip(&moments)
                .filter(|(_, m)| m.0 > 0)
                .map(|(v, &(n, s, s2))| {
                    let mean = s / n as f64;
                    (v.clone(), (s2 / n as f64 - mean * mean).max(0.0).sqrt())
                })
                .collect(),
            ranges: ranges.into_iter().filter(|(_, lo, hi)| hi > lo).collect(),
        })
    }
}
