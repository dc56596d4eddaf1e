//! A calibrated null for the equation-error test: what the same scan finds on records that the
//! start model itself made.
//!
//! The equation error is biased wherever the smoothed states differ systematically from the
//! truth: noisy displacements low-passed, differentiated twice and put through a nonlinear
//! library leave residuals that depend on the state (largest where the restoring force is
//! steepest), and an effect local in the state — a stop near the largest displacement — fits
//! them. The block tests treat that bias as signal. So every candidate that passes them is
//! scanned again on synthetic records made without any missing effect: the start model's own
//! simulation of each record under its measured inputs, plus fresh Gaussian noise with each
//! channel's spectrum as the tool's noise estimate gives it (the floor
//! `tfs_signal::band` fits to the upper half of the channel's spectrum; where that half is the
//! signal's own tail and shows no floor, white noise at the largest level the spectrum allows),
//! smoothed as the measured records are. The candidate's held-out drop over the draws is its null distribution,
//! selection of the best variant included; the candidate stays significant only when its drop
//! on the measured records lies beyond that distribution (a one-sided prediction t test over the
//! draws, corrected like the block tests). A draw whose motion does not span the records' range
//! is no null of them and is dropped; where the start model cannot be simulated on every record, or
//! fewer than two draws remain, the null cannot be made and the block tests decide alone.
//!
//! The re-scan is skipped where it cannot matter. A candidate fitting nothing but the equation
//! error's bias and the noise can at most remove the whole held-out residual the start model
//! leaves on its own synthetic records; when the candidate's measured drop (in the residual's
//! units, not as a fraction) is larger than that residual on every draw, what it removes is more
//! than the null holds, and it stays significant without the re-scan. A strong missing effect
//! (hysteresis hidden behind a linear model: the residual of the synthetic draws is a few per
//! cent of the measured one) passes this way; a bias-sized candidate on a model that already
//! holds the truth (its synthetic residual is about the measured one) is re-scanned as before.
//!
//! Nor is a candidate re-judged whose refitted model, by the judge of held-out predictions,
//! removes most of the start model's own held-out prediction error (its RMS error at most half
//! the start model's: `judge::predicts_better_by`). The null asks whether an equation-error drop
//! could be the equation error's bias; that bias lives in the smoothed states of the equation,
//! not in the simulated motion, and on the start model's own synthetic records — where it is all
//! there is — the start model already predicts the motion up to the noise, so all a candidate
//! can take away there is the noise's share. On noise-free records the null can read a large
//! drop as bias (a Bouc–Wen element on a rig: 94 % measured against 89 ± 3 % on the draws)
//! while the refit with the effect predicts held-out motion 23 times better (free-run R-MSE).

use rayon::prelude::*;
use statrs::distribution::{ContinuousCDF, StudentsT};
use tfs_data::Record;
use tfs_library::Model;
use tfs_signal::band::{Band, noise_spectrum, reconstruct};

use crate::effects::Catalogue;
use crate::evidence::NullEvidence;
use crate::polish::best_variant;
use crate::prepare::{DiagnoseOptions, Layout, RecordStates};
use crate::scan::{DofSetup, context, setup_dof};
use crate::simulate::BaseRun;

/// One record's material for synthetic draws: the noise band of every channel the draws
/// perturb.
struct Source<'a> {
    record: &'a Record,
    /// The start model's own run of the record (from its fitted start state).
    run: &'a tfs_dynamics::Trajectory,
    /// Per column of the record (in its order): the band of its noise, spanning every bin
    /// (`None` for a column no draw perturbs).
    bands: Vec<Option<Band>>,
}

/// The null test of one candidate: how many draws it rests on, and its one-sided p value.
#[derive(Debug, Clone, Copy)]
struct NullTest {
    draws: usize,
    p: f64,
}

/// A candidate the null re-judges: the equation it extends, its effect, and its held-out drop
/// on the measured records.
pub(crate) struct NullJob {
    /// The DOF whose equation it extends.
    pub dof_idx: usize,
    /// The catalogue effect.
    pub effect: String,
    /// Relative drop of the held-out equation error on the measured records.
    pub delta: f64,
    /// Held-out residual sum of squares with the effect on the measured records.
    pub after: f64,
}

