//! The two ground truths of a cell: the truss force itself (with the folded stop) and its
//! polynomial least-squares surrogate (the paper's simulated system), computed at run time.

use faer::Mat;
use serde::{Deserialize, Serialize};
use std::str::FromStr;
use std::sync::Arc;

use crate::cell::{KreslingCell, equilibria_1d};
use crate::{OrigamiError, Result};

/// Which force law a simulation uses as the truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Truth {
    /// The tabulated truss force with the folded stop at `h < 0`.
    #[default]
    Truss,
    /// The `{h^5, h^6, h^7}` (or other powers) least-squares fit of the truss force.
    Surrogate,
}

impl Truth {
    /// The label recorded with every simulation: `"truss"` or `"surrogate"`.
    pub fn label(self) -> &'static str {
        match self {
            Truth::Truss => "truss",
            Truth::Surrogate => "surrogate",
        }
    }
}

impl FromStr for Truth {
    type Err = OrigamiError;
    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "truss" => Ok(Truth::Truss),
            "surrogate" => Ok(Truth::Surrogate),
            other => Err(OrigamiError::Param(format!(
                "truth '{other}' is unknown; use 'truss' or 'surrogate'"
            ))),
        }
    }
}

/// How the surrogate is fitted: powers of `h`, range and number of uniform samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SurrogateSpec {
    /// Powers of `h` in the basis (default `[5, 6, 7]`, the paper's Table 1 terms).
    pub powers: Vec<u32>,
    /// Lower end of the fitting range (default 0).
    pub h_lo: f64,
    /// Upper end of the fitting range (default 1.7).
    pub h_hi: f64,
    /// Number of uniformly spaced samples, ends included (default 17001).
    pub samples: usize,
}

impl Default for SurrogateSpec {
    fn default() -> Self {
        Self {
            powers: vec![5, 6, 7],
            h_lo: 0.0,
            h_hi: 1.7,
            samples: 17001,
        }
    }
}

/// A polynomial force `F(h) = Σ c_k h^{p_k}` fitted to a truss cell (pure polynomial for all `h`,
/// no stop: this is the paper's simulated system).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Surrogate {
    /// The fitting specification.
    pub spec: SurrogateSpec,
    /// Coefficients, one per power in `spec.powers`.
    pub coefs: Vec<f64>,
    /// RMS of the fit residual on the samples.
    pub rms_residual: f64,
}

impl Surrogate {
    /// Uniformly weighted least-squares fit of the cell's truss force (faer column-pivoted QR via
    /// `tfs_regress::lstsq`).
    pub fn fit(cell: &KreslingCell, spec: &SurrogateSpec) -> Result<Self> {
        if spec.powers.is_empty() {
            return Err(OrigamiError::Param(
                "surrogate 'powers' is empty; give at least one power of h, e.g. [5, 6, 7]".into(),
            ));
        }
        if !(spec.h_lo.is_finite() && spec.h_hi.is_finite() && spec.h_hi > spec.h_lo) {
            return Err(OrigamiError::Param(format!(
                "surrogate range [{}, {}] must be finite with h_lo < h_hi",
                spec.h_lo, spec.h_hi
            )));
        }
        if spec.samples < 2 * spec.powers.len() {
            return Err(OrigamiError::Param(format!(
                "surrogate 'samples' = {} is too few for {} powers; use at least {}",
                spec.samples,
                spec.powers.len(),
                2 * spec.powers.len()
            )));
        }
        let n = spec.samples;
        let h: Vec<f64> = (0..n)
            .map(|i| spec.h_lo + (spec.h_hi - spec.h_lo) * i as f64 / (n - 1) as f64)
            .collect();
        let f: Vec<f64> = h.iter().map(|&x| cell.force(x)).collect();
        let a = Mat::from_fn(n, spec.powers.len(), |i, j| {
            h[i].powi(spec.powers[j] as i32)
        });
        let fit = tfs_regress::lstsq(a.as_ref(), &f)
            .map_err(|e| OrigamiError::Numeric(format!("surrogate least squares: {e}")))?;
        let coefs = fit.coef;
        let rms_residual = (fit.rss / n as f64).sqrt();
        Ok(Self {
            spec: spec.clone(),
            coefs,
            rms_residual,
        })
    }

