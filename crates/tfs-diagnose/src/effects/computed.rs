//! Columns computed from a record's inputs (delayed or filtered inputs), named so that a refitted
//! model stays a plain `tfs-model/1` file, and the upgrade of model files that still name a
//! Maxwell element as a computed column.

use tfs_data::Columns;
use tfs_library::{Equation, Factor, Model, ModelTerm, StateLaw, Term, Var};

use crate::{DiagnoseError, Result};

/// A column computed from a record's input rather than read from it.
#[derive(Debug, Clone, PartialEq)]
pub enum ComputedColumn {
    /// Input column `input` delayed by `delay` seconds (the first value is held before the start).
    Delayed {
        /// The input column.
        input: String,
        /// Delay in seconds.
        delay: f64,
    },
    /// Input column `input` low-pass filtered with time constant `tau` seconds (`τ y' + y = u`,
    /// starting from `y = u₀`): the first-order dynamics of an exciter or amplifier.
    Lowpass {
        /// The input column.
        input: String,
        /// Time constant in seconds.
        tau: f64,
    },
}

/// Rounds to 3 significant digits.
pub(crate) fn round3(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    format!("{v:.2e}").parse().unwrap_or(v)
}

fn encode(v: f64) -> String {
    let s = format!("{}", round3(v));
    let s = if s.contains('e') {
        format!("{:.6}", round3(v))
            .trim_end_matches('0')
            .to_string()
    } else {
        s
    };
    s.replace('.', "p").replace('-', "m")
}

fn decode(s: &str) -> Option<f64> {
    let v: f64 = s.replace('p', ".").replace('m', "-").parse().ok()?;
    (v.is_finite() && v > 0.0).then_some(v)
}

impl ComputedColumn {
    /// The column name: `<input>_delay_<δ>` or `<input>_lowpass_<τ>`, numbers with `p` for the
    /// decimal point (`0.35` → `0p35`).
    pub fn name(&self) -> String {
        match self {
            ComputedColumn::Delayed { input, delay } => {
                format!("{input}_delay_{}", encode(*delay))
            }
            ComputedColumn::Lowpass { input, tau } => {
                format!("{input}_lowpass_{}", encode(*tau))
            }
        }
    }

    /// Recognises a computed column name.
    pub fn parse(name: &str) -> Option<Self> {
        if let Some((input, delay)) = name.rsplit_once("_delay_")
            && !input.is_empty()
        {
            return Some(ComputedColumn::Delayed {
                input: input.to_string(),
                delay: decode(delay)?,
            });
        }
        if let Some((input, tau)) = name.rsplit_once("_lowpass_")
            && !input.is_empty()
        {
            return Some(ComputedColumn::Lowpass {
                input: input.to_string(),
                tau: decode(tau)?,
            });
        }
        None
    }

    /// The input column this one is computed from.
    pub fn source(&self) -> String {
        match self {
            ComputedColumn::Delayed { input, .. } | ComputedColumn::Lowpass { input, .. } => {
                input.clone()
            }
        }
    }

    /// Computes the column from `cols` (which must hold [`ComputedColumn::source`]) sampled
    /// every `dt` seconds.
    pub fn compute(&self, cols: &dyn Columns, dt: f64) -> Result<Vec<f64>> {
        let src = self.source();
        let s = cols
            .column(&src)
            .ok_or_else(|| DiagnoseError::InvalidParameter {
                name: "record",
                reason: format!(
                    "column '{src}' is needed to compute '{}' but is missing",
                    self.name()
                ),
            })?;
        Ok(match self {
            ComputedColumn::Delayed { delay, .. } => delayed(s, dt, *delay),
            ComputedColumn::Lowpass { tau, .. } => lowpass(s, dt, *tau),
        })
    }
}

