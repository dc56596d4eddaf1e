//! Tied multi-DOF T-F-S regression for chains: one force law per connecting element, shared by
//! the equations of both DOFs it connects (Newton's third law).
//!
//! A library term that is a function of a relative coordinate only, `f(x_i − x_j)` or
//! `(x_i − x_j)'` with `x_j` another DOF, describes the element between masses `i` and `j`. When
//! the same term appears in the libraries of both DOFs, the element pushes on mass `j` with the
//! opposite force: per unit mass its coefficient in `x_j''` is `−(m_i/m_j)` times its
//! coefficient in `x_i''` (paper Eq. 18: `b_k` and `ζ2` appear in both equations). The joint
//! regression stacks the frequency-domain rows of every DOF (the same weak-form rows
//! [`crate::identify_tfs`] builds) and solves for one unknown per element term, so the partner
//! equation no longer has to find the coupling on its own (where it is a small part of the
//! acceleration and is easily zeroed or distorted by noise and collinearity).
//!
//! The stages are the single-DOF fit's ([`crate::blocks`], [`crate::criterion1`],
//! [`crate::criterion3`], [`crate::criterion4`], [`crate::uncertainty`]) on the stacked rows;
//! where the two differ (how held-out settings are scored, Criterion 4's stopping rule, no refit
//! after it, no term test) `docs/DECISIONS.md` says why.

mod layout;

use std::time::Instant;

use faer::Mat;
use tfs_data::Record;
use tfs_library::{Equation, Library, ModelTerm};
use tfs_regress::{Compressed, lstsq_support};

use crate::blocks::{blocks_of, prepare_all, record_bins, time_domain_blocks};
use crate::criterion1::criterion1_dof;
use crate::criterion1::kappa::Criterion1;
use crate::criterion3::rows::{WindowTransform, rows_for};
use crate::criterion3::settings::{choose_setting, grid, loo_errors};
use crate::criterion3::{Transforms, dof_transforms};
use crate::criterion4::{StepResult, StopRule, assemble, residual_stats};
use crate::error::{Result, invalid};
use crate::fit::{Selection, fit_select};
use crate::options::{Checked, IdentifySpec};
use crate::pipeline::{finish, ms};
use crate::trace::{
    AssemblyStep, AssemblyVerdict, ChosenSettings, Criterion4Outcome, DofTrace, Identified, Method,
    RecordBins, TieTrace, TiedTrace,
};
use crate::uncertainty::{ClusterRows, INTERVAL_LEVEL, bin_clusters, jackknife_intervals};
use crate::verdict::tied_support_verdict;
use layout::{DofRows, Layout, stack, ties_of};
pub use layout::{MassChoice, Tie, TieOptions, chain_ties, library_ties};

