//! Basins of chains (multi-DOF): stable states given by the caller, 2-D slices of the state
//! space, classification by the nearest stable state with an energy trapping test.

use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use tfs_dynamics::SecondOrderSystem;

use crate::error::{Result, invalid};
use crate::grid::{BasinConfig, BasinMap, Judge, Label, Progress, classify_one, run_grid};

/// A shared potential `V(x)` of a chain's displacements.
pub type VectorFn = Arc<dyn Fn(&[f64]) -> f64 + Send + Sync>;

/// Relative safety margin subtracted from the caller's barrier.
const BARRIER_MARGIN: f64 = 1e-6;

/// Stable states, masses, potential and barrier of a chain.
///
/// Trapping test (used for early exit and for the final label): the total energy
/// `Σ ½ m_i v_i² + V(x)` is below `barrier` (the lowest saddle energy, minus a tiny margin) and
/// the displacement is within `capture_radius` of the nearest stable state. Below the lowest
/// saddle the energy sublevel set splits into one component per minimum and the trajectory can
/// never leave its component; the capture radius (default: a quarter of the smallest distance
/// between stable states) identifies which component. This is exact when the balls of that
/// radius around each minimum lie inside their own components — true for the Kresling chains
/// and for ordinary landscapes, but not proven in general (document any exotic use).
///
/// The energy argument needs non-negative damping; unlike the S-DOF path (which checks it), the
/// chain path trusts the caller here (set `early_exit = false` if unsure).
///
/// Without a barrier (`None`) there is no energy proof: a start is labelled only if at `t_max`
/// it is within the capture radius of a stable state with kinetic energy below 1e-9 of the
/// state's depth scale (`|V|` at the states, at least 1e-12); early exit is then disabled.
#[derive(Clone)]
pub struct ChainWells {
    stable: Vec<Vec<f64>>,
    masses: Vec<f64>,
    potential: VectorFn,
    barrier: Option<f64>,
    barrier_raw: Option<f64>,
    capture_radius: f64,
}

impl std::fmt::Debug for ChainWells {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ChainWells")
            .field("stable", &self.stable)
            .field("masses", &self.masses)
            .field("barrier", &self.barrier)
            .field("capture_radius", &self.capture_radius)
            .finish()
    }
}

impl ChainWells {
    /// Builds the chain description. `stable` are the stable displacement vectors (labels index
    /// this list), `masses` one per DOF, `potential` the total potential `Σ V_i`, `barrier` the
    /// lowest saddle energy on the same scale as `potential` (see [`ChainWells::barrier_from_saddles`]).
    pub fn new(
        stable: Vec<Vec<f64>>,
        masses: Vec<f64>,
        potential: impl Fn(&[f64]) -> f64 + Send + Sync + 'static,
        barrier: Option<f64>,
    ) -> Result<Self> {
        let n = masses.len();
        if n == 0 {
            return Err(invalid("masses", "need one mass per degree of freedom"));
        }
        if let Some(m) = masses.iter().find(|m| !(m.is_finite() && **m > 0.0)) {
            return Err(invalid(
                "masses",
                format!("{m} must be finite and positive"),
            ));
        }
        if stable.is_empty() {
            return Err(invalid("stable", "need at least one stable state"));
        }
        for (k, s) in stable.iter().enumerate() {
            if s.len() != n || s.iter().any(|c| !c.is_finite()) {
                return Err(invalid(
                    "stable",
                    format!("state {k} must have {n} finite components (one per mass), got {s:?}"),
                ));
            }
        }
        if let Some(b) = barrier {
            if !b.is_finite() {
                return Err(invalid("barrier", "must be finite"));
            }
        }
        let mut dmin = f64::INFINITY;
        for a in 0..stable.len() {
            for b in a + 1..stable.len() {
                dmin = dmin.min(dist(&stable[a], &stable[b]));
            }
        }
        if dmin == 0.0 {
            return Err(invalid("stable", "two stable states coincide"));
        }
        let capture_radius = if dmin.is_finite() { 0.25 * dmin } else { 1.0 };
        let potential: VectorFn = Arc::new(potential);
        let barrier_raw = barrier;
        let barrier = barrier.map(|b| {
            let floor = stable
                .iter()
                .map(|s| potential(s))
                .fold(f64::INFINITY, f64::min);
            b - BARRIER_MARGIN * (b - floor).abs().max(f64::MIN_POSITIVE)
        });
        Ok(Self {
            stable,
            masses,
            potential,
            barrier,
            barrier_raw,
            capture_radius,
        })
    }

    /// The lowest potential energy among the given saddle points (unstable equilibria): use as
    /// the `barrier` of [`ChainWells::new`]. It must be the lowest saddle of the landscape for the
    /// early exit to be exact; pass every saddle you know.
    pub fn barrier_from_saddles(
        potential: impl Fn(&[f64]) -> f64,
        saddles: &[Vec<f64>],
    ) -> Result<f64> {
        let b = saddles
            .iter()
            .map(|s| potential(s))
            .fold(f64::INFINITY, f64::min);
        if !b.is_finite() {
            return Err(invalid(
                "saddles",
                "need at least one saddle with a finite potential",
            ));
        }
        Ok(b)
    }

