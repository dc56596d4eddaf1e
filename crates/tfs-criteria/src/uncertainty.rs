//! The uncertainty of a fitted model: 95 % intervals of the kept coefficients (a jackknife over
//! clusters of neighbouring bins, on each coefficient's effective degrees of freedom), the
//! bootstrap inclusion probability of every term over the same clusters, and the term test a
//! kept term must pass (significance shared among every candidate term of the library).

use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;
use tfs_regress::{BagOptions, Compressed, Stlsq, bagging_with_total, lambda_path};

use crate::criterion3::rows::{REWEIGHT_HALF, WindowTransform, rows_for};
use crate::error::Result;
use crate::fit::{path_opts, threshold_for_support};
use crate::pipeline::{DofContext, Regression};

/// Level of the coefficient intervals.
pub(crate) const INTERVAL_LEVEL: f64 = 0.95;

/// The two-sided `level` quantile of Student's t with `nu` degrees of freedom (`t` with
/// `P(|T| ≤ t) = level`).
fn student_t_quantile(nu: f64, level: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    StudentsT::new(0.0, 1.0, nu.max(1.0))
        .map(|t| t.inverse_cdf(0.5 + 0.5 * level))
        .unwrap_or(f64::INFINITY)
}

/// The test a selected term must pass to stay in the model: `|coefficient| ≥ t·SE` with `t`
/// the two-sided quantile of Student's t on the jackknife's clusters less one at the level
/// `1 − 0.05/m`, `m` the number of candidate terms the library offered (Bonferroni: STLSQ picks
/// the terms that fit the noise best out of all `m`); the SE is recovered from the term's 95 %
/// interval on that interval's own degrees of freedom. Why this test, and what it changed on
/// repeated noise draws: `docs/DECISIONS.md`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TermTest {
    /// Candidate terms `m` (non-constant terms of the library offered).
    pub candidates: usize,
    /// Two-sided level `1 − 0.05/m`.
    pub level: f64,
    /// Degrees of freedom of the test: the clusters of the jackknife less one.
    pub dof: f64,
    /// The critical `|coefficient| / SE`.
    pub t_critical: f64,
    /// Degrees of freedom of each term's interval (design-based; see `cluster_intervals`),
    /// which turn its 95 % half-width back into its standard error.
    pub interval_dof: std::collections::BTreeMap<String, f64>,
}

impl TermTest {
    /// The test for `candidates` candidate terms on `dof` degrees of freedom, with the
    /// intervals' own degrees of freedom `interval_dof` per term.
    fn new(
        candidates: usize,
        dof: f64,
        interval_dof: std::collections::BTreeMap<String, f64>,
    ) -> Self {
        let m = candidates.max(1) as f64;
        let level = 1.0 - (1.0 - INTERVAL_LEVEL) / m;
        Self {
            candidates,
            level,
            dof,
            t_critical: student_t_quantile(dof, level),
            interval_dof,
        }
    }

    /// Does the term `term` with coefficient `coef` and 95 % interval `[lo, hi]` pass?
    pub fn passes(&self, term: &str, coef: f64, interval: [f64; 2]) -> bool {
        self.margin(term, coef, interval) >= 1.0
    }

    /// `|coef|` over the critical value: below 1 fails; the smallest is the least significant.
    pub fn margin(&self, term: &str, coef: f64, [lo, hi]: [f64; 2]) -> f64 {
        let nu = self.interval_dof.get(term).copied().unwrap_or(self.dof);
        let se = 0.5 * (hi - lo) / student_t_quantile(nu, INTERVAL_LEVEL);
        coef.abs() / (self.t_critical * se)
    }
}

/// Neighbouring bins per cluster of the interval estimate: the span over which
/// [`crate::criterion3::rows::reweight`] averages residual power into a bin's weight, so every
/// bin's weight depends (almost) only on residuals of its own cluster and its neighbours' (see
/// `docs/DECISIONS.md` for the coverage this gives).
const CLUSTER_BINS: usize = 2 * REWEIGHT_HALF;