/// T-F-S SINDy with the force laws of chain elements tied between the DOFs they connect (see the
/// module docs). Criterion 1 per DOF as in [`crate::identify_tfs`]; Criterion 3 rows, the λ path
/// and Criterion 4 with data assembly on the stacked rows of all DOFs; δ, the window count, the
/// STLSQ threshold (and the masses with [`MassChoice::Estimate`]) are chosen from the training
/// records only. Criterion 2 and the term test are not run. The result is an ordinary per-DOF
/// [`tfs_library::Model`] in which the partner coefficients equal `−m_owner/m_partner` times the
/// owner's; the trace's `why` lines and the model trace's `"ties"` entry say which coefficients
/// are tied.
///
/// Errors: the spec's errors of [`crate::identify_tfs`]; no ties in the spec (use
/// [`crate::identify_tfs`]); non-positive or missing masses.
pub fn identify_tfs_tied(
    records: &[Record],
    spec: &IdentifySpec,
    tie: &TieOptions,
) -> Result<Identified> {
    let t_all = Instant::now();
    let spec = &spec.check()?;
    let opt = &spec.tfs;
    let libs = &spec.libraries;
    let nd = libs.len();
    let ties = ties_of(libs, &spec.dofs);
    if ties.is_empty() {
        return invalid(
            "identify_tfs_tied: no library term of a relative coordinate (xi-xj) between two DOFs appears in both DOFs' libraries; add it to both (e.g. '(x2-x1)^1..7' in x1's and x2's library) or use identify_tfs",
        );
    }
    let mut masses = initial_masses(&tie.masses, nd)?;
    let layout = Layout::new(libs, &ties);
    let blocks = blocks_of(records)?;
    let nb = blocks.len();
    if nb < 2 {
        return invalid("identify_tfs_tied needs at least two blocks of data");
    }
    let mut timing = Vec::new();
    let t0 = Instant::now();
    let preps = prepare_all(&blocks, spec, true)?;
    timing.push(("band-limited reconstruction".to_string(), ms(t0)));
    // ---- Time-domain validation rows per DOF and block.
    let td: Vec<Vec<(Mat<f64>, Vec<f64>)>> = (0..nd)
        .map(|d| time_domain_blocks(&preps, &spec.dofs, d, &libs[d]))
        .collect::<Result<_>>()?;
    let PerDof {
        c1s,
        qs,
        transforms,
    } = per_dof_stages(&blocks, &preps, spec, libs, &mut timing)?;
    let joint = Joint {
        layout: &layout,
        libs,
        transforms: &transforms,
        nb,
    };
    let ratios_of =
        |m: &[f64]| -> Vec<f64> { ties.iter().map(|t| m[t.owner] / m[t.partner]).collect() };
    // ---- Settings by leave-one-block-out held-out error of the tied fit.
    let t0 = Instant::now();
    let settings = grid(opt);
    let scores = tied_scores(&joint, &td, &ratios_of(&masses), &settings, opt)?;
    let (candidates, best_err, (wi, di)) = choose_setting(&settings, &scores, &[], opt);
    let (delta, windows) = (opt.criterion3.deltas[di], opt.criterion3.window_counts[wi]);
    let rows = joint.rows(wi, delta);
    timing.push(("settings selection".to_string(), ms(t0)));
    // ---- Masses (optional scan, DOF by DOF relative to the first).
    let mass_why = match &tie.masses {
        MassChoice::Estimate { candidates } => {
            let t0 = Instant::now();
            let why = scan_masses(&joint, &rows, candidates, &mut masses, &ratios_of, spec)?;
            timing.push(("mass scan".to_string(), ms(t0)));
            why
        }
        choice => given_masses_why(choice),
    };
    let ratios = ratios_of(&masses);
    // ---- Data assembly + Criterion 4 (the last block is held out), on the tied rows.
    let t0 = Instant::now();
    let hold = nb - 1;
    let cb = joint.blocks(&rows, &ratios)?;
    let accepted = tied_assembly(&joint, &cb, &rows, &td, &blocks, &ratios, opt)?;
    let (theta, thr) = (&accepted.theta, accepted.thr);
    timing.push(("assembly and criterion 4".to_string(), ms(t0)));
    let coefs = layout.expand(theta, &ratios);
    // ---- Intervals: the cluster jackknife of `identify_tfs` on the joint rows of the records the
    // coefficients were fitted on (a cluster holds the bins of one window pair of one record, of
    // every DOF's equation).
    let t0 = Instant::now();
    let (half, interval_note) = if opt.uncertainty.bagging >= 2 {
        tied_intervals(&joint, wi, accepted.used, delta, theta, &ratios)
    } else {
        (
            vec![None; theta.len()],
            "no coefficient intervals (tfs.bagging = 0)".to_string(),
        )
    };
    timing.push(("intervals".to_string(), ms(t0)));
    // ---- Model and trace.
    let common = Common {
        spec,
        libs,
        layout: &layout,
        ties: &ties,
        ratios: &ratios,
        mass_why,
        head: vec![
            format!(
                "δ = {delta} and {windows} window(s) per record: lowest mean held-out residual ({best_err:.3e}) of the tied fit when each record in turn is left out"
            ),
            match opt.fit.threshold {
                Some(t) => format!("STLSQ threshold {t} given by the user"),
                None => format!(
                    "STLSQ threshold {thr:.4} (scaled): BIC of the tied frequency-domain rows of the held-out record '{}' along a λ path of {} thresholds (more where the library's columns cancel one another)",
                    blocks[hold].source(),
                    opt.fit.n_thresholds
                ),
            },
            interval_note,
        ],
    };
    let bins: Vec<Vec<RecordBins>> = (0..nd)
        .map(|d| {
            record_bins(
                &blocks,
                &preps,
                d,
                &qs[d],
                rows.iter().map(|per| &per[d].2[..]),
            )
        })
        .collect();
    let outcome = TiedOutcome {
        c1s,
        coefs,
        half,
        outcome: accepted.outcome,
        steps: accepted.steps,
        bins,
        settings: ChosenSettings {
            form: opt.criterion3.form,
            delta,
            windows,
            threshold: thr,
            candidates,
            coefficient_candidates: Vec::new(),
            why: Vec::new(),
        },
        held_out: blocks[hold].source().to_string(),
    };
    let (equations, dof_traces) = outcome.into_parts(&common);
    let mut id = finish(
        Method::TfsSindyTied,
        &spec.dofs,
        equations,
        dof_traces,
        timing,
        t_all,
    )?;
    id.trace.tied = Some(tied_trace(&ties, &ratios, &spec.dofs, masses));
    Ok(id)
}

