//! Restoring force, stiffness and potential of a model along one DOF.
//!
//! For the equation `x'' = Σ_j c_j θ_j(x, x', u)` the restoring force per unit mass along DOF `x`
//! is `F(x) = −x''(x, x' = 0, u = 0)` with every other DOF held at 0: the force of Eq. (16)'s
//! `x'' + ζx' + αx^5 + … = 0` is `F = αx^5 + …` (the fitted coefficient of `x^5` is `−α`).
//! Every velocity or input factor vanishes at rest (`v^k`, `abs(0)`, `sign(0)`, `tanh(0)` are all
//! 0), and a relative coordinate `(x-xb)` or `(x2-x)` reduces to `±x`. The potential is
//! `V(x) = ∫_0^x F(s) ds`, so `V(0) = 0` and `V' = F`.
//!
//! Polynomial terms are integrated exactly. Terms with `abs`, `sign` or `tanh` of the coordinate
//! are integrated numerically (composite 8-point Gauss–Legendre on 128 panels graded towards 0,
//! where those functions have their kink or steep part); their `stiffness` uses the analytic
//! derivative (`sign` has derivative 0 away from 0).
//!
//! For a chain this is the slice of the force field along one DOF with the others at zero; it is a
//! true potential of that slice. Potentials in other relative coordinates are not provided.

use crate::model::Model;
use crate::term::{Coord, Factor, Var, pow_u};
use crate::{LibraryError, Result};

/// A real polynomial `Σ c_k x^k` with coefficients in ascending order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Polynomial {
    coeffs: Vec<f64>,
}

impl Polynomial {
    /// From ascending coefficients (`[c0, c1, …]`); trailing zeros are trimmed.
    pub fn new(mut coeffs: Vec<f64>) -> Self {
        while coeffs.last() == Some(&0.0) {
            coeffs.pop();
        }
        Self { coeffs }
    }

    /// Ascending coefficients.
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs
    }

    /// Degree (`None` for the zero polynomial).
    pub fn degree(&self) -> Option<usize> {
        self.coeffs.len().checked_sub(1)
    }

    /// Value at `x` (Horner).
    pub fn eval(&self, x: f64) -> f64 {
        self.coeffs.iter().rev().fold(0.0, |acc, c| acc * x + c)
    }

    /// The derivative.
    pub fn derivative(&self) -> Polynomial {
        Polynomial::new(
            self.coeffs
                .iter()
                .enumerate()
                .skip(1)
                .map(|(k, c)| c * k as f64)
                .collect(),
        )
    }

    /// The antiderivative vanishing at 0.
    pub fn integral(&self) -> Polynomial {
        let mut c = vec![0.0];
        c.extend(
            self.coeffs
                .iter()
                .enumerate()
                .map(|(k, c)| c / (k + 1) as f64),
        );
        Polynomial::new(c)
    }

    /// Adds `c·x^k`.
    pub fn add_monomial(&mut self, c: f64, k: usize) {
        if self.coeffs.len() <= k {
            self.coeffs.resize(k + 1, 0.0);
        }
        self.coeffs[k] += c;
    }

    /// Scales every coefficient.
    pub fn scaled(&self, s: f64) -> Polynomial {
        Polynomial::new(self.coeffs.iter().map(|c| c * s).collect())
    }
}

#[derive(Debug, Clone)]
enum SliceKind {
    Pow(u32),
    /// Any other factor, evaluated through [`Factor::apply`] and [`Factor::derivative`].
    Other(Factor),
}

/// The restoring force of one DOF, prepared for repeated evaluation (see the module docs).
#[derive(Debug, Clone)]
pub struct Restoring {
    dof: String,
    /// Exact polynomial part of `F`.
    force_poly: Polynomial,
    /// Antiderivative of `force_poly`.
    potential_poly: Polynomial,
    /// Non-polynomial part of `F`: coefficient and factors `f(s·x)`.
    other: Vec<(f64, Vec<(f64, SliceKind)>)>,
}

/// 8-point Gauss–Legendre nodes and weights on [-1, 1].
const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

impl Restoring {
    /// The DOF this restoring force belongs to.
    pub fn dof(&self) -> &str {
        &self.dof
    }

    /// The polynomial `F` if every surviving term is polynomial.
    pub fn polynomial(&self) -> Option<&Polynomial> {
        self.other.is_empty().then_some(&self.force_poly)
    }

    fn other_force(&self, x: f64) -> f64 {
        self.other
            .iter()
            .map(|(c, fs)| {
                -c * fs
                    .iter()
                    .map(|(s, k)| {
                        let y = s * x;
                        match k {
                            SliceKind::Pow(k) => pow_u(y, *k),
                            SliceKind::Other(f) => f.apply(y),
                        }
                    })
                    .product::<f64>()
            })
            .sum()
    }

    /// Restoring force per unit mass `F(x)`.
    pub fn force(&self, x: f64) -> f64 {
        self.force_poly.eval(x) + self.other_force(x)
    }

