//! One Kresling truss cell: the torque-free branch `θ(h)`, its tabulated force and potential,
//! the folded stop, equilibria, barriers and plotting curves.
//!
//! **Branch.** For each height `h` the twist `θ` relaxes to a torque-free minimum of `U(h, ·)`
//! (Eq. A.8 with `∂²U/∂θ² > 0`). The branch starts at `h = 0` from the global minimiser of
//! `U(0, θ)` (for a compatible crease pattern such as γ0 = 30°, R = c0, that is the stress-free
//! folded state `a = a0, b = b0`) and is followed in `h` by predictor–corrector continuation
//! (Newton on `T = ∂U/∂θ` with the analytic predictor `θ' = −U_hθ / U_θθ`). Every stress-free
//! state of the pattern lies on it (tested).
//!
//! **Force and potential.** `F(h) = dV/dh = ∂U/∂h` at `θ(h)` (envelope theorem, exact) and
//! `F'(h) = U_hh − U_hθ² / U_θθ`. Both are stored at the nodes of a uniform grid on `[0, h_max]`;
//! `F` is a cubic Hermite interpolant with those exact slopes, and the tabulated potential is the
//! *exact antiderivative of the interpolated force*, so `dV/dh = F` holds to rounding and an
//! undamped simulation conserves `½mv² + V` up to the integrator's own error. The reference is
//! `V(0) = 0`, i.e. `V(h) = U(h, θ(h)) − U(0, θ(0))`. The interpolation error is measured at
//! build time against direct solves at every interval midpoint ([`KreslingCell::table_error`]).
//! Beyond `h_max` the branch is followed directly (slow but exact).
//!
//! **Folded stop.** The truss energy is even in `h`, so the bare model has a mirror well at
//! `h ≈ −1.58` (γ0 = 30°) that the physical cell does not have. For `h < 0` the cell force is the
//! bare (odd) truss force plus a one-sided contact `k_stop · h`, and the potential gains
//! `½ k_stop h²`. The default `k_stop` is 100 × the largest `|F'|` on the table.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

use crate::geometry::{KreslingParams, Truss};
use crate::{OrigamiError, Result};

/// Numerical options of a cell: table resolution and range, and the folded stop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CellOptions {
    /// Target grid spacing of the `F`/`V` table (default 1e-3).
    pub step: f64,
    /// Upper end of the table; `None` means `2·max(a0, b0)` (springs stretched ~100%).
    pub h_max: Option<f64>,
    /// Stiffness of the folded stop acting for `h < 0`; `None` means 100 × max |F'| on the table.
    pub k_stop: Option<f64>,
}

impl Default for CellOptions {
    fn default() -> Self {
        Self {
            step: 1e-3,
            h_max: None,
            k_stop: None,
        }
    }
}

/// A direct (untabulated) evaluation of the branch at one height.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BranchPoint {
    /// Height `h ≥ 0`.
    pub h: f64,
    /// Torque-free twist `θ(h)` in radians.
    pub theta: f64,
    /// Axial force `F = ∂U/∂h`.
    pub force: f64,
    /// Axial stiffness `dF/dh = U_hh − U_hθ²/U_θθ`.
    pub stiffness: f64,
    /// Potential `V(h) = U(h, θ(h)) − U(0, θ(0))`.
    pub potential: f64,
}

/// The energy barrier between two neighbouring stable states.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Barrier {
    /// Lower stable state.
    pub from: f64,
    /// Unstable state in between.
    pub over: f64,
    /// Upper stable state.
    pub to: f64,
    /// `V(over) − V(from)`: energy to go up (deploy).
    pub forward: f64,
    /// `V(over) − V(to)`: energy to come back down.
    pub backward: f64,
}