/// The trace's record of the ties: each tied term with its owner, partner and factor, and the
/// masses.
fn tied_trace(ties: &[Tie], ratios: &[f64], dofs: &[String], masses: Vec<f64>) -> TiedTrace {
    TiedTrace {
        ties: ties
            .iter()
            .zip(ratios)
            .map(|(t, r)| TieTrace {
                term: t.term.clone(),
                owner: dofs[t.owner].clone(),
                partner: dofs[t.partner].clone(),
                factor_in_partner: -r,
            })
            .collect(),
        masses,
    }
}

/// The tied fit's per-DOF results before they become equations and traces.
struct TiedOutcome {
    /// Criterion 1 per DOF.
    c1s: Vec<Criterion1>,
    /// Coefficients per DOF and library column.
    coefs: Vec<Vec<f64>>,
    /// Interval half-width per unknown.
    half: Vec<Option<f64>>,
    /// Criterion 4's outcome.
    outcome: Criterion4Outcome,
    /// Criterion 4's steps per DOF.
    steps: Vec<Vec<AssemblyStep>>,
    /// Criterion 3's bins per DOF and record.
    bins: Vec<Vec<RecordBins>>,
    /// The settings (without the `why` lines, which are per DOF).
    settings: ChosenSettings,
    /// The held-out record.
    held_out: String,
}

impl TiedOutcome {
    /// Every DOF's equation and trace, with its support verdict.
    fn into_parts(self, c: &Common<'_>) -> (Vec<Equation>, Vec<DofTrace>) {
        let mut equations = Vec::new();
        let mut dof_traces = Vec::new();
        for (d, ((lib, bins), mut c1)) in c.libs.iter().zip(self.bins).zip(self.c1s).enumerate() {
            equations.push(tied_equation(c, d, &self.coefs[d], &self.half));
            let dof = &c.spec.dofs[d];
            tied_support_verdict(dof, lib, &self.coefs[d], &mut c1);
            let mut verdict = AssemblyVerdict::new(self.outcome.clone());
            if !c1.support.is_supported() {
                verdict.qualify(c1.support.clone());
            }
            dof_traces.push(DofTrace {
                dof: dof.clone(),
                library: lib.names(),
                offered_library: None,
                criterion1: Some(c1),
                criterion2: None,
                regression_library: lib.names(),
                bins,
                settings: ChosenSettings {
                    why: c.why(d),
                    ..self.settings.clone()
                },
                assembly: self.steps[d].clone(),
                assembly_verdict: verdict,
                held_out_record: self.held_out.clone(),
                term_test: None,
            });
        }
        (equations, dof_traces)
    }
}

/// What the tied fit's Criterion 4 accepted: the unknowns, the STLSQ threshold, the records the
/// coefficients were fitted on, the verdict and each DOF's assembly steps.
struct TiedAccepted {
    theta: Vec<f64>,
    thr: f64,
    used: usize,
    outcome: Criterion4Outcome,
    steps: Vec<Vec<AssemblyStep>>,
}

