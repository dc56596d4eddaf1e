//! Window functions sampled together with their analytic first and second time derivatives.
//!
//! A window spans the whole record: sample `k` of `n` sits at normalised position
//! `s = k/(n−1) ∈ [0, 1]`, i.e. time `t = k·dt` over the duration `T = (n−1)·dt`. Derivatives are
//! with respect to time, `dw/dt = (1/T)·dw/ds`, `d²w/dt² = (1/T²)·d²w/ds²`.

use crate::{Result, SignalError, check_dt, invalid};
use std::f64::consts::PI;

/// A window shape on the normalised interval `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Window {
    /// `w = 1` (no taper). Does not vanish at the ends.
    Rectangular,
    /// `w = sin²(πs)`; `w` and `w'` vanish at both ends (`w''` does not).
    Hann,
    /// `w = sin⁴(πs)`; `w`, `w'` and `w''` vanish at both ends.
    HannSquared,
    /// Tukey (tapered cosine): flat top, raised-cosine tapers on a fraction `alpha ∈ [0, 1]`
    /// of the record (half at each end). `alpha = 0` is rectangular, `alpha = 1` is Hann.
    /// For `alpha > 0`, `w` and `w'` vanish at both ends; `w''` jumps where the tapers meet the top.
    Tukey {
        /// Tapered fraction of the record, in `[0, 1]`.
        alpha: f64,
    },
    /// Polynomial bump `w = (4s(1−s))^p` (peak 1 at the centre). For `p ≥ 2`, `w` and `w'`
    /// vanish at both ends; for `p ≥ 3`, `w''` vanishes too.
    Bump {
        /// Exponent `p ≥ 1`.
        p: u32,
    },
}

/// A sampled window with analytic time derivatives (all of length `n`).
#[derive(Debug, Clone, PartialEq)]
pub struct WindowSamples {
    /// Window values `w(t_k)`.
    pub w: Vec<f64>,
    /// First time derivative `dw/dt (t_k)` in 1/s.
    pub dw: Vec<f64>,
    /// Second time derivative `d²w/dt² (t_k)` in 1/s².
    pub ddw: Vec<f64>,
}

impl Window {
    /// Checks the shape parameters (`alpha ∈ [0, 1]`, `p ≥ 1`).
    pub fn validate(&self) -> Result<()> {
        match *self {
            Window::Tukey { alpha } if !(alpha.is_finite() && (0.0..=1.0).contains(&alpha)) => {
                Err(invalid(
                    "alpha",
                    alpha,
                    "the Tukey taper fraction must lie in [0, 1]",
                ))
            }
            Window::Bump { p: 0 } => Err(invalid(
                "p",
                0,
                "the bump exponent must be at least 1 (use ≥ 3 for derivative transfer with vanishing w'')",
            )),
            _ => Ok(()),
        }
    }

    /// True when `w` and `w'` vanish at both ends, so the derivative-transfer identities
    /// `∫ x' w e^{−iωt} = −∫ x (w' − iωw) e^{−iωt}` and
    /// `∫ x'' w e^{−iωt} = ∫ x (w'' − 2iωw' − ω²w) e^{−iωt}` hold without boundary terms.
    pub fn supports_derivative_transfer(&self) -> bool {
        match *self {
            Window::Rectangular => false,
            Window::Hann | Window::HannSquared => true,
            Window::Tukey { alpha } => alpha > 0.0 && alpha <= 1.0,
            Window::Bump { p } => p >= 2,
        }
    }