/// The null's part of the evidence of every candidate in `jobs` (see the module docs), in their
/// order: `None` where the null cannot be made or tested. `runs` are the start model's
/// simulations of `records`; `tests` is the Bonferroni factor of the block tests.
pub(crate) fn calibrate(
    model: &Model,
    records: &[Record],
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    jobs: &[NullJob],
    runs: &[BaseRun],
    tests: usize,
) -> Vec<Option<NullEvidence>> {
    let none = || vec![None; jobs.len()];
    if jobs.is_empty() || opts.null_draws < 2 {
        return none();
    }
    let Some(sources) = sources(model, records, runs) else {
        return none();
    };
    let mut dofs: Vec<usize> = jobs.iter().map(|j| j.dof_idx).collect();
    dofs.sort_unstable();
    dofs.dedup();
    // Each draw is made, read and dropped in its own task, so only the draws being worked on
    // hold records (a draw is a set of synthetic records with their smoothed states: the null
    // of a 640k-sample record kept eight at once held about 500 MB). A draw keeps the start
    // model's held-out residual per DOF (the ceiling's) and the drops of the candidates it
    // already settles as re-scanned ([`Pending`]); the others' are made on a second visit.
    let pending: Vec<Pending> = jobs.iter().map(Pending::of).collect();
    let first: Vec<Option<Visit>> = (0..opts.null_draws)
        .into_par_iter()
        .map(|i| {
            let syn = synthesize(model, &sources, opts, &dofs, i)?;
            let residuals = syn.residuals();
            let drops = jobs
                .iter()
                .zip(&pending)
                .map(|(job, p)| {
                    p.rescanned_on(residuals[job.dof_idx])
                        .then(|| rescan_job(model, &syn, catalogue, opts, job.dof_idx, &job.effect))
                        .flatten()
                })
                .collect();
            Some(Visit { residuals, drops })
        })
        .collect();
    // The ceiling: a candidate whose measured absolute drop is larger than the whole held-out
    // residual the start model leaves on every synthetic draw of its equation fits something
    // the equation error's bias and the noise cannot hold, so re-scanning it is not needed.
    let ceilings: Vec<Option<Ceiling>> = jobs.iter().map(|j| ceiling(&first, j)).collect();
    let rescan: Vec<bool> = ceilings
        .iter()
        .map(|c| !c.as_ref().is_some_and(Ceiling::clears))
        .collect();
    // The second visit: the draws where a candidate that is re-scanned after all was left
    // undecided, made again (the same seeds, so the same records) and scanned for those.
    let again = |v: &Visit| -> Vec<usize> {
        (0..jobs.len())
            .filter(|&j| {
                let r = v.residuals[jobs[j].dof_idx];
                rescan[j] && r.is_some() && !pending[j].rescanned_on(r)
            })
            .collect()
    };
    let second: Vec<Vec<(usize, Option<f64>)>> = first
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            let Some(v) = v else { return Vec::new() };
            let todo = again(v);
            if todo.is_empty() {
                return Vec::new();
            }
            let Some(syn) = synthesize(model, &sources, opts, &dofs, i) else {
                return Vec::new();
            };
            todo.into_iter()
                .map(|j| {
                    let job = &jobs[j];
                    (
                        j,
                        rescan_job(model, &syn, catalogue, opts, job.dof_idx, &job.effect),
                    )
                })
                .collect()
        })
        .collect();
    let draws: Vec<Vec<Option<f64>>> = if rescan.iter().any(|&r| r) {
        first
            .into_iter()
            .zip(second)
            .map(|(v, later)| match v {
                Some(v) => {
                    let mut row: Vec<Option<f64>> = v
                        .drops
                        .into_iter()
                        .zip(&rescan)
                        .map(|(d, &r)| d.filter(|_| r))
                        .collect();
                    for (j, d) in later {
                        row[j] = d;
                    }
                    row
                }
                None => Vec::new(),
            })
            .collect()
    } else {
        Vec::new()
    };
    jobs.iter()
        .enumerate()
        .map(|(j, job)| {
            if let Some(c) = ceilings[j].as_ref().filter(|c| c.clears()) {
                return Some(NullEvidence::Clears {
                    draws: c.draws,
                    largest: c.largest,
                    measured: c.measured,
                });
            }
            let d: Vec<f64> = draws
                .iter()
                .filter_map(|row| row.get(j).copied().flatten())
                .filter(|v| v.is_finite())
                .collect();
            let g: Vec<f64> = d.iter().map(|&v| log_gain(v)).collect();
            let t = null_test(&g, log_gain(job.delta))?;
            let (mean, sd) = mean_sd(&d);
            Some(NullEvidence::Tested {
                draws: t.draws,
                mean,
                sd,
                p: (t.p * tests as f64).min(1.0),
            })
        })
        .collect()
}