/// Data assembly and Criterion 4 on the tied rows `cb` (one per block; `rows` per block and DOF)
/// with every DOF's held-out time-domain block of `td`: met when every DOF meets it. The tied fit
/// keeps the coefficients of the step that met it (see `docs/DECISIONS.md`); when the records
/// run out, the last step's support is refit on every block.
fn tied_assembly(
    joint: &Joint<'_>,
    cb: &[Compressed],
    rows: &[Vec<DofRows>],
    td: &[Vec<(Mat<f64>, Vec<f64>)>],
    blocks: &[Record],
    ratios: &[f64],
    opt: &crate::options::TfsOptions,
) -> Result<TiedAccepted> {
    let (layout, nb, nd) = (joint.layout, joint.nb, joint.libs.len());
    let hold = nb - 1;
    let step = |k: usize| -> StepResult<Selection> {
        let train = Compressed::merge(&cb[..k])?;
        let (theta, thr) = fit_select(&train, &cb[hold], opt.fit.threshold, opt.fit.n_thresholds)?;
        let coefs = layout.expand(&theta, ratios);
        let stats = (0..nd)
            .map(|d| {
                let (ha, hy) = &td[d][hold];
                let (mu, sigma) = residual_stats(ha.as_ref(), hy, &coefs[d]);
                AssemblyStep {
                    records: blocks[..k].iter().map(|r| r.source().to_string()).collect(),
                    rows: rows[..k].iter().map(|per| per[d].0.nrows()).sum(),
                    n_terms: coefs[d].iter().filter(|c| **c != 0.0).count(),
                    mu,
                    sigma,
                }
            })
            .collect();
        Ok(((theta, thr), stats))
    };
    let rule = StopRule {
        mu0: opt.criterion4.mu0,
        sigma0: opt.criterion4.sigma0,
        previous_nonempty: false,
    };
    let run = assemble(hold, nd, &rule, step)?;
    let (theta, thr, used, outcome) = match run.accepted() {
        Some((k, (c, t))) => {
            // The coefficients of the assembly step that met the criterion (see DECISIONS.md
            // for why the tied fit does not refit them on every record).
            let outcome = Criterion4Outcome::TiedMet {
                after: k,
                held_out: blocks[hold].source().to_string(),
            };
            (c, t, k, outcome)
        }
        None => {
            let (c, t) = run.last_or((vec![0.0; layout.params.len()], 0.0));
            let support: Vec<bool> = c.iter().map(|v| *v != 0.0).collect();
            let all = Compressed::merge(cb)?;
            let f = lstsq_support(&all, &support)?;
            (f.coef, t, nb, Criterion4Outcome::TiedRanOut { records: nb })
        }
    };
    Ok(TiedAccepted {
        theta,
        thr,
        used,
        outcome,
        steps: run.steps,
    })
}