/// JSON summary of a cell (`tfs simulate kresling --json` and `tfs kresling`): keys `b0`, `stable`,
/// `unstable`, `barrier` are stable contract keys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellSummary {
    /// Rest length of the `b` crease (Eq. A.1).
    pub b0: f64,
    /// Stable heights (strict local minima of `V`, including the folded `h = 0` if it is one).
    pub stable: Vec<f64>,
    /// Unstable equilibrium heights.
    pub unstable: Vec<f64>,
    /// Deployment barrier `V(u) − V(s1)` from the lowest stable state over the next unstable one;
    /// `null` for a monostable cell.
    pub barrier: Option<f64>,
    /// Every barrier between consecutive stable states.
    pub barriers: Vec<Barrier>,
    /// `V` at the stable states.
    pub v_stable: Vec<f64>,
    /// `V` at the unstable states.
    pub v_unstable: Vec<f64>,
    /// "monostable", "bistable" or "multistable".
    pub classification: String,
    /// Stiffness of the folded stop.
    pub k_stop: f64,
    /// Upper end of the table.
    pub h_max: f64,
    /// Largest measured |F_table − F_direct| (at interval midpoints).
    pub table_error: f64,
    /// The parameters.
    pub params: KreslingParams,
}

/// Samples of the potential and force for plotting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    /// Heights.
    pub h: Vec<f64>,
    /// Potential `V(h)` (with the stop for `h < 0`).
    pub v: Vec<f64>,
    /// Force `F(h)` (with the stop for `h < 0`).
    pub f: Vec<f64>,
}

/// A Kresling truss cell with its tabulated torque-free branch.
#[derive(Debug, Clone)]
pub struct KreslingCell {
    params: KreslingParams,
    truss: Truss,
    dh: f64,
    h_max: f64,
    theta: Vec<f64>,
    dtheta: Vec<f64>,
    f: Vec<f64>,
    df: Vec<f64>,
    v: Vec<f64>,
    u_ref: f64,
    k_stop: f64,
    table_error: f64,
    stable: Vec<f64>,
    unstable: Vec<f64>,
}

#[inline]
fn hermite(s: f64) -> [f64; 4] {
    let s2 = s * s;
    let s3 = s2 * s;
    [
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        -2.0 * s3 + 3.0 * s2,
        s3 - s2,
    ]
}

#[inline]
fn hermite_d(s: f64) -> [f64; 4] {
    let s2 = s * s;
    [
        6.0 * s2 - 6.0 * s,
        3.0 * s2 - 4.0 * s + 1.0,
        -6.0 * s2 + 6.0 * s,
        3.0 * s2 - 2.0 * s,
    ]
}

#[inline]
fn hermite_int(s: f64) -> [f64; 4] {
    let s2 = s * s;
    let s3 = s2 * s;
    let s4 = s3 * s;
    [
        s - s3 + 0.5 * s4,
        0.5 * s2 - 2.0 * s3 / 3.0 + 0.25 * s4,
        s3 - 0.5 * s4,
        0.25 * s4 - s3 / 3.0,
    ]
}

impl KreslingCell {
    /// Builds the cell with default [`CellOptions`].
    pub fn new(params: KreslingParams) -> Result<Self> {
        Self::with_options(params, CellOptions::default())
    }

