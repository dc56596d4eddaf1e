//! Internal states: physics that is not a function of `(x, x', u)` but of their history.
//!
//! An internal state `z` obeys a first-order law `z' = g(q', z; p)` driven by a velocity
//! coordinate `q'` (a DOF's own `x'` or a relative `(a-b)'`), and enters an equation through a
//! term factor whose value is `z`. The law and its parameters are part of the term's name, so a
//! model file carries them and round-trips:
//!
//! * `maxwell(q', τ)`: `z' = (q' − z)/τ`, the velocity low-pass filtered with time constant `τ`
//!   seconds (a hidden Maxwell element: a spring in series with a dashpot);
//! * `bouc_wen(q', a, b[, ν])`: `z' = q' − a·|q'|·|z|^(ν−1)·z − b·q'·|z|^ν` (Bouc–Wen
//!   hysteresis, `z` in the units of `q`; with the benchmark's force form
//!   `z_F' = α q' − β(γ|q'||z_F|^(ν−1) z_F + δ q' |z_F|^ν)` and `z_F = α z`:
//!   `a = βγ·α^(ν−1)`, `b = βδ·α^(ν−1)`; `ν = 1` is not printed);
//! * `dahl(q', κ)`: `z' = κ·(q' − |q'|·z)`, Dahl friction with `z` in `[−1, 1]` (the friction
//!   force is the coefficient times `z`; `1/κ` is the presliding displacement).
//!
//! Every state starts at `z = 0`: on a record at the first sample ([`StateLaw::integrate`]), in a
//! simulation at its start.

use crate::{LibraryError, Result};

/// The law `z' = g(q', z)` of an internal state (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StateLaw {
    /// `z' = (q' − z)/τ` (τ in seconds, > 0).
    Maxwell {
        /// Time constant (s).
        tau: f64,
    },
    /// `z' = q' − a|q'||z|^(ν−1) z − b q' |z|^ν` (ν ≥ 1).
    BoucWen {
        /// Coefficient of the `|q'|` part (per unit of `q` when ν = 1).
        a: f64,
        /// Coefficient of the `q'` part.
        b: f64,
        /// The exponent ν (≥ 1; 1 is the common choice).
        nu: f64,
    },
    /// `z' = κ (q' − |q'| z)` (κ > 0, per unit of `q`).
    Dahl {
        /// Inverse presliding displacement.
        kappa: f64,
    },
}

fn invalid(field: &str, message: String) -> LibraryError {
    LibraryError::Invalid {
        field: field.into(),
        message,
    }
}