/// Half-widths (level [`INTERVAL_LEVEL`]) of the coefficients `sel` of `coef` (positions among
/// the regression columns) from a cluster jackknife on the frequency-domain rows of `clusters`
/// (every regression column, from [`bin_clusters`]): leaving cluster `g` out moves the
/// least-squares coefficients by exactly `z_g = (G − G_g)⁻¹ A_gᵀ e_g` (`G = AᵀA`; `G_g`, `e_g`
/// the cluster's Gram matrix and residuals), and `V = (C−1)/C · Σ_g (z_g − z̄)(z_g − z̄)ᵀ`. The
/// quantile is Student's t on each coefficient's own design-based degrees of freedom
/// ([`effective_dof`]). Returns the half-widths, `C` and the degrees of freedom of each
/// coefficient, or `None` with fewer than 3 clusters or when leaving one cluster out leaves the
/// fit undetermined. The choices and their coverage on repeated noise draws:
/// `docs/DECISIONS.md`.
fn cluster_intervals(
    clusters: &[ClusterRows],
    sel: &[usize],
    coef: &[f64],
    fixed: Option<usize>,
) -> Option<(Vec<f64>, usize, Vec<f64>)> {
    // A fixed column's part of the target is taken off every row (its coefficient is known).
    let fixed_part = |row: &[f64]| fixed.map_or(0.0, |j| coef[j] * row[j]);
    let own: Vec<ClusterRows> = clusters
        .iter()
        .map(|rows| {
            rows.iter()
                .map(|(row, y)| (sel.iter().map(|&j| row[j]).collect(), *y - fixed_part(row)))
                .collect()
        })
        .collect();
    let sub: Vec<f64> = sel.iter().map(|&j| coef[j]).collect();
    jackknife_intervals(&own, &sub)
}

/// The delete-one-cluster jackknife of `cluster_intervals` on clusters of rows that already
/// hold only the fitted coefficients' columns (`coef[c]` multiplies column `c`): half-widths of
/// the [`INTERVAL_LEVEL`] intervals, the number of clusters and each coefficient's effective
/// degrees of freedom. Shared with the tied chain fit, whose rows are the joint ones.
pub(crate) fn jackknife_intervals(
    clusters: &[ClusterRows],
    coef: &[f64],
) -> Option<(Vec<f64>, usize, Vec<f64>)> {
    use faer::linalg::solvers::Solve;
    let k = coef.len();
    let mut norms = vec![0.0; k];
    for (row, _) in clusters.iter().flatten() {
        for c in 0..k {
            norms[c] += row[c] * row[c];
        }
    }
    let g = clusters.len();
    if g < 3 || k == 0 {
        return None;
    }
    // Columns scaled to unit norm (x^7 and x' differ by orders of magnitude).
    let d: Vec<f64> = norms
        .iter()
        .map(|v| if *v > 0.0 { 1.0 / v.sqrt() } else { 0.0 })
        .collect();
    // Each cluster's Gram matrix and score A_gᵀe_g, and their sum.
    let mut gram = Mat::<f64>::zeros(k, k);
    let mut own: Vec<(Mat<f64>, Mat<f64>)> = Vec::with_capacity(g);
    for rows in clusters {
        let mut gg = Mat::<f64>::zeros(k, k);
        let mut sg = Mat::<f64>::zeros(k, 1);
        for (row, y) in rows {
            let e = y - (0..k).map(|c| row[c] * coef[c]).sum::<f64>();
            for p in 0..k {
                sg[(p, 0)] += row[p] * d[p] * e;
                for q in 0..k {
                    gg[(p, q)] += row[p] * d[p] * row[q] * d[q];
                }
            }
        }
        gram += &gg;
        own.push((gg, sg));
    }
    let mut z = Mat::<f64>::zeros(k, g);
    for (gi, (gg, sg)) in own.iter().enumerate() {
        let rest = &gram - gg;
        if !well_conditioned(&rest) {
            return None;
        }
        let zg = rest.llt(faer::Side::Lower).ok()?.solve(sg);
        for p in 0..k {
            z[(p, gi)] = zg[(p, 0)];
        }
    }
    let gf = g as f64;
    let nus = {
        let hg: Vec<Mat<f64>> = own.iter().map(|(a, _)| a.clone()).collect();
        effective_dof(&gram, &hg)
    };
    let half = (0..k)
        .map(|p| {
            let tq = student_t_quantile(nus[p], INTERVAL_LEVEL);
            let mean = (0..g).map(|c| z[(p, c)]).sum::<f64>() / gf;
            let v = (0..g).map(|c| (z[(p, c)] - mean).powi(2)).sum::<f64>() * (gf - 1.0) / gf;
            tq * v.sqrt() * d[p]
        })
        .collect();
    Some((half, g, nus))
}

/// Smallest eigenvalue over largest of a leave-one-cluster-out Gram matrix (columns at unit norm)
/// below which the other clusters are taken not to pin the coefficients down.
const JACKKNIFE_MIN_EIGEN_RATIO: f64 = 1e-12;