    /// Builds the cell: validates the parameters, follows the branch, tabulates `F`, `F'`, `V`,
    /// measures the table error and finds the equilibria.
    pub fn with_options(params: KreslingParams, opts: CellOptions) -> Result<Self> {
        params.validate()?;
        let truss = Truss::new(&params);
        if !(opts.step.is_finite() && opts.step > 0.0 && opts.step <= 0.05) {
            return Err(OrigamiError::Param(format!(
                "'step' = {} must be in (0, 0.05]; the default 1e-3 gives ~1e-11 table error",
                opts.step
            )));
        }
        let h_max = opts.h_max.unwrap_or(2.0 * params.a0.max(truss.b0)).max(0.0);
        if !(h_max.is_finite() && h_max > 10.0 * opts.step) {
            return Err(OrigamiError::Param(format!(
                "'h_max' = {h_max} must be finite and larger than 10 table steps"
            )));
        }
        let n = (h_max / opts.step).ceil() as usize;
        let dh = h_max / n as f64;
        let mut cell = Self {
            params,
            truss,
            dh,
            h_max,
            theta: Vec::with_capacity(n + 1),
            dtheta: Vec::with_capacity(n + 1),
            f: Vec::with_capacity(n + 1),
            df: Vec::with_capacity(n + 1),
            v: Vec::with_capacity(n + 1),
            u_ref: 0.0,
            k_stop: 0.0,
            table_error: 0.0,
            stable: Vec::new(),
            unstable: Vec::new(),
        };
        let th0 = cell.start_theta()?;
        let mut th = th0;
        for i in 0..=n {
            let h = i as f64 * dh;
            if i > 0 {
                th = cell
                    .track(h - dh, th, h)
                    .ok_or_else(|| OrigamiError::Branch(format!(
                        "the torque-free branch θ(h) folds or loses stability near h = {h:.4} (∂²U/∂θ² ≤ 0); \
                         this crease pattern has no single-valued branch on [0, h_max]; lower 'h_max' or change the parameters"
                    )))?;
            }
            let p = cell.truss.partials(h, th);
            if i == 0 {
                cell.u_ref = p.u;
            }
            cell.theta.push(th);
            cell.dtheta.push(-p.u_ht / p.u_tt);
            cell.f.push(p.u_h);
            cell.df.push(p.u_hh - p.u_ht * p.u_ht / p.u_tt);
        }
        cell.v.push(0.0);
        for i in 0..n {
            let w = hermite_int(1.0);
            let inc = dh
                * (w[0] * cell.f[i]
                    + w[1] * dh * cell.df[i]
                    + w[2] * cell.f[i + 1]
                    + w[3] * dh * cell.df[i + 1]);
            let last = cell.v[i];
            cell.v.push(last + inc);
        }
        // Measured interpolation error at interval midpoints.
        let mut err: f64 = 0.0;
        for i in 0..n {
            let h = (i as f64 + 0.5) * dh;
            let direct = cell.branch_point_near(h, cell.theta_interp(h))?;
            err = err.max((direct.force - cell.truss_force(h)).abs());
        }
        cell.table_error = err;
        let max_df = cell.df.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        cell.k_stop = match opts.k_stop {
            Some(k) if k.is_finite() && k > 0.0 => k,
            Some(k) => {
                return Err(OrigamiError::Param(format!(
                    "'k_stop' = {k} must be a finite number > 0 (or omitted for 100 × max|F'|)"
                )));
            }
            None => 100.0 * max_df,
        };
        cell.find_equilibria();
        Ok(cell)
    }

    /// Global minimiser of `U(0, θ)` over `θ`, polished by Newton.
    fn start_theta(&self) -> Result<f64> {
        let n = 3600;
        let mut best: Option<(f64, f64)> = None;
        for i in 0..n {
            let th = -PI + 2.0 * PI * (i as f64 + 0.5) / n as f64;
            let u = self.truss.partials(0.0, th).u;
            if u.is_finite() && best.is_none_or(|(_, bu)| u < bu) {
                best = Some((th, u));
            }
        }
        let (th, _) = best.ok_or_else(|| OrigamiError::Branch("U(0, θ) is not finite".into()))?;
        self.newton(0.0, th).ok_or_else(|| {
            OrigamiError::Branch(
                "Newton on the torque-free condition T(θ; h = 0) = 0 did not converge".into(),
            )
        })
    }

    /// Newton on `T(θ; h) = 0` from `th`, accepting only a local minimum (`U_θθ > 0`).
    fn newton(&self, h: f64, mut th: f64) -> Option<f64> {
        for _ in 0..60 {
            let p = self.truss.partials(h, th);
            if !(p.u_tt > 0.0 && p.u_t.is_finite()) {
                return None;
            }
            let d = (p.u_t / p.u_tt).clamp(-0.2, 0.2);
            th -= d;
            if d.abs() <= 1e-14 * (1.0 + th.abs()) {
                let p = self.truss.partials(h, th);
                return (p.u_tt > 0.0).then_some(th);
            }
        }
        None
    }

    /// Follows the branch from `(h0, th0)` to `h1` with adaptive predictor–corrector steps.
    fn track(&self, h0: f64, th0: f64, h1: f64) -> Option<f64> {
        let mut h = h0;
        let mut th = th0;
        let mut step = (h1 - h0).clamp(-0.05, 0.05);
        if step == 0.0 {
            return self.newton(h1, th0);
        }
        while h != h1 {
            let hn = if (h1 - h).abs() <= step.abs() {
                h1
            } else {
                h + step
            };
            let p = self.truss.partials(h, th);
            let pred = th - p.u_ht / p.u_tt * (hn - h);
            match self.newton(hn, pred) {
                Some(t) if (t - pred).abs() < 0.05 => {
                    h = hn;
                    th = t;
                    step *= 1.5;
                }
                _ => {
                    step *= 0.5;
                    if step.abs() < 1e-10 {
                        return None;
                    }
                }
            }
        }
        Some(th)
    }