/// The scale the null test works on: a held-out drop `d` is one minus a ratio of error sums of
/// squares, and the test compares `−ln(1 − d)`, the log of that ratio (turned so that a gain is
/// positive). On it a ratio's spread is roughly symmetric and unbounded both ways, as the t test
/// assumes; the drop itself is bounded above by 1 and unbounded below, so a null whose draws
/// scatter far into negative drops (a candidate that overfits records with nothing missing)
/// would swamp a measured drop near 100 %, which no draw comes near. For small drops the two
/// scales agree (`−ln(1 − d) ≈ d`). A ratio of 0 (an exact fit) is taken at the smallest
/// positive number.
fn log_gain(d: f64) -> f64 {
    -(1.0 - d).max(f64::MIN_POSITIVE).ln()
}

/// The mean and sample standard deviation of `d` (at least two values; 0 spread otherwise).
fn mean_sd(d: &[f64]) -> (f64, f64) {
    let n = d.len();
    let mean = d.iter().sum::<f64>() / n.max(1) as f64;
    let sd = if n > 1 {
        (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    (mean, sd)
}

/// The one-sided prediction test of a new value `observed` against the draws `d`: its excess
/// over their mean in units of their spread, `sd·√(1 + 1/n)`, referred to a t distribution
/// with `n − 1` degrees of freedom (its exact tail: the draws are few, and a strong effect lies
/// many spreads beyond them). `None` with fewer than two draws.
fn null_test(d: &[f64], observed: f64) -> Option<NullTest> {
    let n = d.len();
    if n < 2 {
        return None;
    }
    let (mean, sd) = mean_sd(d);
    let scale = sd * (1.0 + 1.0 / n as f64).sqrt();
    let p = if scale > 0.0 {
        StudentsT::new(0.0, 1.0, (n - 1) as f64)
            .ok()?
            .sf((observed - mean) / scale)
    } else if observed > mean {
        0.0
    } else {
        1.0
    };
    Some(NullTest { draws: n, p })
}

/// The synthetic material of every record; `None` when the start model's simulation of some
/// record is missing, failed or left the finite numbers (its perturbed simulations would too).
fn sources<'a>(
    model: &Model,
    records: &'a [Record],
    runs: &'a [BaseRun],
) -> Option<Vec<Source<'a>>> {
    records
        .iter()
        .zip(runs)
        .map(|(r, run)| {
            let tr = run.as_ref()?.as_ref().ok()?;
            let ok = tr.x.len() == model.dofs.len()
                && tr
                    .x
                    .iter()
                    .all(|x| x.len() == r.len() && x.iter().all(|v| v.is_finite()))
                && tr.v.len() == tr.x.len()
                && tr.v.iter().all(|v| v.len() == r.len());
            if !ok {
                return None;
            }
            let dt = r.dt();
            // Only the channels a draw perturbs (the model's inputs and DOFs): a record's other
            // columns (a simulator's clean channels) are carried along as they are.
            let drawn = |c: &String| model.inputs.contains(c) || model.dofs.contains(c);
            let bands = r
                .names()
                .iter()
                .map(|c| {
                    let b = reconstruct(r.column(c).filter(|_| drawn(c))?, dt, None).band;
                    Some(raw_noise_band(&b))
                })
                .collect();
            Some(Source {
                record: r,
                run: tr,
                bands,
            })
        })
        .collect()
}

/// The band of a channel's raw measurement noise, as the tool's noise estimate gives it: every
/// bin, not only the reconstruction's band. Where the channel's spectrum shows a noise floor,
/// the fitted floor; where its upper half is the signal's own tail
/// ([`Band::floor_is_signal_tail`]: no floor is visible), the extrapolated floor (its slope
/// clamped to −2) would put noise of a signal's size at low frequencies, and the noise is only
/// bounded: white noise at the lowest level the spectrum reaches, the largest the spectrum
/// allows (white noise above it would show as a flat floor there, [`Band::white_noise_var_bound`]).
fn raw_noise_band(b: &Band) -> Band {
    let top_bin = b.mirror_len / 2;
    let mut raw = Band {
        cutoff_hz: top_bin as f64 * b.bin_hz,
        ..*b
    };
    if b.floor_is_signal_tail && top_bin > 0 {
        raw.floor_log_a = b.floor_log_a + b.floor_beta * (top_bin as f64).ln();
        raw.floor_beta = 0.0;
    }
    raw
}

