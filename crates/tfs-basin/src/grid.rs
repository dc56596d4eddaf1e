//! Basin-of-attraction grids: configuration, labels, the map type and the S-DOF grid driver.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tfs_dynamics::SecondOrderSystem;

use crate::error::{Result, invalid};
use crate::lanes::Run;
use crate::scalar::{LANES, run_row};
use crate::wells::WellInfo;

/// How often (in steps) the trapping test runs. Trapping is permanent, so testing every few
/// steps only delays the exit by at most this many steps.
pub(crate) const CHECK_EVERY: usize = 4;
/// A trajectory whose displacement exceeds this multiple of the grid's extent is `Diverged`.
const BLOWUP_FACTOR: f64 = 1e6;
/// Most RK4 steps a map may ask for (every start run to `t_max`): about two minutes of one
/// core's work in the SIMD blocks; more is refused by [`BasinConfig::validate`].
pub const MAX_STEPS: f64 = 1e11;
/// Most cells a map may have (5000 × 5000).
pub const MAX_CELLS: usize = 25_000_000;

/// Where one initial condition ends up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Label {
    /// Settles in the stable state with this index (into `WellInfo::stable()` or the chain's list).
    State(usize),
    /// Not provably settled by `t_max`.
    Unsettled,
    /// The state became non-finite or huge.
    Diverged,
}

/// How the starts of a map are integrated. Every method integrates a start with the same
/// fixed-step RK4 arithmetic and the same trapping test, so a start that is integrated gets the
/// same label from all three; they differ in which starts are integrated and how fast.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Method {
    /// Coarse-to-fine (the default): a lattice every 8th node (fewer on small grids), then at
    /// each finer level only the starts whose surroundings disagree (in end state or in the
    /// number of well crossings on the way) are integrated; the rest take the shared label.
    /// Starts run in SIMD blocks (see [`Method::EveryCell`]).
    #[default]
    Refined,
    /// Every start integrated, sixteen side by side in SIMD lanes, in parallel tasks.
    EveryCell,
    /// Every start integrated, one scalar model call per start and stage, rows in parallel:
    /// the original path, kept as the baseline of the benchmark.
    Scalar,
}

/// Grid and integration settings shared by every basin computation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BasinConfig {
    /// Number of grid nodes along the first axis (x0, or the slice's first coordinate); ≥ 2.
    pub nx: usize,
    /// Number of grid nodes along the second axis (v0, or the slice's second coordinate); ≥ 2.
    pub ny: usize,
    /// Range of the first axis; nodes include both ends.
    pub x_range: (f64, f64),
    /// Range of the second axis; nodes include both ends.
    pub v_range: (f64, f64),
    /// Fixed RK4 step. For the Table 1 model 0.01–0.02 is converged; check with [`dt_convergence`].
    pub dt: f64,
    /// Time cap; a start not provably settled by then is [`Label::Unsettled`].
    pub t_max: f64,
    /// Stop a trajectory as soon as it is provably trapped in a well.
    pub early_exit: bool,
    /// Parallelise with rayon (results do not depend on it).
    pub parallel: bool,
    /// Which starts are integrated and how (see [`Method`]).
    #[serde(default)]
    pub method: Method,
}

impl BasinConfig {
    /// A configuration with `dt = 0.01`, `t_max = 100`, early exit and parallelism on.
    pub fn new(nx: usize, ny: usize, x_range: (f64, f64), v_range: (f64, f64)) -> Self {
        Self {
            nx,
            ny,
            x_range,
            v_range,
            dt: 0.01,
            t_max: 100.0,
            early_exit: true,
            parallel: true,
            method: Method::Refined,
        }
    }