/// Criterion 1 per DOF (κ, κ0 and the verdict of the untied library) and Criterion 3's
/// transforms per DOF, window count and block (reweighted per DOF by its own untied
/// full-library fit, as in the single-DOF pipeline), with the decimation per DOF and block.
fn per_dof_stages(
    blocks: &[Record],
    preps: &[crate::blocks::Prepared<'_>],
    spec: &Checked<'_>,
    libs: &[Library],
    timing: &mut Vec<(String, f64)>,
) -> Result<PerDof> {
    let t0 = Instant::now();
    let mut c1s: Vec<Criterion1> = Vec::with_capacity(libs.len());
    for (d, lib) in libs.iter().enumerate() {
        c1s.push(criterion1_dof(blocks, preps, spec, d, lib)?.verdict);
    }
    preps.iter().for_each(|p| p.release_spectra());
    timing.push(("criterion 1".to_string(), ms(t0)));
    let t0 = Instant::now();
    let mut qs = Vec::with_capacity(libs.len());
    let mut transforms: Vec<Transforms> = Vec::with_capacity(libs.len());
    for (d, lib) in libs.iter().enumerate() {
        let all: Vec<usize> = (0..lib.len()).collect();
        let (q, t) = dof_transforms(preps, spec, d, lib, &all)?;
        qs.push(q);
        transforms.push(t);
    }
    timing.push(("criterion 3 transforms".to_string(), ms(t0)));
    Ok(PerDof {
        c1s,
        qs,
        transforms,
    })
}

/// What the tied fit computes per DOF before it stacks the rows: Criterion 1, the decimation
/// per record and Criterion 3's transforms.
struct PerDof {
    c1s: Vec<Criterion1>,
    qs: Vec<Vec<usize>>,
    transforms: Vec<Transforms>,
}

/// The trace line of masses that are not estimated.
fn given_masses_why(choice: &MassChoice) -> String {
    match choice {
        MassChoice::Given(m) => format!("masses given by the user: {m:?}"),
        _ => "masses equal (tie factor −1)".to_string(),
    }
}

/// The masses the fit starts from (all 1 unless given), after checking the choice.
fn initial_masses(choice: &MassChoice, nd: usize) -> Result<Vec<f64>> {
    match choice {
        MassChoice::Equal => Ok(vec![1.0; nd]),
        MassChoice::Given(m) => {
            if m.len() != nd || m.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                return invalid(format!(
                    "tie.masses = Given({m:?}): give one positive finite mass per DOF ({nd})"
                ));
            }
            Ok(m.clone())
        }
        MassChoice::Estimate { candidates } => {
            if candidates.is_empty() || candidates.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                return invalid(format!(
                    "tie.masses = Estimate {{ candidates: {candidates:?} }}: give at least one positive finite ratio"
                ));
            }
            Ok(vec![1.0; nd])
        }
    }
}

/// The joint regression's inputs: the layout of the unknowns, the libraries and every DOF's
/// transforms (`transforms[dof][window count][record]`) of `nb` records.
struct Joint<'a> {
    layout: &'a Layout,
    libs: &'a [Library],
    transforms: &'a [Transforms],
    nb: usize,
}

impl Joint<'_> {
    /// Frequency rows per block and DOF for one (window count, δ).
    fn rows(&self, wi: usize, delta: f64) -> Vec<Vec<DofRows>> {
        (0..self.nb)
            .map(|b| {
                (0..self.libs.len())
                    .map(|d| {
                        let all: Vec<usize> = (0..self.libs[d].len()).collect();
                        let parts = self.transforms[d][wi][b]
                            .iter()
                            .map(|w| rows_for(w, delta, &all))
                            .collect();
                        stack(parts, self.libs[d].len())
                    })
                    .collect()
            })
            .collect()
    }

    /// The joint rows of every block, compressed, at the tie ratios `ratios`.
    fn blocks(&self, rows: &[Vec<DofRows>], ratios: &[f64]) -> Result<Vec<Compressed>> {
        rows.iter()
            .map(|per| {
                let pd: Vec<(Mat<f64>, Vec<f64>)> =
                    per.iter().map(|(a, y, _)| (a.clone(), y.clone())).collect();
                self.layout.joint(&pd, ratios)
            })
            .collect()
    }
}

/// The held-out score of the tied fit at every setting of `settings` (see [`tied_loo`]): trained
/// on the other blocks' joint frequency rows, scored on the held-out block's joint time-domain
/// rows (`td[dof][block]`) at the tie ratios `ratios`.
fn tied_scores(
    joint: &Joint<'_>,
    td: &[Vec<(Mat<f64>, Vec<f64>)>],
    ratios: &[f64],
    settings: &[(usize, usize)],
    opt: &crate::options::TfsOptions,
) -> Result<Vec<f64>> {
    let val: Vec<Compressed> = (0..joint.nb)
        .map(|b| {
            let per: Vec<(Mat<f64>, Vec<f64>)> = td.iter().map(|t| t[b].clone()).collect();
            joint.layout.joint(&per, ratios)
        })
        .collect::<Result<_>>()?;
    let cb: Vec<Vec<Compressed>> = settings
        .iter()
        .map(|&(wi, di)| joint.blocks(&joint.rows(wi, opt.criterion3.deltas[di]), ratios))
        .collect::<Result<_>>()?;
    tied_loo(&cb, &val, opt)
}