    /// Value and first two derivatives with respect to the normalised position `s ∈ [0, 1]`.
    /// Outside `[0, 1]` all three are zero. The shape must be valid (see [`Window::validate`]).
    pub fn eval_unit(&self, s: f64) -> (f64, f64, f64) {
        if !(0.0..=1.0).contains(&s) {
            return (0.0, 0.0, 0.0);
        }
        match *self {
            Window::Rectangular => (1.0, 0.0, 0.0),
            Window::Hann => hann(s),
            Window::HannSquared => {
                let (sn, cs) = (PI * s).sin_cos();
                (
                    sn.powi(4),
                    4.0 * PI * sn.powi(3) * cs,
                    4.0 * PI * PI * (3.0 * sn * sn * cs * cs - sn.powi(4)),
                )
            }
            Window::Tukey { alpha } => {
                if alpha <= 0.0 {
                    return (1.0, 0.0, 0.0);
                }
                let half = alpha / 2.0;
                if s < half {
                    let (w, d, dd) = hann(s / alpha);
                    (w, d / alpha, dd / (alpha * alpha))
                } else if s > 1.0 - half {
                    let (w, d, dd) = hann((1.0 - s) / alpha);
                    (w, -d / alpha, dd / (alpha * alpha))
                } else {
                    (1.0, 0.0, 0.0)
                }
            }
            Window::Bump { p } => {
                let u = 4.0 * s * (1.0 - s);
                let du = 4.0 * (1.0 - 2.0 * s);
                let ddu = -8.0;
                let pf = p as f64;
                let w = u.powi(p as i32);
                let dw = pf * u.powi(p as i32 - 1) * du;
                let ddw = if p >= 2 {
                    pf * (pf - 1.0) * u.powi(p as i32 - 2) * du * du
                        + pf * u.powi(p as i32 - 1) * ddu
                } else {
                    pf * ddu
                };
                (w, dw, ddw)
            }
        }
    }

    /// Samples the window over `n ≥ 2` points spaced `dt` seconds apart, with analytic time
    /// derivatives (see the module docs for the time scaling).
    pub fn sample(&self, n: usize, dt: f64) -> Result<WindowSamples> {
        self.validate()?;
        check_dt(dt)?;
        if n < 2 {
            return Err(SignalError::TooShort {
                what: "window length",
                needed: 2,
                got: n,
            });
        }
        let span = (n - 1) as f64 * dt;
        let (mut w, mut dw, mut ddw) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for k in 0..n {
            let s = if k == n - 1 {
                1.0
            } else {
                k as f64 / (n - 1) as f64
            };
            let (a, b, c) = self.eval_unit(s);
            w.push(a);
            dw.push(b / span);
            ddw.push(c / (span * span));
        }
        Ok(WindowSamples { w, dw, ddw })
    }
}

impl Window {
    /// Samples the window as a periodic one over `len` points spaced `dt` apart: sample `k` sits
    /// at `s = k/len`, so the window returns to its start value one step past the last sample
    /// (what a `len`-point transform sees), with time derivatives over the span `len·dt`. For
    /// [`Window::HannSquared`] the value and first two derivatives vanish at `s = 0` and `s = 1`.
    pub fn sample_periodic(&self, len: usize, dt: f64) -> Result<WindowSamples> {
        self.validate()?;
        check_dt(dt)?;
        if len < 2 {
            return Err(SignalError::TooShort {
                what: "window length",
                needed: 2,
                got: len,
            });
        }
        let l = len as f64 * dt;
        let (mut w, mut dw, mut ddw) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
        for i in 0..len {
            let (a, b, c) = self.eval_unit(i as f64 / len as f64);
            w[i] = a;
            dw[i] = b / l;
            ddw[i] = c / (l * l);
        }
        Ok(WindowSamples { w, dw, ddw })
    }
}

/// Hann `sin²(πs)` with derivatives in `s`; exact zeros at the ends.
fn hann(s: f64) -> (f64, f64, f64) {
    let sn = (PI * s).sin();
    let (s2, c2) = (2.0 * PI * s).sin_cos();
    let w = if s == 0.0 || s == 1.0 { 0.0 } else { sn * sn };
    let d = if s == 0.0 || s == 1.0 { 0.0 } else { PI * s2 };
    (w, d, 2.0 * PI * PI * c2)
}