    /// Checks every field; the numerics only see a validated configuration.
    pub fn validate(&self) -> Result<()> {
        if self.nx < 2 || self.ny < 2 {
            return Err(invalid(
                "nx/ny",
                format!(
                    "grid {}×{} is too small: need at least 2 nodes per axis",
                    self.nx, self.ny
                ),
            ));
        }
        if self.nx.checked_mul(self.ny).is_none_or(|c| c > MAX_CELLS) {
            return Err(invalid(
                "nx/ny",
                format!(
                    "grid {}×{} has more than {MAX_CELLS} cells; use a smaller grid or a narrower range",
                    self.nx, self.ny
                ),
            ));
        }
        for (name, (a, b)) in [("x_range", self.x_range), ("v_range", self.v_range)] {
            if !(a.is_finite() && b.is_finite() && a < b) {
                return Err(invalid(
                    name,
                    format!("({a}, {b}) must be finite with lower < upper"),
                ));
            }
        }
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(invalid(
                "dt",
                format!("{} must be finite and positive", self.dt),
            ));
        }
        if !(self.t_max.is_finite() && self.t_max >= self.dt) {
            return Err(invalid(
                "t_max",
                format!(
                    "{} must be finite and at least dt = {}",
                    self.t_max, self.dt
                ),
            ));
        }
        let per_start = (self.t_max / self.dt).ceil();
        let cells = (self.nx as f64) * (self.ny as f64);
        if per_start * cells > MAX_STEPS {
            return Err(invalid(
                "dt",
                format!(
                    "dt = {} with t_max = {} asks up to {:.3e} RK4 steps per start, {:.3e} for the {}×{} grid, \
                     above the limit of {MAX_STEPS:.0e}; use dt ≥ {:.3e}, a shorter t_max or a smaller grid",
                    self.dt,
                    self.t_max,
                    per_start,
                    per_start * cells,
                    self.nx,
                    self.ny,
                    self.t_max * cells / MAX_STEPS
                ),
            ));
        }
        Ok(())
    }

    /// Worst-case RK4 steps of the whole map (every start run to `t_max`).
    pub fn max_total_steps(&self) -> f64 {
        (self.t_max / self.dt).ceil() * (self.nx as f64) * (self.ny as f64)
    }

    /// Number of RK4 steps to reach `t_max`.
    pub(crate) fn steps(&self) -> usize {
        (self.t_max / self.dt).ceil() as usize
    }
    /// Value of the first axis at node `i`.
    pub fn x_at(&self, i: usize) -> f64 {
        node(self.x_range, self.nx, i)
    }
    /// Value of the second axis at node `j`.
    pub fn v_at(&self, j: usize) -> f64 {
        node(self.v_range, self.ny, j)
    }
}

fn node((a, b): (f64, f64), n: usize, i: usize) -> f64 {
    if i + 1 == n {
        b
    } else {
        a + (b - a) * i as f64 / (n - 1) as f64
    }
}

/// A labelled grid of initial conditions, row-major: `labels[j * nx + i]` is the start at
/// first-axis node `i` and second-axis node `j` (rows run along the first axis).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BasinMap {
    /// One label per grid node, row-major over the second axis.
    pub labels: Vec<Label>,
    /// Nodes along the first axis.
    pub nx: usize,
    /// Nodes along the second axis.
    pub ny: usize,
    /// Range of the first axis (x0 for S-DOF maps).
    pub x_range: (f64, f64),
    /// Range of the second axis (v0 for S-DOF maps).
    pub y_range: (f64, f64),
    /// Name of the first axis, for plots.
    pub x_name: String,
    /// Name of the second axis, for plots.
    pub y_name: String,
    /// Positions of the stable states that `Label::State(k)` refers to.
    pub states: Vec<Vec<f64>>,
    /// Share of cells in each stable state's basin (same order as `states`).
    pub shares: Vec<f64>,
    /// Cells labelled [`Label::Unsettled`].
    pub unsettled_count: usize,
    /// Cells labelled [`Label::Diverged`].
    pub diverged_count: usize,
    /// Wall-clock seconds the computation took.
    pub seconds: f64,
    /// Starts integrated (all of them unless [`Method::Refined`] filled some from agreeing
    /// neighbours).
    #[serde(default)]
    pub integrated: usize,
}