    fn branch_point_near(&self, h: f64, guess: f64) -> Result<BranchPoint> {
        let th = self.newton(h, guess).ok_or_else(|| {
            OrigamiError::Branch(format!("direct torque-free solve failed at h = {h}"))
        })?;
        Ok(self.point_at(h, th))
    }

    fn point_at(&self, h: f64, th: f64) -> BranchPoint {
        let p = self.truss.partials(h, th);
        BranchPoint {
            h,
            theta: th,
            force: p.u_h,
            stiffness: p.u_hh - p.u_ht * p.u_ht / p.u_tt,
            potential: p.u - self.u_ref,
        }
    }

    /// Direct (untabulated) solve of the branch at `h ≥ 0`: Newton from the tabulated twist
    /// inside the table, continuation from `h_max` beyond it.
    pub fn branch_point(&self, h: f64) -> Result<BranchPoint> {
        if !(h.is_finite() && h >= 0.0) {
            return Err(OrigamiError::Param(format!(
                "'h' = {h} must be finite and >= 0 for a branch solve"
            )));
        }
        if h <= self.h_max {
            self.branch_point_near(h, self.theta_interp(h))
        } else {
            let n = self.theta.len() - 1;
            let th = self.track(self.h_max, self.theta[n], h).ok_or_else(|| {
                OrigamiError::Branch(format!(
                    "branch continuation failed beyond h_max at h = {h}"
                ))
            })?;
            Ok(self.point_at(h, th))
        }
    }

    #[inline]
    fn locate(&self, h: f64) -> (usize, f64) {
        let n = self.f.len() - 1;
        let x = h / self.dh;
        let i = (x.floor() as usize).min(n - 1);
        (i, x - i as f64)
    }

    fn theta_interp(&self, h: f64) -> f64 {
        let (i, s) = self.locate(h);
        let w = hermite(s);
        w[0] * self.theta[i]
            + w[1] * self.dh * self.dtheta[i]
            + w[2] * self.theta[i + 1]
            + w[3] * self.dh * self.dtheta[i + 1]
    }

    /// Bare truss force for `h ≥ 0` (table inside, direct beyond; NaN if that fails).
    #[inline]
    fn truss_force(&self, h: f64) -> f64 {
        if h <= self.h_max {
            let (i, s) = self.locate(h);
            let w = hermite(s);
            w[0] * self.f[i]
                + w[1] * self.dh * self.df[i]
                + w[2] * self.f[i + 1]
                + w[3] * self.dh * self.df[i + 1]
        } else {
            self.branch_point(h).map_or(f64::NAN, |p| p.force)
        }
    }

    #[inline]
    fn truss_stiffness(&self, h: f64) -> f64 {
        if h <= self.h_max {
            let (i, s) = self.locate(h);
            let w = hermite_d(s);
            (w[0] * self.f[i]
                + w[1] * self.dh * self.df[i]
                + w[2] * self.f[i + 1]
                + w[3] * self.dh * self.df[i + 1])
                / self.dh
        } else {
            self.branch_point(h).map_or(f64::NAN, |p| p.stiffness)
        }
    }

    fn truss_potential(&self, h: f64) -> f64 {
        if h <= self.h_max {
            let (i, s) = self.locate(h);
            let w = hermite_int(s);
            self.v[i]
                + self.dh
                    * (w[0] * self.f[i]
                        + w[1] * self.dh * self.df[i]
                        + w[2] * self.f[i + 1]
                        + w[3] * self.dh * self.df[i + 1])
        } else {
            // Continue from the table's end so V stays continuous (difference ~ table error).
            let n = self.v.len() - 1;
            match self.branch_point(h) {
                Ok(p) => {
                    self.v[n] + p.potential - self.point_at(self.h_max, self.theta[n]).potential
                }
                Err(_) => f64::NAN,
            }
        }
    }