/// Mean leave-one-block-out held-out error of the tied fit at every setting: trained on the
/// other blocks' rows `cb[setting]`, scored by the relative residual on the held-out block's
/// compressed rows `val[block]`.
fn tied_loo(
    cb: &[Vec<Compressed>],
    val: &[Compressed],
    opt: &crate::options::TfsOptions,
) -> Result<Vec<f64>> {
    loo_errors(
        cb.len(),
        val.len(),
        &|g, k| &cb[g][k],
        &|train, held| Ok(fit_select(train, held, opt.fit.threshold, opt.fit.n_thresholds)?.0),
        &|_, f, coef| Ok(val[f].rss(&coef)? / val[f].b_norm2().max(f64::MIN_POSITIVE)),
    )
}

/// The mass scan: each DOF's mass relative to the first, one DOF at a time over the candidate
/// ratios, scored on the held-out block's own frequency rows (the rows are fixed during the
/// scan, so these errors are comparable across ratios, and they are the rows the regression
/// weighs; the band-limited time-domain residual is dominated by the reconstruction noise of
/// x1'' and does not resolve the ratio). Updates `masses`; returns the trace line.
fn scan_masses(
    joint: &Joint<'_>,
    rows: &[Vec<DofRows>],
    candidates: &[f64],
    masses: &mut [f64],
    ratios_of: &dyn Fn(&[f64]) -> Vec<f64>,
    spec: &Checked<'_>,
) -> Result<String> {
    let opt = &spec.tfs;
    let mut scores = Vec::new();
    for d in 1..masses.len() {
        let mut best_m: Option<(f64, f64)> = None;
        for &c in candidates {
            let mut m = masses.to_vec();
            m[d] = c * masses[0];
            let cbm = joint.blocks(rows, &ratios_of(&m))?;
            let err = tied_loo(std::slice::from_ref(&cbm), &cbm, opt)?[0];
            scores.push((d, c, err));
            if best_m.is_none_or(|b| err < b.1) {
                best_m = Some((c, err));
            }
        }
        if let Some((c, _)) = best_m {
            masses[d] = c * masses[0];
        }
    }
    Ok(format!(
        "masses estimated relative to {} by a scan of the candidate ratios scored by the leave-one-record-out error on the held-out frequency rows: {:?} (DOF, ratio, error: {})",
        spec.dofs[0],
        masses,
        scores
            .iter()
            .map(|(d, c, e)| format!("{} {c} {e:.3e}", spec.dofs[*d]))
            .collect::<Vec<_>>()
            .join("; ")
    ))
}

/// What every DOF's part of the tied model and trace shares.
struct Common<'a> {
    spec: &'a Checked<'a>,
    libs: &'a [Library],
    layout: &'a Layout,
    ties: &'a [Tie],
    ratios: &'a [f64],
    mass_why: String,
    /// The settings', threshold's and intervals' trace lines.
    head: Vec<String>,
}

impl Common<'_> {
    /// The `why` lines of DOF `d`.
    fn why(&self, d: usize) -> Vec<String> {
        let mut why = vec![
            format!(
                "tied chain regression: the rows of all {} DOF equations solved together with one unknown per element term ({} unknowns for {} library columns)",
                self.libs.len(),
                self.layout.params.len(),
                self.libs.iter().map(|l| l.len()).sum::<usize>()
            ),
            self.mass_why.clone(),
        ];
        why.extend(self.head.iter().cloned());
        let tied_here: Vec<String> = self
            .ties
            .iter()
            .zip(self.ratios)
            .filter(|(t, _)| t.partner == d)
            .map(|(t, r)| {
                format!(
                    "{} = −{r:.4}×(its coefficient in {}'')",
                    t.term, self.spec.dofs[t.owner]
                )
            })
            .collect();
        if !tied_here.is_empty() {
            why.push(format!(
                "tied coefficients (Newton's third law): {}",
                tied_here.join("; ")
            ));
        }
        why
    }
}