impl BasinMap {
    /// Label of the node `(i, j)`.
    pub fn label(&self, i: usize, j: usize) -> Label {
        self.labels[j * self.nx + i]
    }
    /// First-axis value at node `i`.
    pub fn x_at(&self, i: usize) -> f64 {
        node(self.x_range, self.nx, i)
    }
    /// Second-axis value at node `j`.
    pub fn y_at(&self, j: usize) -> f64 {
        node(self.y_range, self.ny, j)
    }

    pub(crate) fn assemble(
        (labels, integrated): (Vec<Label>, usize),
        cfg: &BasinConfig,
        names: (&str, &str),
        states: Vec<Vec<f64>>,
        seconds: f64,
    ) -> Self {
        let mut counts = vec![0usize; states.len()];
        let (mut unsettled, mut diverged) = (0, 0);
        for l in &labels {
            match *l {
                Label::State(k) => counts[k] += 1,
                Label::Unsettled => unsettled += 1,
                Label::Diverged => diverged += 1,
            }
        }
        let total = labels.len() as f64;
        Self {
            nx: cfg.nx,
            ny: cfg.ny,
            x_range: cfg.x_range,
            y_range: cfg.v_range,
            x_name: names.0.to_string(),
            y_name: names.1.to_string(),
            shares: counts.iter().map(|&c| c as f64 / total).collect(),
            states,
            unsettled_count: unsettled,
            diverged_count: diverged,
            labels,
            seconds,
            integrated,
        }
    }
}

/// Optional progress callback: called now and then with the number of grid cells labelled so
/// far (out of `nx · ny`; integrated or, with [`Method::Refined`], filled).
pub type Progress<'a> = Option<&'a (dyn Fn(usize) + Sync)>;

/// Decides the label of a trajectory from its current state.
pub(crate) trait Judge: Sync {
    /// The state index if `(x, v)` is provably trapped (final label).
    fn trapped(&self, x: &[f64], v: &[f64]) -> Option<usize>;
    /// Whether the early-exit test may be used.
    fn early(&self) -> bool;
    /// Blow-up bound: a displacement component at or beyond it (or a non-finite state) is
    /// `Diverged`.
    fn limit(&self) -> f64;
    /// Whether the state has blown up.
    fn blown(&self, x: &[f64], v: &[f64]) -> bool {
        let lim = self.limit();
        !(x.iter().all(|c| c.abs() < lim) && v.iter().all(|c| c.is_finite()))
    }
    /// Label of a trajectory that reached `t_max`.
    fn at_cap(&self, x: &[f64], v: &[f64]) -> Label;
    /// Which region of the state space `x` is in (a well, or the nearest stable state): the
    /// number of changes along a trajectory tells routes to the same state apart.
    fn region(&self, x: &[f64]) -> u32;
}

/// Labels every grid node by `cfg.method` and counts the starts integrated;
/// `start(i, j, x, v)` writes the start of node `(i, j)`. Each integrated start's label depends only on that start, and what is integrated
/// depends only on labels, so the map is independent of the thread count.
pub(crate) fn run_grid<S, J, F>(
    sys: &S,
    judge: &J,
    cfg: &BasinConfig,
    progress: Progress<'_>,
    start: F,
) -> (Vec<Label>, usize)
where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
    F: Fn(usize, usize, &mut [f64], &mut [f64]) + Sync,
{
    let (nx, ny) = (cfg.nx, cfg.ny);
    let all = nx * ny;
    let done = AtomicUsize::new(0);
    let report = |n: usize| {
        if let Some(cb) = progress {
            cb(n);
        }
    };
    if cfg.method == Method::Scalar {
        let mut labels = vec![Label::Unsettled; nx * ny];
        let row = |(j, out): (usize, &mut [Label])| {
            run_row(sys, judge, cfg, LANES, |i, x, v| start(i, j, x, v), out);
            report((done.fetch_add(1, Ordering::Relaxed) + 1) * nx);
        };
        if cfg.parallel {
            labels.par_chunks_mut(nx).enumerate().for_each(row);
        } else {
            labels.chunks_mut(nx).enumerate().for_each(row);
        }
        return (labels, all);
    }
    let run = lanes_run(sys, judge, cfg);
    let at = |c: usize, x: &mut [f64], v: &mut [f64]| start(c % nx, c / nx, x, v);
    // Cells finished before this batch, plus those of this batch as its tasks finish.
    let base = AtomicUsize::new(0);
    let tick =
        |n: usize| report(base.load(Ordering::Relaxed) + done.fetch_add(n, Ordering::Relaxed) + n);
    let mut compute = |cells: &[usize]| {
        done.store(0, Ordering::Relaxed);
        run.cells(cells, cfg.parallel, &at, &tick)
    };
    if cfg.method == Method::EveryCell {
        let cells: Vec<usize> = (0..all).collect();
        return (compute(&cells).into_iter().map(|o| o.label).collect(), all);
    }
    let step = crate::refine::coarse_step(nx, ny);
    let resolved = |n: usize| {
        base.store(n, Ordering::Relaxed);
        report(n);
    };
    let (labels, work) = crate::refine::coarse_to_fine(nx, ny, step, &mut compute, &resolved);
    (labels, work.integrated)
}