    /// Axial restoring force `F(h)` with the folded stop (`h < 0`: odd truss force + `k_stop·h`).
    #[inline]
    pub fn force(&self, h: f64) -> f64 {
        if h >= 0.0 {
            self.truss_force(h)
        } else {
            -self.truss_force(-h) + self.k_stop * h
        }
    }

    /// Axial stiffness `dF/dh` (with the stop for `h < 0`).
    #[inline]
    pub fn stiffness(&self, h: f64) -> f64 {
        if h >= 0.0 {
            self.truss_stiffness(h)
        } else {
            self.truss_stiffness(-h) + self.k_stop
        }
    }

    /// Potential `V(h)` with `V(0) = 0` (with `½ k_stop h²` added for `h < 0`).
    pub fn potential(&self, h: f64) -> f64 {
        if h >= 0.0 {
            self.truss_potential(h)
        } else {
            self.truss_potential(-h) + 0.5 * self.k_stop * h * h
        }
    }

    /// The bare truss force without the stop (odd in `h`; has the mirror well at negative `h`).
    pub fn bare_force(&self, h: f64) -> f64 {
        h.signum() * self.truss_force(h.abs())
    }

    /// Torque-free twist `θ(h)` in radians for `h ≥ 0` (even in `h`).
    pub fn theta(&self, h: f64) -> f64 {
        let h = h.abs();
        if h <= self.h_max {
            self.theta_interp(h)
        } else {
            self.branch_point(h).map_or(f64::NAN, |p| p.theta)
        }
    }

    /// Crease lengths `(a, b)` on the branch at height `h`.
    pub fn crease_lengths(&self, h: f64) -> (f64, f64) {
        self.truss.lengths(h, self.theta(h))
    }

    /// Truss energy `U(h, θ)` of Eq. (A.4) at an arbitrary configuration.
    pub fn energy(&self, h: f64, theta: f64) -> f64 {
        self.truss.partials(h, theta).u
    }

    /// Torque `T(θ; h) = ∂U/∂θ` of Eq. (A.8).
    pub fn torque(&self, h: f64, theta: f64) -> f64 {
        self.truss.partials(h, theta).u_t
    }

    /// Stress-free configurations `(h, θ)`, `h ≥ 0`, where `a = a0` and `b = b0`.
    pub fn rest_states(&self) -> Vec<(f64, f64)> {
        self.truss.rest_states()
    }

    /// The parameters.
    pub fn params(&self) -> &KreslingParams {
        &self.params
    }

    /// Rest length `b0` (Eq. A.1).
    pub fn b0(&self) -> f64 {
        self.truss.b0
    }

    /// Stiffness of the folded stop.
    pub fn k_stop(&self) -> f64 {
        self.k_stop
    }

    /// Upper end of the table.
    pub fn h_max(&self) -> f64 {
        self.h_max
    }

    /// Largest |F_table − F_direct| measured at every interval midpoint at build time.
    pub fn table_error(&self) -> f64 {
        self.table_error
    }

    /// Largest |F| on the table (a scale for relative errors).
    pub fn force_scale(&self) -> f64 {
        self.f.iter().fold(0.0f64, |m, f| m.max(f.abs()))
    }

    /// Stable heights (ascending).
    pub fn stable(&self) -> &[f64] {
        &self.stable
    }

    /// Unstable equilibrium heights (ascending).
    pub fn unstable(&self) -> &[f64] {
        &self.unstable
    }

    fn find_equilibria(&mut self) {
        let (stable, unstable) =
            equilibria_1d(|h| self.force(h), 0.0, self.h_max, self.f.len() - 1);
        // Polish interior roots with the direct solve.
        let polish = |h: f64| -> f64 {
            if h == 0.0 {
                return h;
            }
            let mut h = h;
            for _ in 0..3 {
                match self.branch_point(h) {
                    Ok(p) if p.stiffness != 0.0 => h -= p.force / p.stiffness,
                    _ => break,
                }
            }
            h
        };
        let stable: Vec<f64> = stable.into_iter().map(polish).collect();
        let unstable: Vec<f64> = unstable.into_iter().map(polish).collect();
        self.stable = stable;
        self.unstable = unstable;
    }