/// A seed for draw `i`, record `r`, column `c`, distinct for every triple.
fn seed(base: u64, i: usize, r: usize, c: usize) -> u64 {
    let mix = |h: u64, v: u64| (h ^ v).wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(29);
    mix(mix(mix(base, i as u64 + 1), r as u64 + 1), c as u64 + 1)
}

/// Draw `i`: synthetic records, their smoothed states, the fold layout and the start model's
/// equation of every DOF in `dofs` on them (`None` where the draw is no null of the records).
fn synthesize(
    model: &Model,
    sources: &[Source<'_>],
    opts: &DiagnoseOptions,
    dofs: &[usize],
    i: usize,
) -> Option<Synthetic> {
    // The start model is known only where the records went, and it is a null of these records
    // only if it goes there too: a draw whose displacements do not span the records' range
    // (each end within a tenth of the range: not leaving it for a well or a stretch the records
    // never visited, not settling where they kept moving) is dropped. A synthetic record that
    // already reaches beyond an end by more than that settles it, so the draw stops there,
    // before simulating the other records or smoothing any.
    let measured: Vec<(f64, f64)> = model
        .dofs
        .iter()
        .map(|d| extent(sources.iter().filter_map(|s| s.record.column(d))))
        .collect();
    let width = |m: (f64, f64)| 0.1 * (m.1 - m.0);
    let within = |v: f64, end: f64, w: f64| (v - end).abs() <= w;
    let mut recs = Vec::with_capacity(sources.len());
    for (r, s) in sources.iter().enumerate() {
        let rec = synthetic(model, s, opts, i, r)?;
        for (d, &m) in model.dofs.iter().zip(&measured) {
            let Some(x) = rec.column(d) else { continue };
            let (lo, hi) = extent(std::iter::once(x));
            let w = width(m);
            // The union's ends lie at or beyond this record's, so an end already too far out
            // stays too far out (the same test as on the union below).
            if (lo < m.0 && !within(lo, m.0, w)) || (hi > m.1 && !within(hi, m.1, w)) {
                return None;
            }
        }
        recs.push(rec);
    }
    for (d, &m) in model.dofs.iter().zip(&measured) {
        let drawn = extent(recs.iter().filter_map(|r| r.column(d)));
        let w = width(m);
        if !(within(drawn.0, m.0, w) && within(drawn.1, m.1, w)) {
            return None;
        }
    }
    let states: Vec<RecordStates> = recs
        .iter()
        .map(|rec| RecordStates::new(model, rec, opts).ok())
        .collect::<Option<_>>()?;
    let layout = Layout::new(&states, opts).ok()?;
    let dt = sources.first()?.record.dt();
    let mut setups: Vec<Option<DofSetup>> = (0..model.dofs.len()).map(|_| None).collect();
    for &idx in dofs {
        setups[idx] = setup_dof(model, idx, &states, &layout)
            .ok()
            .map(DofSetup::lean);
    }
    Some(Synthetic {
        states,
        layout,
        setups,
        dt,
    })
}

/// One synthetic draw, ready to be scanned.
struct Synthetic {
    states: Vec<RecordStates>,
    layout: Layout,
    /// Per DOF of the model: the start model's equation on the draw, where asked for.
    setups: Vec<Option<DofSetup>>,
    dt: f64,
}

/// The held-out drop of effect `name`'s best variant on the equation of DOF `idx` in the
/// synthetic draw `syn` (`None` where it cannot be scored).
fn rescan_job(
    model: &Model,
    syn: &Synthetic,
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    idx: usize,
    name: &str,
) -> Option<f64> {
    let d = syn.setups.get(idx)?.as_ref()?;
    job_delta(
        model,
        d,
        &syn.states,
        &syn.layout,
        catalogue,
        opts,
        name,
        syn.dt,
    )
}

/// A candidate's measured absolute drop against the start model's whole held-out residual on
/// the synthetic draws.
struct Ceiling {
    /// The candidate's held-out drop on the measured records (residual sum of squares).
    drop: f64,
    /// The start model's held-out residual on the measured records.
    measured: f64,
    /// The largest held-out residual of the start model over the draws.
    largest: f64,
    /// Draws that could be scored.
    draws: usize,
}

impl Ceiling {
    /// Whether the measured drop exceeds the start model's whole residual on every draw (at
    /// least two draws): a candidate fitting only the bias and the noise of the equation error
    /// could at most remove all of it.
    fn clears(&self) -> bool {
        self.draws >= 2 && self.drop > self.largest
    }
}

/// The ceiling of candidate `job` over the draws `visits`; `None` when its measured drop is not
/// a finite fraction in (0, 1) or a draw's residual is not finite.
fn ceiling(visits: &[Option<Visit>], job: &NullJob) -> Option<Ceiling> {
    let (delta, after, idx) = (job.delta, job.after, job.dof_idx);
    if !(delta.is_finite() && delta > 0.0 && delta < 1.0 && after.is_finite()) {
        return None;
    }
    let measured = after / (1.0 - delta);
    let residuals: Vec<f64> = visits
        .iter()
        .flatten()
        .filter_map(|v| v.residuals.get(idx).copied().flatten())
        .collect();
    if residuals.iter().any(|r| !r.is_finite()) {
        return None;
    }
    Some(Ceiling {
        drop: measured - after,
        measured,
        largest: residuals.iter().copied().fold(0.0, f64::max),
        draws: residuals.len(),
    })
}

/// What one draw leaves once it is dropped: the start model's held-out residual per DOF of the
/// model (`None` where its equation was not set up on the draw) and, per candidate, its drop
/// where the draw already settled that it is re-scanned.
struct Visit {
    residuals: Vec<Option<f64>>,
    drops: Vec<Option<f64>>,
}

impl Synthetic {
    /// The start model's held-out residual (sum over blocks) per DOF of the model.
    fn residuals(&self) -> Vec<Option<f64>> {
        self.setups
            .iter()
            .map(|d| d.as_ref().map(|d| d.base_cv.heldout.iter().sum::<f64>()))
            .collect()
    }
}

/// A candidate before the draws are seen: whether the ceiling could clear it at all, and the
/// measured drop a draw's residual must stay below for it to.
struct Pending {
    /// `None` when the ceiling cannot clear the candidate (its measured drop is not a finite
    /// fraction in (0, 1)), else its absolute drop ([`Ceiling::drop`]).
    drop: Option<f64>,
}

impl Pending {
    fn of(job: &NullJob) -> Self {
        let (delta, after) = (job.delta, job.after);
        let drop = (delta.is_finite() && delta > 0.0 && delta < 1.0 && after.is_finite())
            .then(|| after / (1.0 - delta) - after);
        Self { drop }
    }

    /// Whether a draw on which the start model's residual of the candidate's equation is
    /// `residual` settles that the candidate is re-scanned (so it is scanned on the draw at
    /// once): the ceiling cannot clear it, or the residual is not finite or not below its drop
    /// (the largest residual over the draws is then not either). A draw without the equation
    /// (`None`) scores nothing.
    fn rescanned_on(&self, residual: Option<f64>) -> bool {
        match (self.drop, residual) {
            (_, None) => false,
            (None, Some(_)) => true,
            (Some(drop), Some(r)) => !r.is_finite() || drop <= r,
        }
    }
}

/// Draw `i`'s synthetic record `r`: the start model's simulation of source `s` under its
/// measured inputs plus a fresh draw of their noise, with a draw of the displacements' noise
/// added (`None` where it cannot be made or left the finite numbers).
fn synthetic(
    model: &Model,
    s: &Source<'_>,
    opts: &DiagnoseOptions,
    i: usize,
    r: usize,
) -> Option<Record> {
    let first = tfs_dynamics::SimulateOptions {
        initial_state: tfs_dynamics::InitialState::FirstSamples,
        ..Default::default()
    };
    let noise = |c: usize, n: usize, salt: usize| -> Option<Vec<f64>> {
        let b = s.bands[c].as_ref()?;
        Some(
            noise_spectrum(b, seed(opts.seed, i, r, 2 * c + salt))?
                .series(n, 1, false)?
                .x,
        )
    };
    let add = |v: &[f64], c: usize, salt: usize| -> Vec<f64> {
        match noise(c, v.len(), salt) {
            Some(n) => v.iter().zip(&n).map(|(a, b)| a + b).collect(),
            None => v.to_vec(),
        }
    };
    // The drive: the measured inputs plus a fresh draw of their noise, so that each draw
    // follows its own trajectory where the motion is sensitive to the input. It starts where
    // the model's own run of the record started (its fitted state: the first sample of each
    // displacement set to it, the velocity given as a column), not from the record's first
    // samples, whose velocity carries the displacement noise times `1/dt`: on a record whose
    // motion is not far above its noise that velocity throws a model over its barrier, every
    // draw fails, and there is no null. Fitting the start again for each draw would cost more
    // than the rest of the simulation, and any plausible start serves a synthetic record.
    let mut drive = s.record.clone();
    for (c, name) in s.record.names().iter().enumerate() {
        if model.inputs.contains(name) {
            drive
                .set_column(name.clone(), add(s.record.column(name)?, c, 0))
                .ok()?;
        }
    }
    for (j, d) in model.dofs.iter().enumerate() {
        let (x0, v) = (s.run.x.get(j)?.first()?, s.run.v.get(j)?);
        let mut x = drive.column(d)?.to_vec();
        x[0] = *x0;
        drive.set_column(d.clone(), x).ok()?;
        drive.set_column(format!("{d}'"), v.clone()).ok()?;
    }
    let drive = crate::simulate::augment_record(model, &drive, opts).ok()?;
    let tr = tfs_dynamics::simulate_model_on_record(model, &drive, &first).ok()?;
    // The record: the simulated displacements plus a draw of their noise, the inputs as
    // measured.
    let mut rec = s.record.clone();
    for (c, name) in s.record.names().iter().enumerate() {
        if let Some(j) = model.dofs.iter().position(|d| d == name) {
            let x = tr.x.get(j).filter(|x| x.len() == rec.len())?;
            if !x.iter().all(|v| v.is_finite()) {
                return None;
            }
            rec.set_column(name.clone(), add(x, c, 1)).ok()?;
        }
    }
    Some(rec)
}

/// The smallest and largest value over `columns`.
fn extent<'a>(columns: impl Iterator<Item = &'a [f64]>) -> (f64, f64) {
    columns
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        })
}

