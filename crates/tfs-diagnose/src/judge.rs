//! How a candidate's refitted model is judged on held-out data, and by which judge.
//!
//! The free-run simulation under the measured input is the judge the user sees (`compare`), and
//! the default. When a candidate the equation error found significant cannot be simulated from
//! the record's start, every candidate's per-fold models run instead over each held-out unit's
//! rows from the smoothed measured state at its first row (internal states from the record's
//! tracks): the rows their equations were fitted on, not the smoothing margin before them
//! (`explain.rs`). It cannot rank models when a fresh draw of the measured input's own noise
//! moves the simulation about as far as the model's error (a multi-stable structure swept through
//! chaotic snap-through: which well it is in decides the error, and the noise decides the well;
//! `tfs_refine::noise_dominated`), or the run from a start one displacement-noise standard
//! deviation away does (its own divergence: a chaotic run parts from itself whatever the
//! input-noise level; `crate::simulate::noise_probe`) on any record — the start model's, or
//! that of a candidate the free run would veto (a model nearer the truth can be the one whose
//! snap-through the noise times; `explain.rs` probes those). Then the candidates are judged by
//! **short-horizon prediction**: held-out data cut into pieces, each simulated from the smoothed
//! measured state at its start (internal states from the record), the squared error summed over
//! the pieces — the model's error over a horizon the input noise cannot take over. The pieces are
//! as long as the start model's own predictions keep their skill (`divergence_horizon`: the
//! lag at which their error reaches the displacement's variance, the record's own measure of how
//! fast nearby motions part), at most two dominant periods. When neither can be simulated the
//! equation error alone decides.
//!
//! A judge vetoes a candidate only when it predicts worse by more than the judge resolves
//! (`predicts_worse`): for the free run, by more than a fresh draw of the input's noise moves
//! the model's score; for the short horizon, when paired tests over the pieces bear it out.
//! Over chaotic divergence the short-horizon error is too coarse to order candidates on its own,
//! so the significant ones are then ordered by their held-out equation error, and the pieces
//! only break that order's ties, by their geometric-mean error (`rank.rs`).
//!
//! A candidate's per-fold model is the model with the candidate's equations refitted on the
//! other folds. For a model fitted with laws tied between its equations (a chain) the refit
//! would untie them, so there the per-fold model keeps the model's own coefficients and takes
//! only what the candidate's fold fit changes against the fold fit without it
//! (`crate::design::anchored`): the model without a candidate is then the model itself.
//!
//! For such an anchored model, a judged prediction that leaves the record's own motion far
//! behind (any state beyond `RANGE_FACTOR` times the record's largest smoothed displacement,
//! velocity or tracked internal state) is stopped there and counts as failed: it has lost the
//! record, and a polynomial model far outside the range it was fitted on is stiff, so finishing
//! the run would cost many small steps to learn only that (`judge_integrator`).

use rayon::prelude::*;
use serde::Serialize;
use tfs_dynamics::{Dopri5, Integrator, SampledInput, SimulateOptions};
use tfs_library::{Factor, Model, Term, evaluate_term};

use crate::design::{FoldEquation, fold_model};
use crate::prepare::{DiagnoseOptions, Layout, RecordStates, variance};
use crate::simulate::BaseRun;
use crate::stats::paired_drop_p_value;

pub use crate::evidence::Judge;

/// The judge of one DOF's held-out predictions in an [`crate::Explanation`], and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JudgeUse {
    /// The DOF.
    pub dof: String,
    /// What ranked the candidates' held-out predictions.
    pub judge: Judge,
    /// Why this judge, in words.
    pub why: String,
    /// True for the plain free run under the measured input, chosen because nothing argued
    /// against it; the verdict names the judge only when this is false.
    pub plain: bool,
}