/// Whether the symmetric matrix `a` is far enough from singular for a jackknife replicate. Whether
/// a Cholesky factorisation of a matrix within rounding of singular succeeds is decided by the
/// last digits of the data (reprinting a record at 15 digits, or shifting its time column, turned
/// intervals on and off and with them the term test); the eigenvalue ratio decides with a margin
/// of four orders of magnitude above rounding.
fn well_conditioned(a: &Mat<f64>) -> bool {
    let Ok(ev) = a.self_adjoint_eigenvalues(faer::Side::Lower) else {
        return false;
    };
    let hi = ev.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let lo = ev.iter().fold(f64::INFINITY, |m, &v| m.min(v));
    hi > 0.0 && lo > JACKKNIFE_MIN_EIGEN_RATIO * hi
}

/// Design-based effective degrees of freedom of the cluster variance of each coefficient, after
/// Bell & McCaffrey (2002) and Imbens & Kolesár (2016): under the working model of independent
/// rows of equal variance, the cluster variance of the coefficient `ℓᵀβ` is a quadratic form
/// in the errors whose eigenvalues are those of the `C × C` matrix
/// `B_gh = δ_gh vᵀG_g v − (G_g v)ᵀ G⁻¹ (G_h v)`, `v = G⁻¹ℓ`, and its Satterthwaite degrees of
/// freedom are `(tr B)² / ‖B‖²_F`. Equal clusters give `C − 1`; clusters of unequal weight
/// give fewer. They depend on the design (`gram = G` and the clusters' Gram matrices `own`), not on the residuals, so they are not themselves noisy. Clamped to
/// `[1, C − 1]`; `C − 1` for every coefficient if `G` cannot be factored.
fn effective_dof(gram: &Mat<f64>, own: &[Mat<f64>]) -> Vec<f64> {
    use faer::linalg::solvers::Solve;
    let k = gram.nrows();
    let c = own.len() as f64;
    let Ok(llt) = gram.llt(faer::Side::Lower) else {
        return vec![(c - 1.0).max(1.0); k];
    };
    let dot = |a: &Mat<f64>, b: &Mat<f64>| (0..k).map(|i| a[(i, 0)] * b[(i, 0)]).sum::<f64>();
    (0..k)
        .map(|p| {
            let l = Mat::<f64>::from_fn(k, 1, |i, _| if i == p { 1.0 } else { 0.0 });
            let v = llt.solve(&l);
            let u: Vec<Mat<f64>> = own.iter().map(|m| m * &v).collect();
            let gu: Vec<Mat<f64>> = u.iter().map(|x| llt.solve(x)).collect();
            let (mut tr, mut fro) = (0.0, 0.0);
            for (a, ua) in u.iter().enumerate() {
                for (b, gub) in gu.iter().enumerate() {
                    let mut x = -dot(ua, gub);
                    if a == b {
                        x += dot(&v, ua);
                        tr += x;
                    }
                    fro += x * x;
                }
            }
            if fro > 0.0 && tr.is_finite() {
                (tr * tr / fro).clamp(1.0, (c - 1.0).max(1.0))
            } else {
                (c - 1.0).max(1.0)
            }
        })
        .collect()
}

/// A library term as [`inclusion_caveat`] sees it.
struct CaveatTerm {
    name: String,
    /// In the model.
    kept: bool,
    /// Its interval passes the [`TermTest`].
    significant: bool,
    /// Bootstrap inclusion.
    inclusion: f64,
    /// Its coefficient in STLSQ's scaled units (columns and target of unit norm), from least
    /// squares on every column.
    scaled: f64,
}

/// Inclusion below this, for a term the term test keeps, gets the caveat of [`inclusion_caveat`].
const LOW_INCLUSION: f64 = 0.9;