    /// Replaces the capture radius (must be positive and below half the smallest distance
    /// between stable states).
    pub fn with_capture_radius(mut self, r: f64) -> Result<Self> {
        let mut dmin = f64::INFINITY;
        for a in 0..self.stable.len() {
            for b in a + 1..self.stable.len() {
                dmin = dmin.min(dist(&self.stable[a], &self.stable[b]));
            }
        }
        if !(r.is_finite() && r > 0.0 && r < 0.5 * dmin) {
            return Err(invalid(
                "capture_radius",
                format!(
                    "{r} must be positive and below half the smallest distance between stable states ({dmin})"
                ),
            ));
        }
        self.capture_radius = r;
        Ok(self)
    }

    /// Stable states (labels index this list).
    pub fn stable(&self) -> &[Vec<f64>] {
        &self.stable
    }
    /// Masses, one per DOF.
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }
    /// The barrier actually used (caller's value minus the safety margin), if any.
    pub fn barrier(&self) -> Option<f64> {
        self.barrier
    }
    /// The caller's lowest saddle energy, as given.
    pub fn saddle_energy(&self) -> Option<f64> {
        self.barrier_raw
    }
    /// Potential `V(x)`.
    pub fn potential(&self, x: &[f64]) -> f64 {
        (self.potential)(x)
    }
    /// Total energy `Σ ½ m_i v_i² + V(x)`.
    pub fn energy(&self, x: &[f64], v: &[f64]) -> f64 {
        self.kinetic(v) + (self.potential)(x)
    }
    fn kinetic(&self, v: &[f64]) -> f64 {
        self.masses
            .iter()
            .zip(v)
            .map(|(m, v)| 0.5 * m * v * v)
            .sum::<f64>()
    }
    /// Index and distance of the nearest stable state.
    pub fn nearest(&self, x: &[f64]) -> (usize, f64) {
        self.stable
            .iter()
            .enumerate()
            .map(|(k, s)| (k, dist(s, x)))
            .fold((0, f64::INFINITY), |b, c| if c.1 < b.1 { c } else { b })
    }
    /// The state index if `(x, v)` is provably trapped (see the type's docs).
    pub fn trapped(&self, x: &[f64], v: &[f64]) -> Option<usize> {
        let b = self.barrier?;
        let (k, d) = self.nearest(x);
        (d < self.capture_radius && self.energy(x, v) < b).then_some(k)
    }
    fn settled_without_barrier(&self, x: &[f64], v: &[f64]) -> Option<usize> {
        let (k, d) = self.nearest(x);
        let scale = self
            .stable
            .iter()
            .map(|s| self.potential(s).abs())
            .fold(1e-12, f64::max);
        (d < self.capture_radius && self.kinetic(v) < 1e-9 * scale).then_some(k)
    }
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q) * (p - q))
        .sum::<f64>()
        .sqrt()
}

/// One axis of a 2-D slice: grid coordinate `c` adds `c · dx` to the displacements and
/// `c · dv` to the velocities.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SliceAxis {
    /// Axis name for plots (e.g. "Δx", "v0").
    pub name: String,
    /// Direction in displacement space (one entry per DOF).
    pub dx: Vec<f64>,
    /// Direction in velocity space (one entry per DOF).
    pub dv: Vec<f64>,
}

/// A 2-D slice of a chain's state space: `x = base_x + c0·axes[0].dx + c1·axes[1].dx`,
/// `v = base_v + c0·axes[0].dv + c1·axes[1].dv`; the grid coordinates `(c0, c1)` range over
/// `BasinConfig::{x_range, v_range}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Slice {
    /// Base displacements.
    pub base_x: Vec<f64>,
    /// Base velocities.
    pub base_v: Vec<f64>,
    /// The two axes.
    pub axes: [SliceAxis; 2],
}

impl Slice {
    /// The paper's slice (§3.2): every displacement shifted by `Δx` from `base_x` (usually the
    /// stable state S1), every velocity equal to `v0`: `x_i(0) = x_i^S + Δx`, `ẋ_i(0) = v0`.
    pub fn paper(base_x: &[f64]) -> Self {
        let n = base_x.len();
        Self {
            base_x: base_x.to_vec(),
            base_v: vec![0.0; n],
            axes: [
                SliceAxis {
                    name: "Δx".into(),
                    dx: vec![1.0; n],
                    dv: vec![0.0; n],
                },
                SliceAxis {
                    name: "v0".into(),
                    dx: vec![0.0; n],
                    dv: vec![1.0; n],
                },
            ],
        }
    }

    /// Number of DOFs.
    pub fn dofs(&self) -> usize {
        self.base_x.len()
    }