/// The SIMD-block run of `cfg`'s step, horizon and early exit.
pub(crate) fn lanes_run<'a, S, J>(sys: &'a S, judge: &'a J, cfg: &BasinConfig) -> Run<'a, S, J>
where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
{
    Run {
        sys,
        judge,
        h: cfg.dt,
        max_steps: cfg.steps(),
        early: cfg.early_exit && judge.early(),
    }
}

/// Labels one start as a lone scalar trajectory: the label a SIMD lane gives it (same
/// arithmetic, tested), without a block's set-up and its idle lanes, which made a lone start
/// in a block 2.5× slower (the MED search classifies thousands of lone starts).
pub(crate) fn classify_one<S, J>(
    sys: &S,
    judge: &J,
    cfg: &BasinConfig,
    start: &dyn Fn(&mut [f64], &mut [f64]),
) -> Label
where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
{
    let mut out = [Label::Unsettled];
    run_row(sys, judge, cfg, 1, |_, x, v| start(x, v), &mut out);
    out[0]
}

/// The S-DOF judge: wells, a blow-up limit, and for each well the kinetic energy above which a
/// state in it cannot be trapped (a cheap test that spares most potential evaluations).
pub(crate) struct SdofJudge<'a> {
    pub(crate) wells: &'a WellInfo,
    pub(crate) limit: f64,
    /// Per well: 1.5 × (barrier − V(bottom)). The potential is at least V(bottom) in the well,
    /// so a kinetic energy above the depth already puts the energy over the barrier; the factor
    /// 1.5 keeps the shortcut clear of rounding, so it never changes a label.
    kinetic_cut: Vec<f64>,
}

impl<'a> SdofJudge<'a> {
    pub(crate) fn new(wells: &'a WellInfo, cfg: &BasinConfig) -> Self {
        let (slo, shi) = wells.search();
        let limit = BLOWUP_FACTOR
            * [slo, shi, cfg.x_range.0, cfg.x_range.1]
                .iter()
                .fold(1.0f64, |m, a| m.max(a.abs()));
        let kinetic_cut = wells
            .wells()
            .iter()
            .map(|w| 1.5 * (w.barrier - wells.potential(w.bottom)).max(0.0))
            .collect();
        Self {
            wells,
            limit,
            kinetic_cut,
        }
    }
}

impl Judge for SdofJudge<'_> {
    #[inline]
    fn trapped(&self, x: &[f64], v: &[f64]) -> Option<usize> {
        let k = self.wells.well_of(x[0])?;
        if 0.5 * self.wells.mass() * v[0] * v[0] > self.kinetic_cut[k] {
            return None;
        }
        self.wells.trapped(x[0], v[0])
    }
    fn early(&self) -> bool {
        true
    }
    fn limit(&self) -> f64 {
        self.limit
    }
    fn at_cap(&self, x: &[f64], v: &[f64]) -> Label {
        self.wells
            .trapped(x[0], v[0])
            .map_or(Label::Unsettled, Label::State)
    }
    fn region(&self, x: &[f64]) -> u32 {
        self.wells.unstable().iter().filter(|&&u| u < x[0]).count() as u32
    }
}