/// The judge of the held-out predictions chosen for a model on its records.
pub(crate) struct Choice {
    /// The judge.
    pub judge: Judge,
    /// Why it was chosen, in words.
    pub why: String,
    /// The plain free run, chosen because nothing argued against it ([`JudgeUse::plain`]).
    pub plain: bool,
    /// The free-run R-MSE difference the judge cannot resolve: the mean over records of the
    /// squared input-noise spread of the model's free run over the measured displacement's
    /// variance (how far a fresh draw of the input's own noise moves the score; 0 when no
    /// input could be perturbed).
    pub resolution: f64,
    /// Under the free run, the R-MSE no model can go below: the measured displacement's own
    /// noise (its variance over the displacement's, mean over records and DOFs) plus
    /// `resolution` (the input noise's share); 0 under the other judges. Most of a model's
    /// error is read above it ([`predicts_better_by`]).
    pub floor: f64,
    /// Under the free run: simulate each held-out unit over its fitted rows from the measured
    /// state there, not the record from t = 0 (see [`heldout_r_mse`]).
    pub from_fitted_rows: bool,
}

/// The judge for `model` on `states`: short-horizon prediction when on any record the free-run
/// error is dominated by the input's own noise or by the run's own divergence
/// ([`crate::simulate::noise_probe`]), free-run otherwise; with the reason in words and
/// the free run's resolution. One such record is enough: the free-run score is a mean over the
/// held-out units, and a unit the input noise dominates adds noise of its own size to every
/// candidate's mean. `runs` are the model's own simulations of the records
/// ([`crate::simulate::base_runs`]).
pub(crate) fn choose(
    model: &Model,
    states: &[RecordStates],
    opts: &DiagnoseOptions,
    runs: &[BaseRun],
) -> Choice {
    let sim = SimulateOptions::default();
    let probes: Vec<Option<crate::simulate::NoiseProbe>> = states
        .par_iter()
        .zip(runs)
        .map(|(s, run)| {
            let rec = crate::simulate::augment_record(model, &s.record, opts).ok()?;
            let tr = run.as_ref()?.as_ref().ok()?;
            crate::simulate::noise_probe(model, &rec, tr, &sim)
        })
        .collect();
    let measured = measurement_floor(model, states);
    let dominated = probes.iter().flatten().filter(|p| p.dominated).count();
    let diverging = probes.iter().flatten().filter(|p| p.diverges).count();
    let shifts: Vec<f64> = probes.iter().flatten().filter_map(|p| p.shift).collect();
    let resolution = if shifts.is_empty() {
        0.0
    } else {
        let m = shifts.iter().sum::<f64>() / shifts.len() as f64;
        if m.is_finite() { m } else { f64::INFINITY }
    };
    if dominated > 0 {
        let how = match (dominated - diverging, diverging) {
            (_, 0) => "a fresh draw of the measured input's noise moves it",
            (0, _) => {
                "its run from a start one displacement-noise standard deviation away parts from it (its own divergence)"
            }
            _ => {
                "a fresh draw of the measured input's noise, or its own divergence from a start one displacement-noise standard deviation away, moves it"
            }
        };
        Choice {
            judge: Judge::ShortHorizon,
            why: format!(
                "free-run simulation cannot rank models on these records: on {dominated} of {} {how} about as far as the model's error",
                states.len()
            ),
            plain: false,
            resolution,
            floor: 0.0,
            from_fitted_rows: false,
        }
    } else {
        Choice {
            judge: Judge::FreeRun,
            why: "free-run simulation under the measured input".to_string(),
            plain: true,
            resolution,
            floor: if resolution.is_finite() {
                measured + resolution
            } else {
                measured
            },
            from_fitted_rows: false,
        }
    }
}

/// The free-run R-MSE that the measured displacement's own noise leaves to any model, the
/// noise-free truth included: per record and DOF the variance of the displacement's
/// measurement noise (the tool's estimate, [`tfs_refine::displacement_noise_var`]) over the
/// measured displacement's variance, the R-MSE's own normaliser; the mean over the records
/// and DOFs where both can be had (0 when none). A simulation carries no measurement noise, so
/// this much of every model's R-MSE against a measured record is the record's, not the model's.
pub(crate) fn measurement_floor(model: &Model, states: &[RecordStates]) -> f64 {
    let shares: Vec<f64> = states
        .iter()
        .flat_map(|s| {
            let noise = tfs_refine::displacement_noise_var(model, &s.record);
            model
                .dofs
                .iter()
                .zip(noise)
                .filter_map(|(d, nv)| {
                    let v = variance(s.record.column(d)?);
                    (v > 0.0 && nv.is_finite()).then(|| nv / v)
                })
                .collect::<Vec<_>>()
        })
        .collect();
    if shares.is_empty() {
        0.0
    } else {
        shares.iter().sum::<f64>() / shares.len() as f64
    }
}