impl StateLaw {
    /// The law's name in term names: `maxwell`, `bouc_wen` or `dahl`.
    pub fn name(&self) -> &'static str {
        match self {
            StateLaw::Maxwell { .. } => "maxwell",
            StateLaw::BoucWen { .. } => "bouc_wen",
            StateLaw::Dahl { .. } => "dahl",
        }
    }

    /// Names of the parameters [`StateLaw::params`] returns (the refinable ones: ν of Bouc–Wen
    /// is a fixed shape exponent and not among them).
    pub fn param_names(&self) -> &'static [&'static str] {
        match self {
            StateLaw::Maxwell { .. } => &["tau"],
            StateLaw::BoucWen { .. } => &["a", "b"],
            StateLaw::Dahl { .. } => &["kappa"],
        }
    }

    /// The refinable parameters, in [`StateLaw::param_names`] order.
    pub fn params(&self) -> Vec<f64> {
        match *self {
            StateLaw::Maxwell { tau } => vec![tau],
            StateLaw::BoucWen { a, b, .. } => vec![a, b],
            StateLaw::Dahl { kappa } => vec![kappa],
        }
    }

    /// The same law with the refinable parameters `p` (validated).
    pub fn with_params(&self, p: &[f64]) -> Result<Self> {
        if p.len() != self.param_names().len() {
            return Err(invalid(
                "state parameters",
                format!(
                    "{} takes {} parameters ({}), {} given",
                    self.name(),
                    self.param_names().len(),
                    self.param_names().join(", "),
                    p.len()
                ),
            ));
        }
        let out = match *self {
            StateLaw::Maxwell { .. } => StateLaw::Maxwell { tau: p[0] },
            StateLaw::BoucWen { nu, .. } => StateLaw::BoucWen {
                a: p[0],
                b: p[1],
                nu,
            },
            StateLaw::Dahl { .. } => StateLaw::Dahl { kappa: p[0] },
        };
        out.validate()?;
        Ok(out)
    }

    /// Checks the parameters: τ, κ positive and finite; a, b finite; ν finite and ≥ 1.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str, v: f64, need: &str| {
            Err(invalid(
                &format!("{}({what})", self.name()),
                format!("{what} = {v}: {need}"),
            ))
        };
        match *self {
            StateLaw::Maxwell { tau } if !(tau > 0.0 && tau.is_finite()) => bad(
                "tau",
                tau,
                "the time constant must be positive and finite (seconds)",
            ),
            StateLaw::Dahl { kappa } if !(kappa > 0.0 && kappa.is_finite()) => bad(
                "kappa",
                kappa,
                "the inverse presliding displacement must be positive and finite",
            ),
            StateLaw::BoucWen { a, .. } if !a.is_finite() => bad("a", a, "must be finite"),
            StateLaw::BoucWen { b, .. } if !b.is_finite() => bad("b", b, "must be finite"),
            StateLaw::BoucWen { nu, .. } if !(nu.is_finite() && nu >= 1.0) => bad(
                "nu",
                nu,
                "the exponent must be finite and at least 1 (1 is the usual choice)",
            ),
            _ => Ok(()),
        }
    }

    /// `|z|^(ν−1)` without a power call for ν = 1 and 2.
    #[inline]
    fn pow_m1(z: f64, nu: f64) -> f64 {
        if nu == 1.0 {
            1.0
        } else if nu == 2.0 {
            z.abs()
        } else {
            z.abs().powf(nu - 1.0)
        }
    }

    /// The rate `g(q', z)`.
    #[inline]
    pub fn rate(&self, q: f64, z: f64) -> f64 {
        match *self {
            StateLaw::Maxwell { tau } => (q - z) / tau,
            StateLaw::BoucWen { a, b, nu } => {
                let p = Self::pow_m1(z, nu);
                q - a * q.abs() * p * z - b * q * p * z.abs()
            }
            StateLaw::Dahl { kappa } => kappa * (q - q.abs() * z),
        }
    }

    /// `(∂g/∂q', ∂g/∂z)` at `(q', z)` (the derivative of `|s|` is taken as `sign(s)`).
    #[inline]
    pub fn rate_jacobian(&self, q: f64, z: f64) -> (f64, f64) {
        match *self {
            StateLaw::Maxwell { tau } => (1.0 / tau, -1.0 / tau),
            StateLaw::BoucWen { a, b, nu } => {
                let p = Self::pow_m1(z, nu);
                let dq = 1.0 - a * sign0(q) * p * z - b * p * z.abs();
                let dz = -nu * p * (a * q.abs() + b * q * sign0(z));
                (dq, dz)
            }
            StateLaw::Dahl { kappa } => (kappa * (1.0 - sign0(q) * z), -kappa * q.abs()),
        }
    }

    /// `∂g/∂p_r` for the refinable parameters `p` ([`StateLaw::params`] order) into `out`.
    #[inline]
    pub fn rate_gradient(&self, q: f64, z: f64, out: &mut [f64]) {
        match *self {
            StateLaw::Maxwell { tau } => out[0] = -(q - z) / (tau * tau),
            StateLaw::BoucWen { nu, .. } => {
                let p = Self::pow_m1(z, nu);
                out[0] = -q.abs() * p * z;
                out[1] = -q * p * z.abs();
            }
            StateLaw::Dahl { .. } => out[0] = q - q.abs() * z,
        }
    }

    /// A bound on `|∂g/∂z|` for drive speeds up to `|q'|` and states up to `|z|`: how fast the
    /// state relaxes (used to choose integration sub-steps).
    #[inline]
    fn stiffness(&self, q: f64, z: f64) -> f64 {
        match *self {
            StateLaw::Maxwell { tau } => 1.0 / tau,
            StateLaw::BoucWen { a, b, nu } => {
                nu * Self::pow_m1(z, nu) * q.abs() * (a.abs() + b.abs())
            }
            StateLaw::Dahl { kappa } => kappa * q.abs(),
        }
    }

    /// The state along a drive `q'` sampled every `dt` seconds, from `z = 0` at the first sample:
    /// exact for a piecewise-linear drive in the linear Maxwell law, classical RK4 on the
    /// linearly interpolated drive otherwise, split where the drive reverses and with enough
    /// sub-steps that each stays well inside the law's relaxation time (at most 64 per piece).
    pub fn integrate(&self, q: &[f64], dt: f64) -> Vec<f64> {
        let mut out = Vec::with_capacity(q.len());
        if q.is_empty() {
            return out;
        }
        let mut z = 0.0;
        out.push(z);
        if let StateLaw::Maxwell { tau } = *self {
            let e = (-dt / tau).exp();
            let c = tau / dt * (1.0 - e);
            for w in q.windows(2) {
                // z' = (q − z)/τ with q linear over the step, solved exactly.
                z = e * z + (1.0 - e) * w[0] + (w[1] - w[0]) * (1.0 - c);
                out.push(z);
            }
            return out;
        }
        for w in q.windows(2) {
            let (q0, q1) = (w[0], w[1]);
            // The rate has a kink where the drive reverses (|q'|): the step is split there, so
            // each piece is smooth and RK4 keeps its order at the tips of a loop.
            let cross = if q0 * q1 < 0.0 { q0 / (q0 - q1) } else { 1.0 };
            for (f0, f1) in [(0.0, cross), (cross, 1.0)] {
                if f1 <= f0 {
                    continue;
                }
                let at = |fr: f64| q0 + (q1 - q0) * fr;
                let span = (f1 - f0) * dt;
                let k = self.stiffness(
                    at(f0).abs().max(at(f1).abs()),
                    z.abs().max(1.0 / self.scale()),
                );
                let sub = ((k * span / 0.1).ceil() as usize).clamp(1, 64);
                let df = (f1 - f0) / sub as f64;
                for s in 0..sub {
                    let fa = f0 + s as f64 * df;
                    let step = |z: f64, fa: f64, d: f64| {
                        let h = d * dt;
                        let (qa, qm, qb) = (at(fa), at(fa + 0.5 * d), at(fa + d));
                        let k1 = self.rate(qa, z);
                        let k2 = self.rate(qm, z + 0.5 * h * k1);
                        let k3 = self.rate(qm, z + 0.5 * h * k2);
                        let k4 = self.rate(qb, z + h * k3);
                        z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                    };
                    let next = step(z, fa, df);
                    // The rate has a kink where the state crosses zero (|z|): a step that
                    // crosses is redone in two, split where the state's line crosses.
                    z = if z * next < 0.0 {
                        let th = z / (z - next);
                        let mid = step(z, fa, th * df);
                        step(mid, fa + th * df, (1.0 - th) * df)
                    } else {
                        next
                    };
                }
            }
            out.push(z);
        }
        out
    }

    /// The size of `z` where the law saturates, for the sub-step bound (∞ when it does not).
    fn scale(&self) -> f64 {
        match *self {
            StateLaw::Maxwell { .. } => f64::INFINITY,
            StateLaw::BoucWen { a, b, .. } => a.abs() + b.abs(),
            StateLaw::Dahl { .. } => 1.0,
        }
    }
}