/// DOF `d`'s equation of the tied model (its coefficients `coef`), each term's interval the
/// interval of its unknown (`half`) times the tie factor.
fn tied_equation(c: &Common<'_>, d: usize, coef: &[f64], half: &[Option<f64>]) -> Equation {
    let terms = c.libs[d]
        .terms()
        .iter()
        .zip(coef)
        .enumerate()
        .filter(|(_, (_, c))| **c != 0.0)
        .map(|(j, (t, cf))| {
            let mut mt = ModelTerm::new(t.clone(), *cf);
            let (p, _) = c.layout.map[d][j];
            mt.interval = half[p].map(|h| {
                let h = h * c.layout.factor(d, j, c.ratios).abs();
                [cf - h, cf + h]
            });
            mt
        })
        .collect();
    Equation {
        dof: c.spec.dofs[d].clone(),
        terms,
    }
}

/// Half-widths (level [`INTERVAL_LEVEL`]) of the tied unknowns `theta` that are not zero, by the
/// cluster jackknife of [`crate::identify_tfs`] on the joint rows the coefficients were fitted
/// on: every DOF's frequency rows of the first `used` records (window count index `wi`, relative
/// amplitude ≥ `delta`) mapped onto the unknowns, grouped by (record, window pair, bins) across
/// the DOFs — the bins of one stretch of one record share its noise in every equation. Returns
/// the half-width per unknown (`None` for the zero ones, or for all when there are too few
/// clusters) and the trace line.
fn tied_intervals(
    joint: &Joint<'_>,
    wi: usize,
    used: usize,
    delta: f64,
    theta: &[f64],
    ratios: &[f64],
) -> (Vec<Option<f64>>, String) {
    let layout = joint.layout;
    let sel: Vec<usize> = (0..theta.len()).filter(|&p| theta[p] != 0.0).collect();
    let mut half = vec![None; theta.len()];
    if sel.is_empty() {
        return (
            half,
            "no coefficient intervals: no term survives".to_string(),
        );
    }
    let mut pos = vec![usize::MAX; theta.len()];
    for (k, &p) in sel.iter().enumerate() {
        pos[p] = k;
    }
    let mut clusters: std::collections::BTreeMap<(usize, usize, usize), ClusterRows> =
        Default::default();
    for (d, per_window_count) in joint.transforms.iter().enumerate() {
        let Some(per_block) = per_window_count.get(wi) else {
            continue;
        };
        let all: Vec<usize> = (0..layout.map[d].len()).collect();
        let rows: Vec<(usize, usize, &WindowTransform)> = per_block
            .iter()
            .take(used)
            .enumerate()
            .flat_map(|(b, wins)| wins.iter().enumerate().map(move |(w, t)| (b, w, t)))
            .collect();
        for (key, rs) in bin_clusters(&rows, delta, &all) {
            let entry = clusters.entry(key).or_default();
            for (row, y) in rs {
                let mut r = vec![0.0; sel.len()];
                for (j, v) in row.iter().enumerate() {
                    let k = pos[layout.map[d][j].0];
                    if k != usize::MAX {
                        r[k] += layout.factor(d, j, ratios) * v;
                    }
                }
                entry.push((r, y));
            }
        }
    }
    let clusters: Vec<ClusterRows> = clusters.into_values().collect();
    let sub: Vec<f64> = sel.iter().map(|&p| theta[p]).collect();
    match jackknife_intervals(&clusters, &sub) {
        Some((h, g, nus)) => {
            for (k, &p) in sel.iter().enumerate() {
                half[p] = Some(h[k]);
            }
            let lo = nus.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = nus.iter().cloned().fold(0.0, f64::max);
            (
                half,
                format!(
                    "coefficient intervals: {:.0}% (± t·SE) of each tied unknown (a partner's interval is the owner's times the tie factor), standard errors by a jackknife over {g} clusters of the joint rows (one window pair of one record, every DOF's equation), t on each unknown's effective degrees of freedom ({lo:.1}–{hi:.1}); no term test and no inclusion probabilities in the tied fit",
                    100.0 * INTERVAL_LEVEL
                ),
            )
        }
        None => (
            half,
            "no coefficient intervals: too few independent clusters of bins".to_string(),
        ),
    }
}