/// Integrates the unforced `sys` from `(x0, v0)` and labels where it ends (S-DOF).
///
/// With `cfg.early_exit` the run stops once the state is inside a well with energy below that
/// well's barrier (final, since damping only removes energy; tested every 4 steps). Otherwise it
/// runs to `t_max` and applies the same test to the final state. Either way a start never
/// proven trapped is `Unsettled`; a state beyond 10⁶ × the grid/search extent or non-finite is
/// `Diverged`. Gives exactly the label [`basin_sdof`] gives the same start when it integrates it
/// (every start with [`Method::EveryCell`] or [`Method::Scalar`]).
pub fn classify_sdof<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    x0: f64,
    v0: f64,
    cfg: &BasinConfig,
) -> Label {
    let cfg = &memory_config(sys, cfg);
    let judge = SdofJudge::new(wells, cfg);
    classify_one(sys, &judge, cfg, &|x, v| sdof_start(x, v, x0, v0))
}

/// The start of an S-DOF run: `(x0, v0)`, and every internal state of the system (the
/// coordinates after the first, [`SecondOrderSystem::internal_states`]) at rest.
fn sdof_start(x: &mut [f64], v: &mut [f64], x0: f64, v0: f64) {
    x.fill(0.0);
    v.fill(0.0);
    x[0] = x0;
    v[0] = v0;
}

/// `cfg`, without the early exit for a system with internal states: its energy is not that of
/// the wells' potential (a hysteretic element stores and returns energy), so being below a
/// barrier proves nothing; such runs go to `t_max`.
fn memory_config<S: SecondOrderSystem + ?Sized>(sys: &S, cfg: &BasinConfig) -> BasinConfig {
    let mut c = cfg.clone();
    if sys.internal_states() > 0 {
        c.early_exit = false;
    }
    c
}

/// Basin map of a 1-DOF system over `(x0, v0)` (see [`classify_sdof`] for each start and
/// [`Method`] for which starts are integrated).
///
/// With `early_exit` the system is first checked to be dissipative for the wells' potential on
/// a coarse grid (error otherwise). A step `dt` too long for RK4 to be stable on the states the
/// grid can reach is refused (see [`crate::step_limit_sdof`]). `progress` is called with the
/// number of cells labelled so far.
pub fn basin_sdof<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    cfg: &BasinConfig,
    progress: Progress<'_>,
) -> Result<BasinMap> {
    cfg.validate()?;
    if sys.dofs() - sys.internal_states() != 1 {
        return Err(invalid(
            "sys",
            format!(
                "basin_sdof needs a 1-DOF system, got {} DOFs; use basin_chain",
                sys.dofs() - sys.internal_states()
            ),
        ));
    }
    let cfg = &memory_config(sys, cfg);
    if cfg.early_exit {
        wells.check_dissipative(sys, cfg.x_range, cfg.v_range, 41)?;
    }
    crate::limits::step_limit_sdof(sys, wells, cfg)?.check(cfg.dt)?;
    let start = Instant::now();
    let judge = SdofJudge::new(wells, cfg);
    let labels = run_grid(sys, &judge, cfg, progress, |i, j, x, v| {
        sdof_start(x, v, cfg.x_at(i), cfg.v_at(j))
    });
    let states = wells.stable().iter().map(|&s| vec![s]).collect();
    Ok(BasinMap::assemble(
        labels,
        cfg,
        ("x0", "v0"),
        states,
        start.elapsed().as_secs_f64(),
    ))
}

/// Step-size convergence check: the BOA error between maps computed with `cfg.dt` and
/// `cfg.dt / 2` (same grid). A value near zero means the step is small enough.
pub fn dt_convergence<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    cfg: &BasinConfig,
) -> Result<f64> {
    let coarse = basin_sdof(sys, wells, cfg, None)?;
    let mut fine_cfg = cfg.clone();
    fine_cfg.dt = cfg.dt / 2.0;
    let fine = basin_sdof(sys, wells, &fine_cfg, None)?;
    crate::compare::boa_error(&coarse, &fine)
}