#[inline]
fn sign0(v: f64) -> f64 {
    crate::term::sign0(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic Jacobian and parameter gradient against central differences.
    #[test]
    fn derivatives_match_differences() {
        let laws = [
            StateLaw::Maxwell { tau: 0.3 },
            StateLaw::BoucWen {
                a: 800.0,
                b: -1100.0,
                nu: 1.0,
            },
            StateLaw::BoucWen {
                a: 3.0,
                b: 1.0,
                nu: 2.5,
            },
            StateLaw::Dahl { kappa: 40.0 },
        ];
        for law in laws {
            for &(q, z) in &[(0.3, 0.02), (-0.7, 0.01), (0.2, -0.05), (-0.1, -0.3)] {
                let (dq, dz) = law.rate_jacobian(q, z);
                let h = 1e-7;
                let nq = (law.rate(q + h, z) - law.rate(q - h, z)) / (2.0 * h);
                let nz = (law.rate(q, z + h) - law.rate(q, z - h)) / (2.0 * h);
                assert!((dq - nq).abs() <= 1e-6 * (1.0 + nq.abs()), "{law:?} dq");
                assert!((dz - nz).abs() <= 1e-6 * (1.0 + nz.abs()), "{law:?} dz");
                let p = law.params();
                let mut g = vec![0.0; p.len()];
                law.rate_gradient(q, z, &mut g);
                for r in 0..p.len() {
                    let hr = 1e-6 * p[r].abs().max(1e-3);
                    let mut pp = p.clone();
                    pp[r] += hr;
                    let mut pm = p.clone();
                    pm[r] -= hr;
                    let up = law.with_params(&pp).unwrap().rate(q, z);
                    let dn = law.with_params(&pm).unwrap().rate(q, z);
                    let num = (up - dn) / (2.0 * hr);
                    assert!(
                        (g[r] - num).abs() <= 1e-5 * (1.0 + num.abs()),
                        "{law:?} param {r}: {} vs {num}",
                        g[r]
                    );
                }
            }
        }
    }

    /// Along a sampled drive the integration agrees with a fine reference: Maxwell against its
    /// closed form for a sine drive, Bouc–Wen and Dahl against RK4 at 200 sub-steps per sample.
    #[test]
    fn integration_matches_references() {
        let dt = 1.0 / 750.0;
        let n = 3000;
        let w = 2.0 * std::f64::consts::PI * 35.0;
        let amp = 5e-4;
        let q: Vec<f64> = (0..n)
            .map(|k| amp * w * (w * k as f64 * dt).cos())
            .collect();
        // Maxwell: z' = (q − z)/τ with q = A cos(ωt), z(0) = 0, at 5 Hz (150 samples a period,
        // so the linear interpolation of the drive between samples costs ~1e-4 of it).
        let tau = 0.01;
        let w = 2.0 * std::f64::consts::PI * 5.0;
        let qm: Vec<f64> = (0..n)
            .map(|k| amp * w * (w * k as f64 * dt).cos())
            .collect();
        let z = StateLaw::Maxwell { tau }.integrate(&qm, dt);
        let a = amp * w;
        let den = 1.0 + (w * tau).powi(2);
        for (k, zk) in z.iter().enumerate() {
            let t = k as f64 * dt;
            let steady = a * ((w * t).cos() + w * tau * (w * t).sin()) / den;
            let exact = steady - a / den * (-t / tau).exp();
            // Linear interpolation of the drive between samples is the only error.
            assert!(
                (zk - exact).abs() < 3e-4 * a,
                "maxwell at {k}: {zk} vs {exact}"
            );
        }
        for law in [
            StateLaw::BoucWen {
                a: 800.0,
                b: -1100.0,
                nu: 1.0,
            },
            StateLaw::BoucWen {
                a: 6000.0,
                b: 2000.0,
                nu: 1.0,
            },
            StateLaw::Dahl { kappa: 5000.0 },
        ] {
            let z = law.integrate(&q, dt);
            // Reference: the same interpolated drive, 2000 RK4 steps per sample (a reversal of
            // the drive inside a step costs it O(h²)).
            let mut zr = 0.0;
            let sub = 2000;
            let h = dt / sub as f64;
            let scale = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for k in 0..n - 1 {
                for s in 0..sub {
                    let f = |fr: f64| q[k] + (q[k + 1] - q[k]) * fr;
                    let (qa, qm, qb) = (
                        f(s as f64 / sub as f64),
                        f((s as f64 + 0.5) / sub as f64),
                        f((s + 1) as f64 / sub as f64),
                    );
                    let k1 = law.rate(qa, zr);
                    let k2 = law.rate(qm, zr + 0.5 * h * k1);
                    let k3 = law.rate(qm, zr + 0.5 * h * k2);
                    let k4 = law.rate(qb, zr + h * k3);
                    zr += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                }
                assert!(
                    (z[k + 1] - zr).abs() < 2e-5 * scale,
                    "{law:?} at {k}: {} vs {zr}",
                    z[k + 1]
                );
            }
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = StateLaw::Maxwell { tau: 0.0 }.validate().unwrap_err();
        assert!(e.to_string().contains("tau"), "{e}");
        let e = StateLaw::BoucWen {
            a: 1.0,
            b: 1.0,
            nu: 0.5,
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("nu"), "{e}");
        assert!(
            StateLaw::Dahl { kappa: 1.0 }
                .with_params(&[1.0, 2.0])
                .is_err()
        );
    }
}
