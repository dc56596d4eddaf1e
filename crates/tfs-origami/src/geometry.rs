//! Kresling truss geometry of the paper's Appendix A: rest lengths, crease lengths, the truss energy
//! `U(h, θ)` and its first and second partial derivatives in closed form.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

use crate::{OrigamiError, Result};

/// Crease and material parameters of one Kresling cell (paper Appendix A).
///
/// Lengths are in the paper's units (c0 = 1), angles in degrees, stiffnesses per crease.
/// `r` is the circumradius of the base hexagon; the paper's cells use `r = 1 = c0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct KreslingParams {
    /// Crease length `a0` (the valley crease) at rest.
    pub a0: f64,
    /// Base polygon side `c0`.
    pub c0: f64,
    /// Crease-pattern angle `γ0` in degrees (the angle opposite `c0` in the flat triangle).
    pub gamma0_deg: f64,
    /// Axial stiffness of each `a` crease spring.
    pub k_a: f64,
    /// Axial stiffness of each `b` crease spring.
    pub k_b: f64,
    /// Moving mass (top plate) `m`.
    pub m: f64,
    /// Viscous damping coefficient `c` on the relative velocity `h'`.
    pub c: f64,
    /// Circumradius `R` of the base hexagon (default 1).
    pub r: f64,
}

impl Default for KreslingParams {
    /// The paper's §3.1 cell: a0 = 1.6, c0 = 1, γ0 = 30°, k_a = k_b = 9.30, m = 1, c = 2, R = 1.
    fn default() -> Self {
        Self {
            a0: 1.6,
            c0: 1.0,
            gamma0_deg: 30.0,
            k_a: 9.30,
            k_b: 9.30,
            m: 1.0,
            c: 2.0,
            r: 1.0,
        }
    }
}

fn positive(name: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(OrigamiError::Param(format!(
            "'{name}' = {v} must be a finite number > 0"
        )))
    }
}

impl KreslingParams {
    /// Checks every parameter; the error names the offending one and the allowed range.
    pub fn validate(&self) -> Result<()> {
        positive("a0", self.a0)?;
        positive("c0", self.c0)?;
        positive("k_a", self.k_a)?;
        positive("k_b", self.k_b)?;
        positive("m", self.m)?;
        positive("r", self.r)?;
        if !(self.c.is_finite() && self.c >= 0.0) {
            return Err(OrigamiError::Param(format!(
                "'c' (damping) = {} must be a finite number >= 0",
                self.c
            )));
        }
        if !(self.gamma0_deg.is_finite() && self.gamma0_deg > 0.0 && self.gamma0_deg < 90.0) {
            return Err(OrigamiError::Param(format!(
                "'gamma0_deg' = {} must lie strictly between 0 and 90 degrees",
                self.gamma0_deg
            )));
        }
        let s = self.a0 * self.gamma0_deg.to_radians().sin() / self.c0;
        if s > 1.0 {
            return Err(OrigamiError::Param(format!(
                "a0·sin(γ0)/c0 = {s:.4} > 1: no crease triangle exists (Eq. A.1); reduce 'a0' or 'gamma0_deg', or increase 'c0'"
            )));
        }
        Ok(())
    }

    /// Rest length of the `b` crease, Eq. (A.1):
    /// `b0 = c0/sin γ0 · sin(γ0 + asin(a0 sin γ0 / c0))`.
    pub fn b0(&self) -> f64 {
        let g = self.gamma0_deg.to_radians();
        self.c0 / g.sin() * (g + (self.a0 * g.sin() / self.c0).asin()).sin()
    }
}

/// Pre-computed constants of the truss energy; all methods are closed-form.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Truss {
    pub a0: f64,
    pub b0: f64,
    pub ka: f64,
    pub kb: f64,
    pub r2: f64,
}

/// Values and partial derivatives of `U(h, θ)` at one point.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Partials {
    pub u: f64,
    pub u_h: f64,
    pub u_t: f64,
    pub u_hh: f64,
    pub u_ht: f64,
    pub u_tt: f64,
}

impl Truss {
    pub fn new(p: &KreslingParams) -> Self {
        Self {
            a0: p.a0,
            b0: p.b0(),
            ka: p.k_a,
            kb: p.k_b,
            r2: p.r * p.r,
        }
    }

    /// Crease lengths `(a, b)` of Eqs. (A.2)–(A.3).
    pub fn lengths(&self, h: f64, theta: f64) -> (f64, f64) {
        let sa = (0.5 * theta).sin();
        let sb = (0.5 * theta + PI / 6.0).sin();
        (
            (h * h + 4.0 * self.r2 * sa * sa).sqrt(),
            (h * h + 4.0 * self.r2 * sb * sb).sqrt(),
        )
    }

    /// Energy (A.4), with all first and second partials.
    pub fn partials(&self, h: f64, theta: f64) -> Partials {
        let (a, b) = self.lengths(h, theta);
        let phi = theta + PI / 3.0;
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        let p = 1.0 - self.a0 / a;
        let q = 1.0 - self.b0 / b;
        let a3 = a * a * a;
        let b3 = b * b * b;
        let u = 3.0 * self.ka * (a - self.a0).powi(2) + 3.0 * self.kb * (b - self.b0).powi(2);
        let u_h = 6.0 * h * (self.ka * p + self.kb * q);
        let u_t = 6.0 * self.r2 * (self.ka * p * st + self.kb * q * sp);
        let u_hh = 6.0 * (self.ka * p + self.kb * q)
            + 6.0 * h * h * (self.ka * self.a0 / a3 + self.kb * self.b0 / b3);
        let u_ht = 6.0 * h * self.r2 * (self.ka * self.a0 * st / a3 + self.kb * self.b0 * sp / b3);
        let u_tt = 6.0
            * self.r2
            * (self.ka * (self.a0 * self.r2 * st * st / a3 + p * ct)
                + self.kb * (self.b0 * self.r2 * sp * sp / b3 + q * cp));
        Partials {
            u,
            u_h,
            u_t,
            u_hh,
            u_ht,
            u_tt,
        }
    }

    /// Stress-free configurations `(h, θ)` with `h ≥ 0` where both springs are at rest length
    /// (`a = a0`, `b = b0`); the deployed and folded states of a compatible crease pattern.
    pub fn rest_states(&self) -> Vec<(f64, f64)> {
        // 4R²[sin²(φ+π/6) − sin²φ] = 2R² sin(2φ + π/6) = b0² − a0², with φ = θ/2.
        let s = (self.b0 * self.b0 - self.a0 * self.a0) / (2.0 * self.r2);
        if s.abs() > 1.0 {
            return Vec::new();
        }
        let base = s.asin();
        let mut out = Vec::new();
        for psi in [base, PI - base] {
            let phi = 0.5 * (psi - PI / 6.0);
            let sa = phi.sin();
            let h2 = self.a0 * self.a0 - 4.0 * self.r2 * sa * sa;
            if h2 >= -1e-12 {
                out.push((h2.max(0.0).sqrt(), 2.0 * phi));
            }
        }
        out.sort_by(|x, y| x.0.total_cmp(&y.0));
        out
    }
}