/// The held-out drop of effect `name`'s best variant on the equation of `d`.
#[allow(clippy::too_many_arguments)]
fn job_delta(
    model: &Model,
    d: &DofSetup,
    states: &[RecordStates],
    layout: &Layout,
    catalogue: &Catalogue,
    opts: &DiagnoseOptions,
    name: &str,
    dt: f64,
) -> Option<f64> {
    let e = catalogue.effects().iter().find(|e| e.name() == name)?;
    let vars = e.variants(&context(model, d, dt, opts));
    let s = best_variant(states, layout, d.idx, &d.base_terms, &vars).ok()??;
    let base: f64 = d.base_cv.heldout.iter().sum();
    (base > 0.0).then(|| (base - s.cv_rss) / base)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A draw settles a candidate as re-scanned only when the ceiling over all draws cannot
    /// clear it, whatever the other draws hold: checked against `ceiling` on every pairing of
    /// candidates (clearable, too small, not a fraction) and residuals (below and above the
    /// drop, not finite, no equation).
    #[test]
    fn a_draw_settles_a_rescan_only_where_the_ceiling_cannot_clear() {
        let job = |delta: f64, after: f64| NullJob {
            dof_idx: 0,
            effect: "e".into(),
            delta,
            after,
        };
        // Measured residual 1.0, after 0.2: drop 0.8.
        let jobs = [
            job(0.8, 0.2),
            job(1.5, 0.2),
            job(0.5, f64::NAN),
            job(0.1, 0.9),
        ];
        let residuals = [
            Some(0.1),
            Some(0.5),
            Some(0.9),
            Some(2.0),
            Some(f64::INFINITY),
            None,
        ];
        let visit = |r: Option<f64>| {
            Some(Visit {
                residuals: vec![r],
                drops: vec![None],
            })
        };
        for j in &jobs {
            let p = Pending::of(j);
            for &r in &residuals {
                if !p.rescanned_on(r) {
                    continue;
                }
                // Whatever the other draws are, the ceiling does not clear the candidate.
                for &other in &residuals {
                    let visits = [visit(r), visit(other), visit(Some(0.0))];
                    let c = ceiling(&visits, j);
                    assert!(!c.is_some_and(|c| c.clears()), "{r:?} {other:?}");
                }
            }
        }
        // And a draw below the drop leaves a clearable candidate open.
        assert!(!Pending::of(&jobs[0]).rescanned_on(Some(0.5)));
        assert!(Pending::of(&jobs[0]).rescanned_on(Some(0.9)));
        assert!(Pending::of(&jobs[1]).rescanned_on(Some(0.1)));
        assert!(!Pending::of(&jobs[0]).rescanned_on(None));
    }

    #[test]
    fn the_prediction_test_separates_a_gain_from_the_null_spread() {
        let d = [0.020, 0.025, 0.018, 0.030, 0.022, 0.027, 0.021, 0.024];
        // Inside the spread: no evidence.
        assert!(null_test(&d, 0.026).unwrap().p > 0.2);
        // Far beyond it: strong evidence.
        assert!(null_test(&d, 0.2).unwrap().p < 1e-5);
        assert!(null_test(&d[..1], 0.2).is_none());
    }

    #[test]
    fn a_near_exact_fit_stands_out_of_a_null_that_scatters_into_negative_drops() {
        // Draws where the candidate overfits records with nothing missing: held-out error
        // 100-160 times the start model's. A measured drop of 99.97 % (error ratio 3e-4).
        let d = [
            -130.0, -100.0, -160.0, -125.0, -140.0, -110.0, -150.0, -120.0,
        ];
        let observed = 0.9997;
        let g: Vec<f64> = d.iter().map(|&v| log_gain(v)).collect();
        assert!(null_test(&g, log_gain(observed)).unwrap().p < 1e-9);
        // On the drop's own scale the negative tail's spread hides it.
        assert!(null_test(&d, observed).unwrap().p > 1e-4);
        // A small drop inside a null of small positive drops stays inside it on either scale.
        let small = [0.048, 0.049, 0.038, 0.049, 0.045, 0.041, 0.052, 0.044];
        let gs: Vec<f64> = small.iter().map(|&v| log_gain(v)).collect();
        assert!(null_test(&gs, log_gain(0.031)).unwrap().p > 0.5);
        assert!((log_gain(0.01) - 0.01).abs() < 1e-4);
        assert!(log_gain(1.0).is_finite());
    }

    #[test]
    fn a_channel_without_a_noise_floor_draws_white_noise_at_its_bound() {
        let b = Band {
            cutoff_hz: 5.0,
            mse_cutoff_hz: 5.0,
            noise_floor: 1.0,
            in_band_noise_share: 0.0,
            noise_var: 0.0,
            floor_log_a: 20.0,
            floor_beta: -2.0,
            bin_hz: 0.01,
            mirror_len: 20_000,
            floor_is_signal_tail: true,
        };
        let raw = raw_noise_band(&b);
        assert_eq!(raw.cutoff_hz, 100.0);
        assert_eq!(raw.floor_beta, 0.0);
        // Flat at the extrapolated floor's lowest level: its variance is the white bound, far
        // below the extrapolated floor's (which puts its power at low frequencies).
        let bound = b.white_noise_var_bound();
        assert!((raw.total_noise_var() / bound - 1.0).abs() < 1e-9);
        assert!(b.total_noise_var() > 1e3 * bound);
        // A visible floor is drawn as fitted, over every bin.
        let seen = raw_noise_band(&Band {
            floor_is_signal_tail: false,
            ..b
        });
        assert_eq!((seen.floor_log_a, seen.floor_beta), (20.0, -2.0));
        assert_eq!(seen.cutoff_hz, 100.0);
    }

    #[test]
    fn the_ceiling_needs_two_draws_and_a_drop_beyond_every_residual() {
        let c = |drop: f64, largest: f64, draws: usize| Ceiling {
            drop,
            measured: 1.0,
            largest,
            draws,
        };
        assert!(c(0.5, 0.1, 8).clears());
        assert!(!c(0.05, 0.1, 8).clears());
        assert!(!c(0.5, 0.1, 1).clears());
    }

    /// Noise bands are made for the channels a draw perturbs (the model's DOFs and inputs)
    /// and for no other column of the record (a simulator's clean channels).
    #[test]
    fn sources_band_only_the_drawn_channels() {
        let dofs = ["x"];
        let t: Vec<f64> = (0..2000).map(|k| k as f64 * 0.01).collect();
        let wave = |f: f64| -> Vec<f64> { t.iter().map(|&t| (f * t).sin()).collect() };
        let rec = Record::new(
            "r",
            t.clone(),
            vec![
                ("x".to_string(), wave(1.1)),
                ("x_clean".to_string(), wave(1.1)),
                ("xb_acc".to_string(), wave(0.7)),
            ],
        )
        .unwrap();
        let eq = tfs_library::Equation {
            dof: "x".into(),
            terms: [("x", -1.0), ("xb_acc", 1.0)]
                .iter()
                .map(|(n, c)| {
                    tfs_library::ModelTerm::new(tfs_library::Term::parse(n, &dofs).unwrap(), *c)
                })
                .collect(),
        };
        let model = Model::new(vec!["x".into()], vec![eq], "test").unwrap();
        let mut run = tfs_dynamics::Trajectory::with_capacity(1, t.len());
        for (k, &tk) in t.iter().enumerate() {
            run.push(tk, &[rec.column("x").unwrap()[k]], &[0.0]);
        }
        let records = [rec];
        let runs = vec![Some(Ok(run))];
        let s = sources(&model, &records, &runs).unwrap();
        let banded: Vec<bool> = s[0].bands.iter().map(Option::is_some).collect();
        assert_eq!(records[0].names(), ["x", "x_clean", "xb_acc"]);
        assert_eq!(banded, [true, false, true]);
    }

    /// A synthetic draw starts where the start model's own run of the record starts (its
    /// fitted state), not at the record's first samples: on a noisy record of a double well
    /// `x'' = x − x³ − 0.2x' + u`, moving in its right well, the first samples' velocity is
    /// past the barrier's escape speed, a run from there leaves the well, and every draw was
    /// dropped (no null). Each draw must now stay in the record's well.
    #[test]
    fn draws_start_from_the_model_s_own_run_not_the_noisy_first_samples() {
        let dofs = ["x"];
        let eq = tfs_library::Equation {
            dof: "x".into(),
            terms: [("x", 1.0), ("x^3", -1.0), ("x'", -0.2), ("u", 1.0)]
                .iter()
                .map(|(n, c)| {
                    tfs_library::ModelTerm::new(tfs_library::Term::parse(n, &dofs).unwrap(), *c)
                })
                .collect(),
        };
        let model = Model::new(vec!["x".into()], vec![eq], "test").unwrap();
        let dt = 0.01;
        let t: Vec<f64> = (0..3000).map(|k| k as f64 * dt).collect();
        let u: Vec<f64> = t.iter().map(|&t| 0.1 * (0.9 * t).sin()).collect();
        let drive = Record::new(
            "r",
            t.clone(),
            vec![
                ("x".to_string(), vec![1.0; t.len()]),
                ("u".to_string(), u.clone()),
            ],
        )
        .unwrap();
        let first = tfs_dynamics::SimulateOptions {
            initial_state: tfs_dynamics::InitialState::FirstSamples,
            ..Default::default()
        };
        let truth = tfs_dynamics::simulate_model_on_record(&model, &drive, &first).unwrap();
        // The motion's spread is about 0.05; white noise of about 0.04 on it.
        let x = tfs_signal::noise::add_noise_seeded(
            &truth.x[0],
            28.0,
            tfs_signal::NoiseKind::White,
            11,
        )
        .unwrap();
        let v0 = tfs_dynamics::initial_velocity(&x, dt, first.velocity_window).unwrap();
        // The escape speed from the well's bottom over the barrier at 0 is √(1/2).
        assert!(
            v0.abs() > 0.8,
            "the first samples' velocity {v0} must be past escape"
        );
        let u = tfs_signal::noise::add_noise_seeded(&u, 40.0, tfs_signal::NoiseKind::White, 12)
            .unwrap();
        let rec = Record::new("r", t.clone(), vec![("x".into(), x), ("u".into(), u)]).unwrap();
        let records = [rec];
        let opts = DiagnoseOptions::default();
        let runs = crate::simulate::base_runs(&model, &records, &opts);
        let s = sources(&model, &records, &runs).expect("the start model simulates the record");
        let (lo, hi) = extent(std::iter::once(records[0].column("x").unwrap()));
        let w = 0.25 * (hi - lo);
        for i in 0..4 {
            let made = synthetic(&model, &s[0], &opts, i, 0).expect("the draw simulates");
            let drawn = extent(std::iter::once(made.column("x").unwrap()));
            assert!(
                drawn.0 > lo - w && drawn.1 < hi + w,
                "draw {i} left the record's well: it spans {drawn:?}, the record ({lo}, {hi})"
            );
        }
    }

    #[test]
    fn seeds_differ_for_every_draw_record_and_column() {
        let mut all: Vec<u64> = (0..4)
            .flat_map(|i| (0..3).flat_map(move |r| (0..3).map(move |c| seed(1, i, r, c))))
            .collect();
        let n = all.len();
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), n);
    }
}