/// First-order low-pass `τ y' + y = v`, exact for a piecewise-linear `v`, starting from `y = v₀`.
pub fn lowpass(v: &[f64], dt: f64, tau: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(v.len());
    let Some(&first) = v.first() else {
        return out;
    };
    let a = (-dt / tau).exp();
    let b = tau / dt * (1.0 - a);
    let mut y = first;
    out.push(y);
    for w in v.windows(2) {
        let (v0, v1) = (w[0], w[1]);
        // Exact solution for v(t) = v0 + (v1 − v0) t/dt over one step.
        y = a * y + (1.0 - a) * v0 + (v1 - v0) * (1.0 - b);
        out.push(y);
    }
    out
}

/// Points of the Lagrange interpolation [`delayed`] reads between samples: from two before to
/// three after the interval.
const TAPS: [i64; 6] = [-2, -1, 0, 1, 2, 3];

/// `v(t − δ)` read between samples by six-point Lagrange interpolation (samples at the ends held
/// beyond them), holding the first value before the start; a whole-sample delay is an exact
/// shift. A sampled input is band-limited, and at ten samples a period linear interpolation
/// between samples loses up to 5 % of the amplitude half-way (it acts as a low-pass filter,
/// which a filter effect then mimics); the six-point interpolation loses less than 0.1 %.
pub fn delayed(v: &[f64], dt: f64, delay: f64) -> Vec<f64> {
    let shift = delay / dt;
    let last = v.len() as i64 - 1;
    let at = |i: i64| v[i.clamp(0, last) as usize];
    (0..v.len())
        .map(|k| {
            let s = k as f64 - shift;
            if s <= 0.0 {
                return v[0];
            }
            let i = s.floor() as i64;
            let f = s - i as f64;
            if f == 0.0 {
                return at(i);
            }
            TAPS.iter()
                .map(|&j| {
                    let w: f64 = TAPS
                        .iter()
                        .filter(|&&m| m != j)
                        .map(|&m| (f - m as f64) / (j - m) as f64)
                        .product();
                    w * at(i + j)
                })
                .sum()
        })
        .collect()
}

/// The computed columns a model uses (recognised among its inputs).
pub fn computed_columns(model: &Model) -> Vec<ComputedColumn> {
    model
        .inputs
        .iter()
        .filter_map(|n| ComputedColumn::parse(n))
        .collect()
}

/// A model file written before internal states were part of the term grammar named a hidden
/// Maxwell element as an input column `maxwell_<dof>_tau_<τ>` (the velocity of `<dof>` low-pass
/// filtered with time constant τ): every such term becomes the internal state
/// `maxwell(<dof>', τ)`, which simulates the same way (started at rest). Other models are
/// returned unchanged.
pub fn upgrade_legacy(model: &Model) -> Result<Model> {
    let legacy = |n: &str| -> Option<(String, f64)> {
        let rest = n.strip_prefix("maxwell_")?;
        let (dof, tau) = rest.rsplit_once("_tau_")?;
        model
            .dofs
            .iter()
            .any(|d| d == dof)
            .then(|| Some((dof.to_string(), decode(tau)?)))?
    };
    if !model.inputs.iter().any(|n| legacy(n).is_some()) {
        return Ok(model.clone());
    }
    let equations = model
        .equations
        .iter()
        .map(|e| Equation {
            dof: e.dof.clone(),
            terms: e
                .terms
                .iter()
                .map(|t| {
                    let factors = t
                        .term
                        .factors()
                        .iter()
                        .flat_map(|f| match f {
                            Factor::Pow(Var::Input(n), k) => match legacy(n) {
                                Some((dof, tau)) => {
                                    vec![
                                        Factor::State(Var::Vel(dof), StateLaw::Maxwell { tau });
                                        *k as usize
                                    ]
                                }
                                None => vec![f.clone()],
                            },
                            other => vec![other.clone()],
                        })
                        .collect();
                    ModelTerm {
                        term: Term::new(factors),
                        ..t.clone()
                    }
                })
                .collect(),
        })
        .collect();
    let mut m = Model::new(model.dofs.clone(), equations, model.method.clone())?;
    m.trace = model.trace.clone();
    m.history = model.history.clone();
    Ok(m)
}