    /// Barriers between consecutive stable states.
    pub fn barriers(&self) -> Vec<Barrier> {
        barriers_between(&self.stable, &self.unstable, |h| self.potential(h))
    }

    /// The JSON summary.
    pub fn summary(&self) -> CellSummary {
        let barriers = self.barriers();
        CellSummary {
            b0: self.b0(),
            stable: self.stable.clone(),
            unstable: self.unstable.clone(),
            barrier: barriers.first().map(|b| b.forward),
            v_stable: self.stable.iter().map(|&h| self.potential(h)).collect(),
            v_unstable: self.unstable.iter().map(|&h| self.potential(h)).collect(),
            classification: classify(self.stable.len()).to_string(),
            barriers,
            k_stop: self.k_stop,
            h_max: self.h_max,
            table_error: self.table_error,
            params: self.params,
        }
    }

    /// `n ≥ 2` samples of `V` and `F` on `[h_lo, h_hi]` for plotting.
    pub fn curve(&self, h_lo: f64, h_hi: f64, n: usize) -> Result<Curve> {
        let h = sample_range(h_lo, h_hi, n)?;
        Ok(Curve {
            v: h.iter().map(|&x| self.potential(x)).collect(),
            f: h.iter().map(|&x| self.force(x)).collect(),
            h,
        })
    }
}

/// "monostable", "bistable" or "multistable" from the number of stable states.
pub(crate) fn classify(n: usize) -> &'static str {
    match n {
        0 => "unstable",
        1 => "monostable",
        2 => "bistable",
        _ => "multistable",
    }
}

pub(crate) fn sample_range(lo: f64, hi: f64, n: usize) -> Result<Vec<f64>> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo && n >= 2) {
        return Err(OrigamiError::Param(format!(
            "curve range [{lo}, {hi}] with {n} samples: need finite lo < hi and at least 2 samples"
        )));
    }
    Ok((0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect())
}

/// Equilibria of a 1-D force on `[lo, hi]` from sign changes on an `n`-interval grid, refined by
/// bisection. A root is stable if `F` goes from negative to positive through it.
pub(crate) fn equilibria_1d(
    f: impl Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    n: usize,
) -> (Vec<f64>, Vec<f64>) {
    let dx = (hi - lo) / n as f64;
    let probe = dx * 1e-3;
    let mut roots = Vec::new();
    let mut prev = f(lo);
    if prev == 0.0 {
        roots.push(lo);
    }
    for i in 1..=n {
        let x1 = if i == n { hi } else { lo + i as f64 * dx };
        let cur = f(x1);
        if cur == 0.0 {
            roots.push(x1);
        } else if prev != 0.0 && prev * cur < 0.0 {
            let (mut a, mut b) = (x1 - dx, x1);
            let fa_neg = prev < 0.0;
            for _ in 0..200 {
                let m = 0.5 * (a + b);
                if m <= a || m >= b {
                    break;
                }
                if (f(m) < 0.0) == fa_neg {
                    a = m;
                } else {
                    b = m;
                }
            }
            roots.push(0.5 * (a + b));
        }
        prev = cur;
    }
    let mut stable = Vec::new();
    let mut unstable = Vec::new();
    for r in roots {
        let left = f(r - probe);
        let right = f(r + probe);
        if left < 0.0 && right > 0.0 {
            stable.push(r);
        } else if (right < 0.0 && (left > 0.0 || r == lo)) || (r == hi && left > 0.0) {
            unstable.push(r);
        }
    }
    (stable, unstable)
}

pub(crate) fn barriers_between(
    stable: &[f64],
    unstable: &[f64],
    v: impl Fn(f64) -> f64,
) -> Vec<Barrier> {
    stable
        .windows(2)
        .filter_map(|w| {
            let over = unstable
                .iter()
                .copied()
                .filter(|&u| u > w[0] && u < w[1])
                .max_by(|a, b| v(*a).total_cmp(&v(*b)))?;
            Some(Barrier {
                from: w[0],
                over,
                to: w[1],
                forward: v(over) - v(w[0]),
                backward: v(over) - v(w[1]),
            })
        })
        .collect()
}