/// A held-out prediction score: its mean (what is reported) and the parts it is the mean of —
/// per held-out unit for the free run, per piece for the short horizon — for paired tests
/// between two models scored on the same parts.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Heldout {
    /// The R-MSE reported (mean over held-out units).
    pub mean: f64,
    /// Per unit (free run) or per piece (short horizon, each piece's squared error over its
    /// length times its unit's variance).
    pub parts: Vec<f64>,
}

/// The held-out error of the per-fold models whose equations `eqs` replace the model's, under
/// the judge of `choice` (mean over held-out units of the R-MSE; `None` when a simulation fails
/// or the judge is the equation error). `horizon` is the piece length of the short-horizon
/// judge (samples).
pub(crate) fn heldout_error(
    choice: &Choice,
    model: &Model,
    eqs: &[FoldEquation<'_>],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    horizon: usize,
) -> Option<Heldout> {
    match choice.judge {
        Judge::FreeRun => heldout_r_mse(model, eqs, states, layout, opts, choice.from_fitted_rows),
        Judge::ShortHorizon => short_horizon(model, eqs, states, layout, opts, horizon),
        Judge::EquationError => None,
    }
}

/// Held-out free-run R-MSE of the per-fold models (per held-out unit; None on failure). A unit
/// is one record's held-out blocks. By default each unit is simulated from t = 0 of its record
/// (by-record folds: the whole record; time folds: the unit's segment, its initial state
/// fitted there). With `from_fitted_rows`, each unit is simulated as one piece over exactly
/// its rows from the smoothed measured state at the first, internal states from the record's
/// tracks ([`predict_pieces`] with the whole range as its horizon): the rows the equation
/// error was fitted on, without the smoothing margin before them, on which a per-fold model
/// fitted elsewhere can run away. The units are simulated side by side and summed in fold
/// order, so the mean is the same on any number of threads; the first failure stops the units
/// not yet started.
fn heldout_r_mse(
    model: &Model,
    eqs: &[FoldEquation<'_>],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    from_fitted_rows: bool,
) -> Option<Heldout> {
    // Per fold its model; per held-out unit (fold, record, the rows of its held-out blocks).
    let mut models = Vec::with_capacity(layout.folds);
    let mut units = Vec::new();
    for f in 0..layout.folds {
        models.push(fold_model(model, eqs, f)?);
        for r in 0..states.len() {
            if let Some(rows) = heldout_rows(layout, states, f, r) {
                units.push((f, r, rows));
            }
        }
    }
    let scores: Vec<f64> = units
        .par_iter()
        .map(|(f, r, range)| {
            let m = &models[*f];
            if from_fitted_rows {
                let n = range.len();
                return predict_pieces(m, &states[*r], range.clone(), n, opts).map(|p| p.0);
            }
            let s = &states[*r];
            let full = crate::simulate::augment_record(m, &s.record, opts).ok()?;
            let u = if layout.by_record {
                full
            } else {
                full.slice(range.clone()).ok()?
            };
            let sim = SimulateOptions {
                integrator: judge_integrator(m, || RecordScale::of(m, s).map(|sc| sc.peak()))?,
                ..SimulateOptions::default()
            };
            // A fold model is a refit of `model`: its start-state fit begins at `model`'s.
            crate::simulate::r_mse_near(m, &u, &sim, Some(model)).ok()
        })
        .collect::<Option<_>>()?;
    let mut sum = 0.0;
    for s in &scores {
        sum += s;
    }
    (!scores.is_empty()).then(|| Heldout {
        mean: sum / scores.len() as f64,
        parts: scores,
    })
}

/// The rows of record `r` held out in fold `f` (from its first held-out block's first row to its
/// last's end, in the record's own rows, past the smoothing margin); `None` when fold `f` holds
/// none of record `r`.
fn heldout_rows(
    layout: &Layout,
    states: &[RecordStates],
    f: usize,
    r: usize,
) -> Option<std::ops::Range<usize>> {
    let mut blocks = layout
        .blocks
        .iter()
        .filter(|b| b.record == r && b.fold == f);
    let first = blocks.next()?;
    let last = blocks.next_back().unwrap_or(first);
    let margin = states[r].margin;
    Some(margin + first.start..margin + last.start + last.len)
}

/// Short-horizon prediction R-MSE of the per-fold models on their held-out blocks (see the
/// module docs): per held-out unit (a record, or one record's held-out segment), the summed
/// squared error of the pieces over the summed squared deviation of the measured displacement
/// from its mean, averaged over DOFs and units.
fn short_horizon(
    model: &Model,
    eqs: &[FoldEquation<'_>],
    states: &[RecordStates],
    layout: &Layout,
    opts: &DiagnoseOptions,
    horizon: usize,
) -> Option<Heldout> {
    let mut sum = 0.0;
    let mut count = 0usize;
    let mut parts = Vec::new();
    for f in 0..layout.folds {
        let m = fold_model(model, eqs, f)?;
        for (r, s) in states.iter().enumerate() {
            let Some(range) = heldout_rows(layout, states, f, r) else {
                continue;
            };
            let (r, pieces) = predict_pieces(&m, s, range, horizon, opts)?;
            sum += r;
            parts.extend(pieces);
            count += 1;
        }
    }
    (count > 0).then(|| Heldout {
        mean: sum / count as f64,
        parts,
    })
}

/// R-MSE (mean over DOFs) of `model`'s predictions over pieces of `horizon` samples covering
/// `range` of the record behind `s`, each started from the smoothed measured state; and per
/// piece its mean squared error over the range's variance (mean over DOFs).
pub(crate) fn predict_pieces(
    model: &Model,
    s: &RecordStates,
    range: std::ops::Range<usize>,
    horizon: usize,
    opts: &DiagnoseOptions,
) -> Option<(f64, Vec<f64>)> {
    let p = Predictor::new(model, s, opts)?;
    let n = model.dofs.len();
    let den: Vec<f64> = (0..n)
        .map(|i| variance(&p.measured(i)[range.clone()]) * range.len() as f64)
        .collect();
    let mut num = vec![0.0; n];
    let mut parts = Vec::new();
    let len = range.len().max(1) as f64;
    let mut k0 = range.start;
    while k0 + 1 < range.end {
        let k1 = (k0 + horizon).min(range.end);
        let errors = p.errors(k0, k1)?;
        let mut part = 0.0;
        for (i, e) in errors.iter().enumerate() {
            let sum: f64 = e.iter().sum();
            num[i] += sum;
            part += sum / (k1 - k0) as f64 * len / den[i].max(f64::MIN_POSITIVE);
        }
        parts.push(part / n.max(1) as f64);
        k0 = k1;
    }
    let r: f64 = num
        .iter()
        .zip(&den)
        .map(|(a, b)| a / b.max(f64::MIN_POSITIVE))
        .sum::<f64>()
        / n.max(1) as f64;
    (r.is_finite() && parts.iter().all(|p| p.is_finite())).then_some((r, parts))
}

/// Starts per record of `divergence_horizon`'s predictions (evenly spaced).
pub(crate) const HORIZON_STARTS: usize = 16;

/// The piece length (samples) of the short-horizon judge for `model` on `states`: the lag at
/// which its predictions from the smoothed measured state lose their skill — their mean squared
/// error, over [`HORIZON_STARTS`] starts along every record's usable rows, reaches the measured
/// displacement's variance (an R-MSE of 1, the error of predicting the mean position; beyond
/// it chaotic divergence, not the model, sets the error). Searched up to `cap` or half the
/// shortest record's usable rows, whichever is less (that window when the predictions keep
/// their skill over it), and at least `floor` (a shorter piece sees the smoothing's error, not
/// the model's).
pub(crate) fn divergence_horizon(
    model: &Model,
    states: &[RecordStates],
    opts: &DiagnoseOptions,
    cap: usize,
    floor: usize,
) -> usize {
    let window = states
        .iter()
        .map(|s| s.usable() / 2)
        .min()
        .unwrap_or(0)
        .min(cap);
    if window <= floor.max(1) {
        return window.max(1);
    }
    let per_record: Vec<Option<Vec<f64>>> = states
        .par_iter()
        .map(|s| {
            // The model's own predictions, unbounded: where they leave the record's range they
            // lose their skill, which is what this measures.
            let p = Predictor::new(model, s, opts)?.unbounded();
            let (lo, hi) = (s.margin, s.margin + s.usable());
            let n = model.dofs.len().max(1) as f64;
            let vars: Vec<f64> = (0..model.dofs.len())
                .map(|i| variance(&p.measured(i)[lo..hi]).max(f64::MIN_POSITIVE))
                .collect();
            let step = ((hi - lo - window) / (HORIZON_STARTS - 1)).max(1);
            let mut acc = vec![0.0; window];
            for j in 0..HORIZON_STARTS {
                let k0 = lo + j * step;
                for (e, v) in p.errors(k0, k0 + window)?.iter().zip(&vars) {
                    for (a, x) in acc.iter_mut().zip(e) {
                        *a += x / v / n;
                    }
                }
            }
            Some(acc)
        })
        .collect();
    let mut acc = vec![0.0; window];
    let mut count = 0usize;
    for a in per_record.into_iter().flatten() {
        for (t, x) in acc.iter_mut().zip(a) {
            *t += x;
        }
        count += HORIZON_STARTS;
    }
    if count == 0 {
        return window;
    }
    acc.iter()
        .position(|a| a / count as f64 >= 1.0)
        .map_or(window, |k| k.max(floor))
}

/// How far a judged prediction may leave the record's own motion before it counts as failed:
/// this many times the largest magnitude among the record's smoothed displacements, velocities
/// and the model's internal states tracked along it. A polynomial model far outside the range
/// it was fitted on is stiff: its prediction crawls there in ever smaller steps and ends with an
/// error that says only "no skill". The bound is on every state, velocities too, so a brief
/// velocity transient at a noisy run's start can also pass it; it is applied to anchored models
/// only (`judge_integrator`).
pub(crate) const RANGE_FACTOR: f64 = 10.0;

/// The record's own motion as a model's judged predictions see it: per DOF its smoothed
/// displacement and velocity, per internal state its track along the smoothed motion.
struct RecordScale<'a> {
    xs: Vec<&'a [f64]>,
    vs: Vec<&'a [f64]>,
    tracks: Vec<Vec<f64>>,
}

impl<'a> RecordScale<'a> {
    /// `None` when a DOF's smoothed column or an internal state's track cannot be had.
    fn of(model: &Model, s: &'a RecordStates) -> Option<Self> {
        let xs = model
            .dofs
            .iter()
            .map(|d| tfs_data::Columns::column(s, d))
            .collect::<Option<_>>()?;
        let vs = model
            .dofs
            .iter()
            .map(|d| tfs_data::Columns::column(s, &format!("{d}'")))
            .collect::<Option<_>>()?;
        let tracks = model
            .internal_states()
            .into_iter()
            .map(|(v, law)| evaluate_term(&Term::new(vec![Factor::State(v, law)]), s).ok())
            .collect::<Option<_>>()?;
        Some(Self { xs, vs, tracks })
    }

    /// The largest finite magnitude over every column.
    fn peak(&self) -> f64 {
        let tracks = self.tracks.iter().map(Vec::as_slice);
        self.xs
            .iter()
            .chain(&self.vs)
            .copied()
            .chain(tracks)
            .flatten()
            .filter(|z| z.is_finite())
            .fold(0.0_f64, |m, z| m.max(z.abs()))
    }
}

/// The judge's integrator for `model`'s predictions along a record whose peak
/// ([`RecordScale::peak`]) `peak` gives: for a model whose per-fold models are anchored
/// (`crate::design::anchored`, a tied chain) the default Dopri5 stopped as blown up once any
/// state passes `RANGE_FACTOR` times that peak (the default's own limit when the record has no
/// motion to measure by); for any other model the default Dopri5, and `peak` is not asked for.
/// `None` when `peak` has none. The anchored fold models are the ones whose runs wander off the
/// records; an untied model's fold models are refits on the records, and bounding their runs
/// turned brief velocity transients at a noisy run's start into failures (`docs/DECISIONS.md`).
fn judge_integrator(model: &Model, peak: impl FnOnce() -> Option<f64>) -> Option<Dopri5> {
    if !crate::design::anchored(model) {
        return Some(Dopri5::default());
    }
    let peak = peak()?;
    Some(Dopri5 {
        blowup_limit: (peak > 0.0).then_some(RANGE_FACTOR * peak),
        ..Dopri5::default()
    })
}

/// Predictions of a model along one record, each from the smoothed measured state at its start
/// (internal states from the record, run from rest along the smoothed motion).
struct Predictor<'a> {
    compiled: tfs_library::CompiledModel,
    input: SampledInput,
    /// The record with the model's computed input columns.
    rec: tfs_data::Record,
    scale: RecordScale<'a>,
    /// The integrator, bounded by the record's scale for an anchored model (`judge_integrator`).
    integrator: Dopri5,
    dofs: Vec<String>,
}

impl<'a> Predictor<'a> {
    /// `None` when the record's computed columns or internal states cannot be made.
    fn new(model: &Model, s: &'a RecordStates, opts: &DiagnoseOptions) -> Option<Self> {
        let rec = crate::simulate::augment_record(model, &s.record, opts).ok()?;
        let compiled = model.compile().ok()?;
        let channels: Vec<Vec<f64>> = compiled
            .input_names()
            .iter()
            .map(|n| rec.column(n).map(<[f64]>::to_vec))
            .collect::<Option<_>>()?;
        let input = if channels.is_empty() {
            SampledInput::zero(0)
        } else {
            SampledInput::new(rec.t()[0], rec.dt(), channels).ok()?
        };
        let scale = RecordScale::of(model, s)?;
        Some(Self {
            compiled,
            input,
            rec,
            integrator: judge_integrator(model, || Some(scale.peak()))?,
            scale,
            dofs: model.dofs.clone(),
        })
    }

    /// The same predictor with the integrator's default blow-up limit instead of the record's
    /// bound.
    fn unbounded(self) -> Self {
        Self {
            integrator: Dopri5::default(),
            ..self
        }
    }

    /// The measured displacement of DOF `i`.
    fn measured(&self, i: usize) -> &[f64] {
        self.rec.column(&self.dofs[i]).unwrap_or(&[])
    }

    /// Per DOF, the squared error of the prediction over samples `k0..k1` against the measured
    /// displacement; `None` when the integration fails.
    fn errors(&self, k0: usize, k1: usize) -> Option<Vec<Vec<f64>>> {
        let sc = &self.scale;
        let mut x0: Vec<f64> = sc.xs.iter().map(|x| x[k0]).collect();
        let mut v0: Vec<f64> = sc.vs.iter().map(|v| v[k0]).collect();
        x0.resize(self.compiled.system_dofs(), 0.0);
        v0.extend(sc.tracks.iter().map(|z| z[k0]));
        let tr = self
            .integrator
            .integrate(&self.compiled, &self.input, &x0, &v0, &self.rec.t()[k0..k1])
            .ok()?;
        Some(
            (0..self.dofs.len())
                .map(|i| {
                    let m = self.measured(i);
                    (k0..k1)
                        .enumerate()
                        .map(|(j, k)| (tr.x[i][j] - m[k]).powi(2))
                        .collect()
                })
                .collect(),
        )
    }
}

/// True when the model scored `after` predicts the held-out data worse than the one scored
/// `before` by more than `judge` can resolve. Free run: its mean R-MSE is higher by more than
/// `resolution` (what a fresh draw of the input's noise moves it), unless neither shows skill
/// (both R-MSEs at least 1, no better than predicting the mean position: [`skill_key`] scores
/// them the same, and which is higher says where each run lost the motion, not which model is
/// closer). Short horizon: the paired
/// one-sided tests over the pieces — of the difference and of the log-ratio, Bonferroni over the
/// two — put the worsening below `alpha`. The equation error judges nothing here (false).
pub(crate) fn predicts_worse(
    judge: Judge,
    before: &Heldout,
    after: &Heldout,
    resolution: f64,
    alpha: f64,
) -> bool {
    match judge {
        Judge::FreeRun => {
            let no_skill =
                skill_key(Some(before.mean)) == 1.0 && skill_key(Some(after.mean)) == 1.0;
            after.mean > before.mean + resolution && !no_skill
        }
        Judge::ShortHorizon => {
            if before.parts.len() != after.parts.len() {
                return after.mean > before.mean;
            }
            paired_drop_p_value(&after.parts, &before.parts) < alpha
        }
        Judge::EquationError => false,
    }
}

/// The share of the model's RMS prediction error a candidate must take away to count as most of
/// what the model misses ([`predicts_better_by`]): its refitted model's error at most half the
/// model's own.
pub(crate) const MOST_OF_THE_ERROR: f64 = 0.5;

/// How much better the model scored `after` predicts the held-out data than the one scored
/// `before`, as a share of the motion's RMS (the drop of the models' own RMS prediction error
/// over the displacement's standard deviation), when the drop is more than `judge` can resolve
/// and either at least `min_share` — an effect's size on the motion, as `min_share` is its size
/// on the force — or at least [`MOST_OF_THE_ERROR`] of `before`'s own RMS prediction error: most
/// of what a model already within `min_share` of the motion misses (`None` otherwise). A stiff
/// stop touched for a few samples, or a term the start library nearly holds, moves the fitted
/// force little and the motion much. A model's own error is its R-MSE above `floor`, the share
/// no model removes (the noise of the measured record and of its input, [`Choice::floor`]; 0 to
/// read the whole R-MSE as the model's): at 40 dB that share is about 1e-4, the whole error of a
/// model within 1–2 % of the motion, and read as the model's it hides an effect that removes
/// most of what the model itself misses. Free run: `after` shows skill and its mean R-MSE is
/// lower by more than `resolution`. Short horizon: the paired one-sided tests over the pieces
/// put the drop below `alpha`. The equation error judges nothing here (`None`).
pub(crate) fn predicts_better_by(
    judge: Judge,
    (before, after): (&Heldout, &Heldout),
    (resolution, floor): (f64, f64),
    alpha: f64,
    min_share: f64,
) -> Option<f64> {
    let own = |r: f64| (r - floor).max(0.0).sqrt();
    let drop = own(before.mean) - own(after.mean);
    let resolved = match judge {
        Judge::FreeRun => after.mean < 1.0 && after.mean < before.mean - resolution,
        Judge::ShortHorizon => {
            before.parts.len() == after.parts.len()
                && paired_drop_p_value(&before.parts, &after.parts) < alpha
        }
        Judge::EquationError => false,
    };
    let most = drop >= MOST_OF_THE_ERROR * own(before.mean);
    (resolved && drop.is_finite() && drop > 0.0 && (drop >= min_share || most)).then_some(drop)
}

/// Which of `scores` (per-piece errors of models scored on the same pieces) has the lowest
/// geometric mean over the pieces (each piece's error at least the smallest positive number);
/// the first of equals, `None` when there are none.
pub(crate) fn lowest_geometric_mean(scores: &[&[f64]]) -> Option<usize> {
    let log_mean = |parts: &[f64]| {
        parts
            .iter()
            .map(|p| p.max(f64::MIN_POSITIVE).ln())
            .sum::<f64>()
            / parts.len().max(1) as f64
    };
    scores
        .iter()
        .map(|p| log_mean(p))
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// A free-run R-MSE as an ordering key: the R-MSE while it shows skill (below 1), 1 for every
/// score that does not (an R-MSE of 1 is the error of predicting the mean position), infinite
/// for a failed simulation.
pub(crate) fn skill_key(r_mse: Option<f64>) -> f64 {
    r_mse.map_or(f64::INFINITY, |r| r.min(1.0))
}

#[cfg(test)]
mod tests;