    /// Checks that every vector has one entry per DOF and is finite.
    pub fn validate(&self, dofs: usize) -> Result<()> {
        let vecs = [
            ("slice.base_x", &self.base_x),
            ("slice.base_v", &self.base_v),
            ("slice.axes[0].dx", &self.axes[0].dx),
            ("slice.axes[0].dv", &self.axes[0].dv),
            ("slice.axes[1].dx", &self.axes[1].dx),
            ("slice.axes[1].dv", &self.axes[1].dv),
        ];
        for (name, v) in vecs {
            if v.len() != dofs || v.iter().any(|c| !c.is_finite()) {
                return Err(invalid(
                    name,
                    format!("needs {dofs} finite entries (one per DOF), got {v:?}"),
                ));
            }
        }
        Ok(())
    }

    /// Writes the state at grid coordinates `(c0, c1)` into `x` and `v`.
    pub fn state_into(&self, c0: f64, c1: f64, x: &mut [f64], v: &mut [f64]) {
        let [a, b] = &self.axes;
        for i in 0..self.base_x.len() {
            x[i] = self.base_x[i] + c0 * a.dx[i] + c1 * b.dx[i];
            v[i] = self.base_v[i] + c0 * a.dv[i] + c1 * b.dv[i];
        }
    }

    /// The state at grid coordinates `(c0, c1)`.
    pub fn state(&self, c0: f64, c1: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.base_x.len();
        let (mut x, mut v) = (vec![0.0; n], vec![0.0; n]);
        self.state_into(c0, c1, &mut x, &mut v);
        (x, v)
    }
}

/// The chain judge: wells plus a blow-up limit.
struct ChainJudge<'a> {
    wells: &'a ChainWells,
    limit: f64,
}

impl<'a> ChainJudge<'a> {
    fn new(wells: &'a ChainWells) -> Self {
        let limit = 1e6
            * wells
                .stable
                .iter()
                .flatten()
                .fold(1.0f64, |m, c| m.max(c.abs()));
        Self { wells, limit }
    }
}

impl Judge for ChainJudge<'_> {
    fn trapped(&self, x: &[f64], v: &[f64]) -> Option<usize> {
        self.wells.trapped(x, v)
    }
    fn early(&self) -> bool {
        self.wells.barrier.is_some()
    }
    fn limit(&self) -> f64 {
        self.limit
    }
    fn region(&self, x: &[f64]) -> u32 {
        self.wells.nearest(x).0 as u32
    }
    fn at_cap(&self, x: &[f64], v: &[f64]) -> Label {
        let settled = if self.wells.barrier.is_some() {
            self.wells.trapped(x, v)
        } else {
            self.wells.settled_without_barrier(x, v)
        };
        settled.map_or(Label::Unsettled, Label::State)
    }
}

/// Integrates the unforced chain from `(x, v)` and labels where it ends (see [`ChainWells`] for
/// the trapping test). Gives exactly the label [`basin_chain`] gives the same start when it
/// integrates it.
pub fn classify_chain<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &ChainWells,
    x: &[f64],
    v: &[f64],
    cfg: &BasinConfig,
) -> Label {
    let judge = ChainJudge::new(wells);
    classify_one(sys, &judge, cfg, &|xs, vs| {
        xs.copy_from_slice(x);
        vs.copy_from_slice(v);
    })
}

pub(crate) fn check_chain<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &ChainWells,
    slice: &Slice,
) -> Result<()> {
    let n = sys.dofs();
    if wells.masses.len() != n {
        return Err(invalid(
            "wells.masses",
            format!(
                "system has {n} DOFs but {} masses were given",
                wells.masses.len()
            ),
        ));
    }
    if wells.stable[0].len() != n {
        return Err(invalid(
            "wells.stable",
            format!(
                "system has {n} DOFs but stable states have {}",
                wells.stable[0].len()
            ),
        ));
    }
    slice.validate(n)
}

/// Basin map of a chain over a 2-D [`Slice`]; the slice coordinates range over
/// `cfg.x_range × cfg.v_range` (see [`crate::Method`] for which starts are integrated). A step
/// too long for RK4 to be stable on the slice is refused. `progress` is called with the number
/// of cells labelled so far.
pub fn basin_chain<S: SecondOrderSystem + ?Sized>(
    sys: &S,
    wells: &ChainWells,
    slice: &Slice,
    cfg: &BasinConfig,
    progress: Progress<'_>,
) -> Result<BasinMap> {
    cfg.validate()?;
    check_chain(sys, wells, slice)?;
    crate::limits::step_limit_chain(sys, wells, slice, cfg)?.check(cfg.dt)?;
    let start = Instant::now();
    let judge = ChainJudge::new(wells);
    let labels = run_grid(sys, &judge, cfg, progress, |i, j, x, v| {
        slice.state_into(cfg.x_at(i), cfg.v_at(j), x, v)
    });
    Ok(BasinMap::assemble(
        labels,
        cfg,
        (&slice.axes[0].name, &slice.axes[1].name),
        wells.stable.clone(),
        start.elapsed().as_secs_f64(),
    ))
}
