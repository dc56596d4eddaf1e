//! Basin-of-attraction grids: configuration, labels, the map type and the S-DOF grid driver.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tfs_dynamics::{Rk4Scratch, SecondOrderSystem, rk4_step};

use crate::error::{Result, invalid};
use crate::wells::WellInfo;

/// How often (in steps) the trapping test runs. Trapping is permanent, so testing every few
/// steps only delays the exit by at most this many steps.
pub(crate) const CHECK_EVERY: usize = 4;
/// A trajectory whose displacement exceeds this multiple of the grid's extent is `Diverged`.
const BLOWUP_FACTOR: f64 = 1e6;

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
    /// Parallelise over grid rows with rayon (results do not depend on it).
    pub parallel: bool,
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
        self.nx
            .checked_mul(self.ny)
            .ok_or_else(|| invalid("nx/ny", "grid size overflows; use a smaller grid"))?;
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
        Ok(())
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
        labels: Vec<Label>,
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
        }
    }
}

/// Optional per-row progress callback: called with the number of rows finished so far.
pub type Progress<'a> = Option<&'a (dyn Fn(usize) + Sync)>;

/// Independent trajectories integrated side by side in one row (instruction-level parallelism;
/// each lane's arithmetic is exactly that of a lone trajectory).
const LANES: usize = 8;

/// Decides the label of a trajectory from its current state.
pub(crate) trait Judge: Sync {
    /// The state index if `(x, v)` is provably trapped (final label).
    fn trapped(&self, x: &[f64], v: &[f64]) -> Option<usize>;
    /// Whether the early-exit test may be used.
    fn early(&self) -> bool;
    /// Whether the state has blown up.
    fn blown(&self, x: &[f64], v: &[f64]) -> bool;
    /// Label of a trajectory that reached `t_max`.
    fn at_cap(&self, x: &[f64], v: &[f64]) -> Label;
}

/// `LANES` copies of a `d`-DOF system side by side: lane `l` owns components `l·d .. (l+1)·d`.
struct Lanes<'a, S: ?Sized> {
    sys: &'a S,
    d: usize,
    k: usize,
}

impl<S: SecondOrderSystem + ?Sized> SecondOrderSystem for Lanes<'_, S> {
    fn dofs(&self) -> usize {
        self.d * self.k
    }
    fn inputs(&self) -> usize {
        self.sys.inputs()
    }
    #[inline]
    fn accel(&self, t: f64, x: &[f64], v: &[f64], u: &[f64], a: &mut [f64]) {
        let d = self.d;
        for ((xl, vl), al) in x
            .chunks_exact(d)
            .zip(v.chunks_exact(d))
            .zip(a.chunks_exact_mut(d))
        {
            self.sys.accel(t, xl, vl, u, al);
        }
    }
}

/// Labels the `out.len()` starts written by `start(i, x, v)`, integrating up to `lanes` of them
/// at once with [`rk4_step`] (zero input; the unforced dynamics are treated as autonomous and
/// `t = 0` is passed). Each start's label depends only on that start.
pub(crate) fn run_row<S, J, F>(
    sys: &S,
    judge: &J,
    cfg: &BasinConfig,
    lanes: usize,
    start: F,
    out: &mut [Label],
) where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
    F: Fn(usize, &mut [f64], &mut [f64]),
{
    let d = sys.dofs();
    if out.is_empty() {
        return;
    }
    let k = lanes.clamp(1, out.len());
    let multi = Lanes { sys, d, k };
    let mut scratch = Rk4Scratch::new(d * k);
    let u = vec![0.0; sys.inputs()];
    let (mut x, mut v) = (vec![0.0; d * k], vec![0.0; d * k]);
    let mut cell: Vec<Option<usize>> = vec![None; k];
    let mut steps = vec![0usize; k];
    let mut next = 0usize;
    let max_steps = cfg.steps();
    let early = cfg.early_exit && judge.early();
    let h = cfg.dt;
    // Fill every lane (k ≤ out.len(), so every lane gets a start).
    for (l, c) in cell.iter_mut().enumerate() {
        let r = l * d..(l + 1) * d;
        start(next, &mut x[r.clone()], &mut v[r]);
        *c = Some(next);
        next += 1;
    }
    loop {
        let mut active = false;
        for l in 0..k {
            let r = l * d..(l + 1) * d;
            while let Some(c) = cell[l] {
                let label = if early && steps[l] % CHECK_EVERY == 0 {
                    judge
                        .trapped(&x[r.clone()], &v[r.clone()])
                        .map(Label::State)
                } else {
                    None
                };
                let label = match label {
                    Some(lab) => Some(lab),
                    None if steps[l] >= max_steps => {
                        Some(judge.at_cap(&x[r.clone()], &v[r.clone()]))
                    }
                    None => None,
                };
                let Some(label) = label else {
                    active = true;
                    break;
                };
                out[c] = label;
                cell[l] = None;
                if next < out.len() {
                    start(next, &mut x[r.clone()], &mut v[r.clone()]);
                    cell[l] = Some(next);
                    steps[l] = 0;
                    next += 1;
                }
            }
        }
        if !active {
            break;
        }
        rk4_step(&multi, 0.0, h, &mut x, &mut v, &u, &u, &u, &mut scratch);
        for l in 0..k {
            if let Some(c) = cell[l] {
                steps[l] += 1;
                let r = l * d..(l + 1) * d;
                if judge.blown(&x[r.clone()], &v[r.clone()]) {
                    out[c] = Label::Diverged;
                    // Restart the lane from a finite state: the next cell, or lane-idle.
                    cell[l] = None;
                    if next < out.len() {
                        start(next, &mut x[r.clone()], &mut v[r]);
                        cell[l] = Some(next);
                        steps[l] = 0;
                        next += 1;
                    } else {
                        x[r.clone()].fill(0.0);
                        v[r].fill(0.0);
                    }
                }
            }
        }
    }
}