    /// Stiffness `dF/dx`.
    pub fn stiffness(&self, x: f64) -> f64 {
        let mut k = self.force_poly.derivative().eval(x);
        for (c, fs) in &self.other {
            // Product rule over the factors.
            let vals: Vec<(f64, f64)> = fs
                .iter()
                .map(|(s, kind)| {
                    let y = s * x;
                    match kind {
                        SliceKind::Pow(p) => (pow_u(y, *p), s * f64::from(*p) * pow_u(y, p - 1)),
                        SliceKind::Other(f) => (f.apply(y), s * f.derivative(y)),
                    }
                })
                .collect();
            let mut d = 0.0;
            for i in 0..vals.len() {
                let mut p = vals[i].1;
                for (j, v) in vals.iter().enumerate() {
                    if j != i {
                        p *= v.0;
                    }
                }
                d += p;
            }
            k -= c * d;
        }
        k
    }

    /// Potential `V(x) = ∫_0^x F`, with `V(0) = 0`.
    pub fn potential(&self, x: f64) -> f64 {
        let mut v = self.potential_poly.eval(x);
        if !self.other.is_empty() && x != 0.0 {
            // Integrate piece by piece between the kinks of the stops (a quadrature across a
            // kink is inaccurate, and its error would move with x), each piece on panels that
            // are finer at its start.
            let mut cuts: Vec<f64> = self
                .kinks()
                .filter(|k| k.abs() < x.abs() && k * x > 0.0)
                .collect();
            cuts.push(0.0);
            cuts.push(x);
            cuts.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
            const N: usize = 128;
            let mut sum = 0.0;
            for piece in cuts.windows(2) {
                let (x0, len) = (piece[0], piece[1] - piece[0]);
                if len == 0.0 {
                    continue;
                }
                for i in 0..N {
                    let a = x0 + len * (i as f64 / N as f64).powi(2);
                    let b = x0 + len * ((i + 1) as f64 / N as f64).powi(2);
                    let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
                    for (t, w) in GL8 {
                        sum += w * h * self.other_force(m + h * t);
                    }
                }
            }
            v += sum;
        }
        v
    }

    /// Positions along the DOF where a one-sided stop of the non-polynomial part starts acting.
    fn kinks(&self) -> impl Iterator<Item = f64> + '_ {
        self.other.iter().flat_map(|(_, fs)| {
            fs.iter().filter_map(|(s, k)| match k {
                SliceKind::Other(Factor::Below(_, c) | Factor::Above(_, c)) if *s != 0.0 => {
                    Some(c / s)
                }
                _ => None,
            })
        })
    }
}

impl Model {
    /// Prepares the restoring force of `dof` (module docs give the definition).
    pub fn restoring(&self, dof: &str) -> Result<Restoring> {
        let eq = self.equation(dof)?;
        let mut force_poly = Polynomial::default();
        let mut other = Vec::new();
        'terms: for mt in &eq.terms {
            let mut factors = Vec::new();
            for f in mt.term.factors() {
                // Slope of the factor's argument along the DOF, with everything else at rest.
                let s = match f.var() {
                    Var::Disp(d) if d == dof => 1.0,
                    Var::RelDisp(a, _) if a == dof => 1.0,
                    Var::RelDisp(_, Coord::Dof(b)) if b == dof => -1.0,
                    // The argument is 0 at rest: a factor that vanishes there takes the term
                    // with it; one that does not (a stop at a non-zero position) is a constant.
                    _ if f.apply(0.0) == 0.0 => continue 'terms,
                    _ => 0.0,
                };
                let kind = match f {
                    Factor::Pow(_, k) => SliceKind::Pow(*k),
                    other => SliceKind::Other(other.clone()),
                };
                factors.push((s, kind));
            }
            if factors.iter().all(|(_, k)| matches!(k, SliceKind::Pow(_))) {
                let mut c = -mt.coef;
                let mut deg = 0usize;
                for (s, k) in &factors {
                    if let SliceKind::Pow(k) = k {
                        c *= pow_u(*s, *k);
                        deg += *k as usize;
                    }
                }
                force_poly.add_monomial(c, deg);
            } else {
                other.push((mt.coef, factors));
            }
        }
        let force_poly = Polynomial::new(force_poly.coeffs);
        let potential_poly = force_poly.integral();
        Ok(Restoring {
            dof: dof.to_string(),
            force_poly,
            potential_poly,
            other,
        })
    }

    /// Restoring force per unit mass `F(x) = −x''(x, 0, 0)` along `dof` (others at 0).
    pub fn restoring_force(&self, dof: &str, x: f64) -> Result<f64> {
        Ok(self.restoring(dof)?.force(check_x(x)?))
    }

    /// Stiffness `dF/dx` along `dof`.
    pub fn stiffness(&self, dof: &str, x: f64) -> Result<f64> {
        Ok(self.restoring(dof)?.stiffness(check_x(x)?))
    }

    /// Potential `V(x) = ∫_0^x F` along `dof` (`V(0) = 0`).
    pub fn potential(&self, dof: &str, x: f64) -> Result<f64> {
        Ok(self.restoring(dof)?.potential(check_x(x)?))
    }
}

fn check_x(x: f64) -> Result<f64> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(LibraryError::Invalid {
            field: "x".into(),
            message: format!("position {x} is not finite"),
        })
    }
}