    /// `F(h)`.
    #[inline]
    pub fn force(&self, h: f64) -> f64 {
        self.spec
            .powers
            .iter()
            .zip(&self.coefs)
            .map(|(&p, &c)| c * h.powi(p as i32))
            .sum()
    }

    /// `dF/dh`.
    pub fn stiffness(&self, h: f64) -> f64 {
        self.spec
            .powers
            .iter()
            .zip(&self.coefs)
            .filter(|(p, _)| **p > 0)
            .map(|(&p, &c)| c * p as f64 * h.powi(p as i32 - 1))
            .sum()
    }

    /// `V(h) = Σ c_k h^{p_k+1} / (p_k+1)`, so `V(0) = 0`.
    pub fn potential(&self, h: f64) -> f64 {
        self.spec
            .powers
            .iter()
            .zip(&self.coefs)
            .map(|(&p, &c)| c * h.powi(p as i32 + 1) / (p as f64 + 1.0))
            .sum()
    }

    /// Label such as `"surrogate{5,6,7}"`.
    pub fn label(&self) -> String {
        let p: Vec<String> = self.spec.powers.iter().map(|p| p.to_string()).collect();
        format!("surrogate{{{}}}", p.join(","))
    }
}

/// The force law of one cell under a chosen truth.
#[derive(Debug, Clone)]
pub enum CellForce {
    /// Tabulated truss force with the folded stop.
    Truss(Arc<KreslingCell>),
    /// Polynomial surrogate.
    Surrogate(Surrogate),
}

impl CellForce {
    /// Builds the force for `truth` (the surrogate uses the default [`SurrogateSpec`]).
    pub fn new(cell: Arc<KreslingCell>, truth: Truth) -> Result<Self> {
        match truth {
            Truth::Truss => Ok(CellForce::Truss(cell)),
            Truth::Surrogate => Ok(CellForce::Surrogate(Surrogate::fit(
                &cell,
                &SurrogateSpec::default(),
            )?)),
        }
    }

    /// Restoring force `F(h)`.
    #[inline]
    pub fn force(&self, h: f64) -> f64 {
        match self {
            CellForce::Truss(c) => c.force(h),
            CellForce::Surrogate(s) => s.force(h),
        }
    }

    /// `dF/dh`.
    pub fn stiffness(&self, h: f64) -> f64 {
        match self {
            CellForce::Truss(c) => c.stiffness(h),
            CellForce::Surrogate(s) => s.stiffness(h),
        }
    }

    /// Potential with `V(0) = 0`.
    pub fn potential(&self, h: f64) -> f64 {
        match self {
            CellForce::Truss(c) => c.potential(h),
            CellForce::Surrogate(s) => s.potential(h),
        }
    }

    /// Which truth this is.
    pub fn truth(&self) -> Truth {
        match self {
            CellForce::Truss(_) => Truth::Truss,
            CellForce::Surrogate(_) => Truth::Surrogate,
        }
    }

    /// Label: `"truss"` or e.g. `"surrogate{5,6,7}"`.
    pub fn label(&self) -> String {
        match self {
            CellForce::Truss(_) => "truss".into(),
            CellForce::Surrogate(s) => s.label(),
        }
    }

    /// Stable and unstable equilibria `(stable, unstable)`. Truss: the cell's own (on
    /// `[0, h_max]`); surrogate: roots on its fitting range widened by 25% each side.
    pub fn equilibria(&self) -> (Vec<f64>, Vec<f64>) {
        match self {
            CellForce::Truss(c) => (c.stable().to_vec(), c.unstable().to_vec()),
            CellForce::Surrogate(s) => {
                let w = s.spec.h_hi - s.spec.h_lo;
                equilibria_1d(
                    |h| s.force(h),
                    s.spec.h_lo - 0.25 * w,
                    s.spec.h_hi + 0.25 * w,
                    4000,
                )
            }
        }
    }
}