/// Runs every grid row through [`run_row`], rows in parallel when asked, collected in order.
/// Each cell's result depends only on its start, so the map is independent of the thread count.
pub(crate) fn run_grid<S, J, F>(
    sys: &S,
    judge: &J,
    cfg: &BasinConfig,
    progress: Progress<'_>,
    start: F,
) -> Vec<Label>
where
    S: SecondOrderSystem + ?Sized,
    J: Judge + ?Sized,
    F: Fn(usize, usize, &mut [f64], &mut [f64]) + Sync,
{
    let mut labels = vec![Label::Unsettled; cfg.nx * cfg.ny];
    let done = AtomicUsize::new(0);
    let row = |(j, out): (usize, &mut [Label])| {
        run_row(sys, judge, cfg, LANES, |i, x, v| start(i, j, x, v), out);
        let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
        if let Some(cb) = progress {
            cb(finished);
        }
    };
    if cfg.parallel {
        labels.par_chunks_mut(cfg.nx).enumerate().for_each(row);
    } else {
        labels.chunks_mut(cfg.nx).enumerate().for_each(row);
    }
    labels
}

/// The S-DOF judge: wells and a blow-up limit.
pub(crate) struct SdofJudge<'a> {
    pub(crate) wells: &'a WellInfo,
    pub(crate) limit: f64,
}

impl<'a> SdofJudge<'a> {
    pub(crate) fn new(wells: &'a WellInfo, cfg: &BasinConfig) -> Self {
        let (slo, shi) = wells.search();
        let limit = BLOWUP_FACTOR
            * [slo, shi, cfg.x_range.0, cfg.x_range.1]
                .iter()
                .fold(1.0f64, |m, a| m.max(a.abs()));
        Self { wells, limit }
    }
}

impl Judge for SdofJudge<'_> {
    #[inline]
    fn trapped(&self, x: &[f64], v: &[f64]) -> Option<usize> {
        self.wells.trapped(x[0], v[0])
    }
    fn early(&self) -> bool {
        true
    }
    #[inline]
    fn blown(&self, x: &[f64], v: &[f64]) -> bool {
        !(x[0].abs() < self.limit && v[0].is_finite())
    }
    fn at_cap(&self, x: &[f64], v: &[f64]) -> Label {
        self.wells
            .trapped(x[0], v[0])
            .map_or(Label::Unsettled, Label::State)
    }
}

/// Integrates the unforced `sys` from `(x0, v0)` and labels where it ends (S-DOF).
///
/// With `cfg.early_exit` the run stops once the state is inside a well with energy below that
/// well's barrier (final, since damping only removes energy; tested every 4 steps). Otherwise it
/// runs to `t_max` and applies the same test to the final state. Either way a start never
/// proven trapped is `Unsettled`; a state beyond 10⁶ × the grid/search extent or non-finite is
/// `Diverged`. Gives exactly the label [`basin_sdof`] gives the same start.
pub fn classify_sdof<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    x0: f64,
    v0: f64,
    cfg: &BasinConfig,
) -> Label {
    let judge = SdofJudge::new(wells, cfg);
    let mut out = [Label::Unsettled];
    run_row(
        sys,
        &judge,
        cfg,
        1,
        |_, x, v| {
            x[0] = x0;
            v[0] = v0;
        },
        &mut out,
    );
    out[0]
}

/// Basin map of a 1-DOF system over `(x0, v0)` (see [`classify_sdof`] for each cell).
///
/// With `early_exit` the system is first checked to be dissipative for the wells' potential on
/// a coarse grid (error otherwise). `progress` is called after every finished row.
pub fn basin_sdof<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &WellInfo,
    cfg: &BasinConfig,
    progress: Progress<'_>,
) -> Result<BasinMap> {
    cfg.validate()?;
    if sys.dofs() != 1 {
        return Err(invalid(
            "sys",
            format!(
                "basin_sdof needs a 1-DOF system, got {} DOFs; use basin_chain",
                sys.dofs()
            ),
        ));
    }
    if cfg.early_exit {
        wells.check_dissipative(sys, cfg.x_range, cfg.v_range, 41)?;
    }
    let start = Instant::now();
    let judge = SdofJudge::new(wells, cfg);
    let labels = run_grid(sys, &judge, cfg, progress, |i, j, x, v| {
        x[0] = cfg.x_at(i);
        v[0] = cfg.v_at(j);
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
