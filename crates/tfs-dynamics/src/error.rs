//! The crate's error type and `Result` alias.

/// Formats a state vector compactly for error messages.
fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.6e}")).collect();
    format!("[{}]", parts.join(", "))
}

/// Errors raised by integrators, inputs, equilibria and error metrics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DynError {
    /// The state became non-finite or left the allowed range.
    #[error(
        "simulation blew up at t = {t:.6} s (x = {}, v = {}); the model is unstable for this input",
        fmt_vec(.x),
        fmt_vec(.v)
    )]
    BlowUp {
        /// Time of the last finite state at or beyond the limit (s).
        t: f64,
        /// Displacements at that time.
        x: Vec<f64>,
        /// Velocities at that time.
        v: Vec<f64>,
    },
    /// A measured displacement left the band its record allows a run
    /// ([`crate::SimulateOptions::range`]): the model does not follow the record.
    #[error(
        "the simulation left the range of the record: {dof} = {x:.6e} at t = {t:.6} s, outside {lo:.6e} to {hi:.6e} (the record's own span widened on each side); the model does not follow this record under its input"
    )]
    LeftRange {
        /// Time of the first output sample outside the band (s).
        t: f64,
        /// The displacement's name.
        dof: String,
        /// Its value there.
        x: f64,
        /// The band's low end.
        lo: f64,
        /// The band's high end.
        hi: f64,
    },
    /// The adaptive step size fell below what floating point can resolve.
    #[error(
        "the model is too stiff or discontinuous to simulate at this tolerance: the step fell to h = {h:.3e} s at t = {t:.6} s; look for a term that jumps (sign(x'), a stop) or a coefficient far larger than the others"
    )]
    StepSizeUnderflow {
        /// Time where the integrator stalled (s).
        t: f64,
        /// The step size that was too small (s).
        h: f64,
    },
    /// The step budget ran out before the final output time.
    #[error(
        "the model is too stiff or discontinuous to simulate at this tolerance: {max_steps} steps got only to t = {t:.6} s on the way to t = {t_target:.6} s (steps of h = {h:.3e} s); look for a term that jumps (sign(x'), a stop) or a coefficient far larger than the others"
    )]
    TooManySteps {
        /// Time reached (s).
        t: f64,
        /// Output time that was being approached (s).
        t_target: f64,
        /// The budget.
        max_steps: usize,
        /// The step size the integrator was proposing when the budget ran out (s).
        h: f64,
    },
    /// A record's displacement is too small for the simulation to follow.
    #[error(
        "{record}: column '{column}' spans only {span:.4e} (peak to peak), too little for a simulation with an absolute tolerance of {atol:e} to follow; give the record in smaller units (e.g. µm instead of m)"
    )]
    Unresolved {
        /// The record's source.
        record: String,
        /// The displacement column.
        column: String,
        /// Its peak-to-peak span.
        span: f64,
        /// The integrator's absolute tolerance.
        atol: f64,
    },
    /// A parameter has an invalid value.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// The parameter name.
        name: &'static str,
        /// What is wrong and what to do.
        reason: String,
    },
    /// A vector has the wrong length.
    #[error("`{name}` has length {got} but {expected} is needed; {hint}")]
    Dimension {
        /// The argument name.
        name: &'static str,
        /// The length needed.
        expected: usize,
        /// The length given.
        got: usize,
        /// What to do.
        hint: &'static str,
    },
    /// A column needed by a model is missing from a record.
    #[error(
        "{record}: column '{column}' needed by the model is missing; the record has [{available}]; rename the column or refit the model with the record's names"
    )]
    MissingColumn {
        /// The record's source.
        record: String,
        /// The missing column.
        column: String,
        /// Comma-separated available columns.
        available: String,
    },
    /// An error from the model library (compiling a model).
    #[error("model: {0}")]
    Model(String),
}

impl DynError {
    /// The same error with its times moved by `t0`: a record simulated on its own clock (from 0
    /// at its first sample) reports times on the record's time column.
    pub(crate) fn on_clock(self, t0: f64) -> Self {
        match self {
            DynError::BlowUp { t, x, v } => DynError::BlowUp { t: t + t0, x, v },
            DynError::StepSizeUnderflow { t, h } => DynError::StepSizeUnderflow { t: t + t0, h },
            DynError::LeftRange { t, dof, x, lo, hi } => DynError::LeftRange {
                t: t + t0,
                dof,
                x,
                lo,
                hi,
            },
            DynError::TooManySteps {
                t,
                t_target,
                max_steps,
                h,
            } => DynError::TooManySteps {
                t: t + t0,
                t_target: t_target + t0,
                max_steps,
                h,
            },
            other => other,
        }
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, DynError>;
