//! The crate's error type and `Result` alias.

/// Errors raised while validating basin inputs, comparing maps or searching for the MED.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BasinError {
    /// A parameter is out of range or inconsistent with the others.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// Name of the offending parameter.
        name: &'static str,
        /// What is wrong and what to do about it.
        reason: String,
    },
    /// The restoring force has no stable equilibrium in the search range.
    #[error(
        "no stable equilibrium found in the search range [{lo}, {hi}]; widen the range or check the model's restoring force"
    )]
    NoStableEquilibrium {
        /// Lower end of the search range.
        lo: f64,
        /// Upper end of the search range.
        hi: f64,
    },
    /// The energy `E = ½mv² + V(x)` of the system grows somewhere, so the early-exit proof fails.
    #[error(
        "the system is not dissipative for the given potential: dE/dt = {rate:.3e} > 0 at x = {x:.6}, v = {v:.6}; \
         check that the force/potential match the model (mass {mass}) and damping is non-negative, or set early_exit = false"
    )]
    NotDissipative {
        /// Displacement where energy grows.
        x: f64,
        /// Velocity where energy grows.
        v: f64,
        /// The positive energy rate found.
        rate: f64,
        /// Mass used in the kinetic energy.
        mass: f64,
    },
    /// Two basin maps cover different grids and cannot be compared cell by cell.
    #[error("basin maps differ in {what}: {a} vs {b}; compute both maps on the same grid")]
    MapMismatch {
        /// Which property differs.
        what: &'static str,
        /// Value in the first map.
        a: String,
        /// Value in the second map.
        b: String,
    },
    /// The RK4 step is too long to be stable on the states the map can reach.
    #[error(
        "dt = {dt} is too long for RK4 on this system: its fastest linearised rate on the states the grid reaches is \
         {rate:.4} /s (at x = {x}, v = {v}), so RK4 is stable only for dt below {max_dt:.4}; \
         use a dt well below that (about {suggest:.2e} keeps dt × rate near 0.05)",
        suggest = 0.05 / rate, x = short(at_x), v = short(at_v)
    )]
    StepTooLong {
        /// The step asked for.
        dt: f64,
        /// The fastest rate `|λ|` found (1/s).
        rate: f64,
        /// The longest stable step.
        max_dt: f64,
        /// Displacements where the rate was found.
        at_x: Vec<f64>,
        /// Velocities where the rate was found.
        at_v: Vec<f64>,
    },
    /// An error from tfs-dynamics (e.g. the equilibrium search).
    #[error(transparent)]
    Dynamics(#[from] tfs_dynamics::DynError),
    /// No pair of neighbouring cells separates the two basins, so no MED can be found.
    #[error(
        "no basin boundary between S{} and S{} on this grid; widen the grid ranges (the boundary must lie inside them) or refine the grid",
        .from + 1,
        .to + 1
    )]
    NoBoundary {
        /// 0-based index of the starting stable state (printed 1-based, as S1, S2, …).
        from: usize,
        /// 0-based index of the target stable state (printed 1-based).
        to: usize,
    },
}

/// `Result` with [`BasinError`].
pub type Result<T> = std::result::Result<T, BasinError>;

/// Shorthand for an [`BasinError::InvalidParameter`].
pub(crate) fn invalid(name: &'static str, reason: impl Into<String>) -> BasinError {
    BasinError::InvalidParameter {
        name,
        reason: reason.into(),
    }
}

/// A state vector for messages: one number alone, several in parentheses, 4 significant digits.
fn short(v: &[f64]) -> String {
    let each: Vec<String> = v.iter().map(|x| format!("{x:.4}")).collect();
    match each.len() {
        1 => each[0].clone(),
        _ => format!("({})", each.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::BasinError;

    /// States are counted from 1 in messages, as in the CLI's `--from`/`--to` flags.
    #[test]
    fn no_boundary_names_states_from_one() {
        let m = BasinError::NoBoundary { from: 0, to: 1 }.to_string();
        assert!(m.contains("between S1 and S2"), "{m}");
    }
}