/// What a low inclusion means when the term test keeps the term: STLSQ cuts by scaled size at
/// the threshold `thr`, and powers of x are so collinear that an insignificant term can have
/// nearly the scaled size of a well-determined one, so inclusion then says how close the term
/// sits to the cut. Returns `None` when no kept, significant term has inclusion below
/// [`LOW_INCLUSION`].
fn inclusion_caveat(terms: &[CaveatTerm], thr: f64) -> Option<String> {
    let low: Vec<&CaveatTerm> = terms
        .iter()
        .filter(|t| t.kept && t.significant && t.inclusion < LOW_INCLUSION)
        .collect();
    if low.is_empty() {
        return None;
    }
    let list = low
        .iter()
        .map(|t| {
            format!(
                "{} ({:.2}; scaled size {:.2})",
                t.name,
                t.inclusion,
                t.scaled.abs()
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    let rival = terms
        .iter()
        .filter(|t| !t.kept)
        .max_by(|a, b| a.scaled.abs().total_cmp(&b.scaled.abs()))
        .map_or(String::new(), |t| {
            format!(
                ", and the largest term left out, {}, has scaled size {:.2}",
                t.name,
                t.scaled.abs()
            )
        });
    Some(format!(
        ". Low inclusion though significant: {list}. STLSQ cuts by scaled size (threshold {thr:.2}){rival}; \
         so here inclusion says how close the term sits to the cut, not how well the data pin it \
         down — the interval and the term test say that"
    ))
}

/// Blocks for bagging: the clusters of frequency-domain rows of [`bin_clusters`] (those of
/// `cluster_intervals`: `CLUSTER_BINS` neighbouring bins of one pair of overlapping windows),
/// each compressed (tens of them; why not whole windows: `docs/DECISIONS.md`).
fn cluster_blocks(clusters: Vec<ClusterRows>) -> Result<Vec<Compressed>> {
    clusters
        .into_par_iter()
        .with_max_len(1)
        .map(|c| {
            let k = c.first().map_or(0, |r| r.0.len());
            let m = Mat::<f64>::from_fn(c.len(), k, |i, j| c[i].0[j]);
            let y: Vec<f64> = c.iter().map(|r| r.1).collect();
            Ok(Compressed::from_rows(m.as_ref(), &y)?)
        })
        .collect()
}

/// Rows `(A row, left-hand side)` of one cluster of bins.
pub(crate) type ClusterRows = Vec<(Vec<f64>, f64)>;

/// The frequency-domain rows (bins with relative amplitude ≥ `delta`, columns `cols`) of `rows`
/// (record, window, transform) grouped into clusters of `CLUSTER_BINS` neighbouring bins of one
/// pair of overlapping windows; each row with its left-hand side.
pub(crate) fn bin_clusters(
    rows: &[(usize, usize, &WindowTransform)],
    delta: f64,
    cols: &[usize],
) -> std::collections::BTreeMap<(usize, usize, usize), ClusterRows> {
    let k = cols.len();
    let mut clusters: std::collections::BTreeMap<_, ClusterRows> = Default::default();
    for &(r, w, t) in rows {
        let (a, y, f) = rows_for(t, delta, cols);
        if a.nrows() == 0 {
            continue;
        }
        let mut i = 0;
        for (fb, bin) in f.iter().zip(cluster_bins(t, &f)) {
            let nrow = if *fb > 0.0 { 2 } else { 1 };
            let entry = clusters.entry((r, w / 2, bin / CLUSTER_BINS)).or_default();
            for _ in 0..nrow {
                entry.push(((0..k).map(|c| a[(i, c)]).collect(), y[i]));
                i += 1;
            }
        }
    }
    clusters
}

/// How many clusters [`bin_clusters`] forms from `rows` at `delta` (the same keys, without
/// building the rows).
pub(crate) fn cluster_count(rows: &[(usize, usize, &WindowTransform)], delta: f64) -> usize {
    let mut keys = std::collections::BTreeSet::new();
    for &(r, w, t) in rows {
        let f = crate::criterion3::rows::kept_freqs(t, delta);
        for bin in cluster_bins(t, &f) {
            keys.insert((r, w / 2, bin / CLUSTER_BINS));
        }
    }
    keys.len()
}

/// The bin index of each kept frequency `f` of the window transform `t` on its own grid of
/// stored bins (from the lowest stored frequency, in steps of the smallest spacing), or its
/// position among `f` when the grid has no spacing.
fn cluster_bins<'f>(t: &WindowTransform, f: &'f [f64]) -> impl Iterator<Item = usize> + 'f {
    let f0 = t.freq.iter().cloned().fold(f64::INFINITY, f64::min);
    let step = t
        .freq
        .windows(2)
        .map(|p| p[1] - p[0])
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    f.iter().enumerate().map(move |(b, &fb)| {
        if step.is_finite() && step > 0.0 {
            ((fb - f0) / step).round() as usize
        } else {
            b
        }
    })
}

/// What [`uncertainty_stage`] found: per regression column its interval and inclusion
/// probability, the trace line that says how, and the term test.
pub(crate) struct Uncertainty {
    /// 95 % interval per regression column (`None`: not kept, the constant, or no intervals).
    pub intervals: Vec<Option<[f64; 2]>>,
    /// Bootstrap inclusion probability per regression column.
    pub inclusion: Vec<Option<f64>>,
    /// How the intervals and inclusion were obtained (or why not).
    pub note: String,
    /// The term test of the kept terms (with intervals only).
    pub term_test: Option<TermTest>,
}

/// Intervals and inclusion probabilities of the coefficients `coef` (per regression column of
/// `reg`) by resampling clusters of the frequency rows of the first `used` records
/// (`transforms`: their windows at the chosen window count; `delta` the chosen bin threshold,
/// `thr` the selection's STLSQ threshold). A pass that the elimination will replace (not
/// `final_pass`, and a kept term fails the term test) skips the bootstrap.
#[allow(clippy::too_many_arguments)]
pub(crate) fn uncertainty_stage(
    ctx: &DofContext<'_>,
    reg: &Regression,
    transforms: &[Vec<WindowTransform>],
    used: usize,
    delta: f64,
    coef: &[f64],
    thr: f64,
) -> Result<Uncertainty> {
    let opt = &ctx.spec.tfs;
    let keep = &reg.keep[..];
    let support: Vec<bool> = coef.iter().map(|v| *v != 0.0).collect();
    let mut out = Uncertainty {
        intervals: vec![None; keep.len()],
        inclusion: vec![None; keep.len()],
        note: "no coefficient intervals (tfs.bagging = 0)".to_string(),
        term_test: None,
    };
    if !(opt.uncertainty.bagging >= 2 && support.iter().any(|&s| s)) {
        return Ok(out);
    }
    let rows: Vec<(usize, usize, &WindowTransform)> = transforms
        .iter()
        .take(used)
        .enumerate()
        .flat_map(|(r, wins)| wins.iter().enumerate().map(move |(w, t)| (r, w, t)))
        .collect();
    // Every cluster's rows over the regression columns, built once: the jackknife reads the
    // model's columns of them, the bootstrap compresses them whole (a pass the elimination
    // replaces skips it).
    let clusters_all: Vec<ClusterRows> = bin_clusters(&rows, delta, keep).into_values().collect();
    let n_parts = clusters_all.len();
    if n_parts < crate::criterion3::settings::MIN_CLUSTERS {
        out.note =
            format!("no coefficient intervals: only {n_parts} independent window(s) to resample");
        return Ok(out);
    }
    let groups = jackknife_step(ctx, reg, &clusters_all, coef, &support, &mut out);
    // Terms that fail the term test; the elimination of `identify_tfs` removes the least
    // significant and re-runs the selection, and that pass replaces this model (`identify_tfs`
    // re-runs whenever a term can go and one is left).
    let weak = (0..keep.len())
        .filter(|&j| !passes_term_test(ctx, reg, &out, coef, j).unwrap_or(true))
        .count();
    let replaced = !ctx.final_pass && weak > 0 && ctx.lib.len() > 1;
    let inclusion_note = if replaced {
        "inclusion not computed in this pass (terms are removed and the selection re-run)"
            .to_string()
    } else {
        bootstrap_step(ctx, reg, clusters_all, coef, &support, thr, &mut out)?
    };
    out.note = interval_note(groups, out.term_test.as_ref(), &inclusion_note);
    Ok(out)
}

/// Whether kept column `j` passes the term test (`None` without an interval or a test).
fn passes_term_test(
    ctx: &DofContext<'_>,
    reg: &Regression,
    u: &Uncertainty,
    coef: &[f64],
    j: usize,
) -> Option<bool> {
    let (iv, t) = u.intervals[j].zip(u.term_test.as_ref())?;
    Some(t.passes(&ctx.names[reg.keep[j]], coef[j], iv))
}

/// The jackknife over the clusters: intervals of the kept terms (not the constant, which is
/// estimated in the time domain) and their term test, written into `out`; the number of
/// clusters that pinned them down (`None` when too few did).
///
/// A kept constant's part is taken off the target at its time-domain value (fixed, not
/// resampled: the mean residual over every sample pins it far better than these bins): the
/// windowed transform of a constant is the window's own spectrum, which reaches the low bins
/// the regression keeps, so leaving it in the residual would put the offset's leakage into
/// every cluster and widen the other terms' intervals until they all fail the term test (a
/// linear oscillator recorded with a sensor offset lost its stiffness, damping and input that
/// way); fitting it afresh from the bins would tie it to the stiffness it is collinear with
/// there.
fn jackknife_step(
    ctx: &DofContext<'_>,
    reg: &Regression,
    clusters_all: &[ClusterRows],
    coef: &[f64],
    support: &[bool],
    out: &mut Uncertainty,
) -> Option<usize> {
    let keep = &reg.keep[..];
    let sel: Vec<usize> = (0..keep.len())
        .filter(|&j| support[j] && Some(j) != reg.const_j)
        .collect();
    let fixed = reg.const_j.filter(|&cj| support[cj]);
    let (half, g, nus) = cluster_intervals(clusters_all, &sel, coef, fixed)?;
    for (k, &j) in sel.iter().enumerate() {
        out.intervals[j] = Some([coef[j] - half[k], coef[j] + half[k]]);
    }
    let m = ctx
        .shared
        .candidates
        .get(ctx.d)
        .copied()
        .unwrap_or(ctx.lib.len());
    let dofs = sel
        .iter()
        .zip(&nus)
        .map(|(&j, &nu)| (ctx.names[keep[j]].clone(), nu))
        .collect();
    out.term_test = Some(TermTest::new(m, (g - 1) as f64, dofs));
    Some(g)
}

/// The bootstrap over the clusters: each term's inclusion probability (written into `out`) at
/// the threshold at which STLSQ keeps exactly the model's terms on all the rows, and the trace's
/// sentence on how it was obtained (with the inclusion caveat, if any).
fn bootstrap_step(
    ctx: &DofContext<'_>,
    reg: &Regression,
    clusters_all: Vec<ClusterRows>,
    coef: &[f64],
    support: &[bool],
    thr: f64,
    out: &mut Uncertainty,
) -> Result<String> {
    let opt = &ctx.spec.tfs;
    let (keep, const_j) = (&reg.keep[..], reg.const_j);
    let n_parts = clusters_all.len();
    let parts = cluster_blocks(clusters_all)?;
    // The model's terms were picked on the first records of Criterion 4 and trimmed by the
    // term test, so `thr` need not give them on these rows: the resamples use the threshold at
    // which STLSQ on all of them does.
    let all_rows = Compressed::merge(&parts)?;
    let boot_thr = lambda_path(&all_rows, &all_rows, &path_opts(opt.fit.n_thresholds))
        .ok()
        .and_then(|p| threshold_for_support(&p, support, const_j));
    let s = bagging_with_total(
        &parts,
        &all_rows,
        &Stlsq {
            threshold: boot_thr.unwrap_or(thr),
            ..Stlsq::default()
        },
        &BagOptions {
            n_boot: opt.uncertainty.bagging,
            level: INTERVAL_LEVEL,
            seed: 1,
        },
    )?;
    for (inc, &p) in out.inclusion.iter_mut().zip(&s.inclusion) {
        *inc = Some(p);
    }
    if let Some(cj) = const_j {
        out.inclusion[cj] = None;
    }
    let scaled = Stlsq::default().initial_scaled_coef(&all_rows);
    let terms: Vec<CaveatTerm> = (0..keep.len())
        .filter(|&j| Some(j) != const_j)
        .map(|j| CaveatTerm {
            name: ctx.names[keep[j]].clone(),
            kept: support[j],
            significant: passes_term_test(ctx, reg, out, coef, j).unwrap_or(false),
            inclusion: out.inclusion[j].unwrap_or(1.0),
            scaled: scaled.get(j).copied().unwrap_or(0.0),
        })
        .collect();
    let caveat = inclusion_caveat(&terms, boot_thr.unwrap_or(thr)).unwrap_or_default();
    Ok(match boot_thr {
        Some(b) => format!(
            "inclusion = share of {} bootstrap resamples of the same {} clusters in which STLSQ keeps the term, at the threshold (scaled {b:.3}) at which it keeps exactly the model's terms on all of them{caveat}",
            opt.uncertainty.bagging, n_parts
        ),
        None => format!(
            "inclusion = share of {} bootstrap resamples of the same {} clusters in which STLSQ at the selection's threshold (scaled {thr:.3}) keeps the term; no threshold gives exactly the model's terms on all the clusters (they were picked on the first records of criterion 4 and trimmed by the term test){caveat}",
            opt.uncertainty.bagging, n_parts
        ),
    })
}

/// The trace's sentence on the intervals: how they were obtained from `groups` clusters (with
/// each term's effective degrees of freedom) or why there are none, then `inclusion_note`.
fn interval_note(
    groups: Option<usize>,
    term_test: Option<&TermTest>,
    inclusion_note: &str,
) -> String {
    match groups {
        Some(g) => format!(
            "coefficient intervals: {:.0}% (± t·SE), standard errors by a jackknife over {g} clusters of {CLUSTER_BINS} neighbouring bins of one window pair (each left out in turn), t on each coefficient's effective degrees of freedom ({}: how many clusters in effect pin it down, from the design); {inclusion_note}",
            100.0 * INTERVAL_LEVEL,
            term_test.map_or(String::new(), |t| t
                .interval_dof
                .iter()
                .map(|(n, v)| format!("{n} {v:.1}"))
                .collect::<Vec<_>>()
                .join(", ")),
        ),
        None => format!(
            "no coefficient intervals: too few independent clusters of bins; {inclusion_note}"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cluster count is the number of clusters formed, for every δ, over windows whose
    /// stored bins span several clusters, one with a single bin (no spacing) and one that
    /// keeps nothing.
    #[test]
    fn cluster_count_is_the_number_of_clusters_formed() {
        use crate::criterion3::rows::WindowTransform;
        use tfs_signal::Complex;
        let window = |bins: usize, f0: f64, seed: usize| {
            let amp: Vec<f64> = (0..bins)
                .map(|b| ((b * 7 + seed * 3) % 11) as f64 / 10.0)
                .collect();
            let max = amp.iter().cloned().fold(0.0, f64::max);
            WindowTransform {
                freq: (0..bins).map(|b| f0 + 0.05 * b as f64).collect(),
                rel_amp: amp.iter().map(|a| a / max.max(1e-300)).collect(),
                lhs: amp.iter().map(|&a| Complex::new(a, 0.5 * a)).collect(),
                cols: vec![(0..bins).map(|b| Complex::new(b as f64, 1.0)).collect(); 2],
                weight: vec![1.0; bins],
            }
        };
        let ws = [
            window(3 * CLUSTER_BINS + 5, 0.0, 1),
            window(2 * CLUSTER_BINS, 0.4, 2),
            window(1, 1.0, 3),
            window(CLUSTER_BINS, 0.2, 0),
        ];
        let rows: Vec<(usize, usize, &WindowTransform)> =
            ws.iter().enumerate().map(|(i, w)| (i / 2, i, w)).collect();
        for delta in [0.0, 0.3, 0.75, 1.0, 1.5] {
            let formed = bin_clusters(&rows, delta, &[0, 1]).len();
            assert_eq!(cluster_count(&rows, delta), formed, "δ = {delta}");
        }
        assert!(bin_clusters(&rows, 0.0, &[0, 1]).len() > 4);
    }

    /// Student's t quantiles (tabulated values) and the term test's Bonferroni level: with one
    /// candidate the test is the 95 % interval itself; with 36 it asks for about 3.2·SE on
    /// many degrees of freedom, and more on few.
    #[test]
    fn term_test_shares_five_percent_among_the_candidates() {
        assert!((student_t_quantile(10.0, 0.95) - 2.228).abs() < 1e-3);
        assert!((student_t_quantile(1e6, 0.95) - 1.960).abs() < 1e-3);
        assert!((student_t_quantile(30.0, 0.99) - 2.750).abs() < 1e-3);
        let none = std::collections::BTreeMap::new;
        let one = TermTest::new(1, 40.0, none());
        assert!(one.passes("x", 1.0, [0.0, 2.0]) && !one.passes("x", 0.99, [-0.01, 1.99]));
        let many = TermTest::new(36, 1e6, none());
        assert!((many.level - (1.0 - 0.05 / 36.0)).abs() < 1e-15);
        // z at 1 − 0.05/72 = 0.99931 is 3.20.
        assert!((many.t_critical - 3.20).abs() < 0.01, "{}", many.t_critical);
        assert!(TermTest::new(36, 20.0, none()).t_critical > many.t_critical);
        // A term 2.5 SE from 0 has a 95 % interval clear of 0 but fails the 36-term test.
        let iv = [2.5 - 1.96, 2.5 + 1.96];
        assert!(iv[0] > 0.0 && !many.passes("x", 2.5, iv) && many.margin("x", 2.5, iv) < 1.0);
        assert!(many.passes("x", 3.3, [3.3 - 1.96, 3.3 + 1.96]));
        // An interval on 4 degrees of freedom (t = 2.776) of the same half-width is the same
        // test on an SE smaller by 1.96/2.776: the term that failed now passes.
        let few = TermTest::new(36, 1e6, [("x".to_string(), 4.0)].into());
        let se_ratio =
            student_t_quantile(1e6, INTERVAL_LEVEL) / student_t_quantile(4.0, INTERVAL_LEVEL);
        assert!((few.margin("x", 2.5, iv) - many.margin("x", 2.5, iv) / se_ratio).abs() < 1e-12);
        assert!(few.passes("x", 2.5, iv) && !few.passes("x'", 2.5, iv));
    }

    /// Equal clusters give the effective degrees of freedom `C − 1`; otherwise they match the
    /// Satterthwaite degrees of freedom of the quadratic form `εᵀMε`, `M = Σ_g c_g c_gᵀ`,
    /// `c_g = (I − P)_{:,g} A_g G⁻¹ℓ`, built row by row from its definition, and unequal
    /// clusters give fewer.
    #[test]
    fn effective_dof_is_the_satterthwaite_dof_of_the_cluster_variance() {
        let eye = |s: f64| Mat::<f64>::from_fn(2, 2, |i, j| if i == j { s } else { 0.0 });
        let own: Vec<Mat<f64>> = (0..10).map(|_| eye(1.0)).collect();
        for nu in effective_dof(&eye(10.0), &own) {
            assert!((nu - 9.0).abs() < 1e-9, "{nu}");
        }
        // 6 clusters of 4 rows, 3 columns, one cluster with 30× larger rows.
        let (c, per, k) = (6, 4, 3);
        let n = c * per;
        let a = Mat::<f64>::from_fn(n, k, |i, j| {
            let v = ((i * 7 + j * 13) % 11) as f64 - 5.0 + 0.3 * j as f64;
            if i < per { 30.0 * v } else { v }
        });
        let gram = a.transpose() * &a;
        let own: Vec<Mat<f64>> = (0..c)
            .map(|g| {
                let ag = a.subrows(g * per, per);
                ag.transpose() * ag
            })
            .collect();
        let nus = effective_dof(&gram, &own);
        use faer::linalg::solvers::DenseSolveCore;
        let ginv = gram.as_ref().llt(faer::Side::Lower).unwrap().inverse();
        let proj = &a * &ginv * a.transpose();
        for (p, nu) in nus.iter().enumerate() {
            let l = Mat::<f64>::from_fn(k, 1, |i, _| f64::from(u8::from(i == p)));
            let w = &a * &ginv * &l;
            let mut m = Mat::<f64>::zeros(n, n);
            for g in 0..c {
                let cg = Mat::<f64>::from_fn(n, 1, |i, _| {
                    (g * per..(g + 1) * per)
                        .map(|r| (f64::from(u8::from(i == r)) - proj[(i, r)]) * w[(r, 0)])
                        .sum()
                });
                m += &cg * cg.transpose();
            }
            let tr: f64 = (0..n).map(|i| m[(i, i)]).sum();
            let m2 = &m * &m;
            let tr2: f64 = (0..n).map(|i| m2[(i, i)]).sum();
            let want = (tr * tr / tr2).clamp(1.0, c as f64 - 1.0);
            assert!(
                (nu - want).abs() < 1e-8 * want,
                "coefficient {p}: {nu} against {want}"
            );
            assert!(*nu < c as f64 - 1.5, "coefficient {p}: {nu}");
        }
    }

    /// The caveat names each kept, significant term of low inclusion and the nearest rival left
    /// out; it stays silent when the low-inclusion term is not significant or not kept.
    #[test]
    fn inclusion_caveat_names_significant_terms_near_the_cut() {
        let t = |name: &str, kept, significant, inclusion, scaled| CaveatTerm {
            name: name.into(),
            kept,
            significant,
            inclusion,
            scaled,
        };
        let terms = [
            t("x^4", false, false, 0.27, 0.65),
            t("x^2", false, false, 0.0, -0.11),
            t("x^5", true, true, 1.0, -13.4),
            t("x'", true, true, 0.49, -0.76),
        ];
        let c = inclusion_caveat(&terms, 0.73).expect("a caveat");
        assert!(c.contains("x' (0.49; scaled size 0.76)"), "{c}");
        assert!(c.contains("x^4, has scaled size 0.65"), "{c}");
        assert!(!c.contains("x^5 ("), "{c}");
        let mut quiet = terms;
        quiet[3].significant = false;
        assert!(inclusion_caveat(&quiet, 0.73).is_none());
        quiet[3].significant = true;
        quiet[3].inclusion = 0.95;
        assert!(inclusion_caveat(&quiet, 0.73).is_none());
    }
}
