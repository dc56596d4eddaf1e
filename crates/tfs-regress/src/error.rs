//! The crate's error type and `Result` alias.

/// Everything that can go wrong in `tfs-regress`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegressError {
    /// Two inputs that must agree in size do not.
    #[error(
        "dimension mismatch in {what}: expected {expected}, found {found}; pass inputs of matching size"
    )]
    DimensionMismatch {
        /// Which quantity is mis-sized (e.g. "b (right-hand side) length vs rows of A").
        what: String,
        /// The size that was required.
        expected: usize,
        /// The size that was given.
        found: usize,
    },
    /// An input contains NaN or ±∞.
    #[error(
        "non-finite value {value} in {what} at row {row}, column {col}; remove or repair that sample before regression"
    )]
    NonFinite {
        /// Which input (`"A"`, `"b"`, `"coef"`, …).
        what: &'static str,
        /// Row index (0-based).
        row: usize,
        /// Column index (0-based; 0 for vectors).
        col: usize,
        /// The offending value.
        value: f64,
    },
    /// A hyper-parameter is out of its valid range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name as spelled in the API.
        name: &'static str,
        /// The value given, formatted.
        value: String,
        /// What the valid range is.
        reason: &'static str,
    },
    /// An input that must be non-empty is empty.
    #[error("empty input: {what}")]
    Empty {
        /// What was empty and what to do about it.
        what: &'static str,
    },
}

/// `Result` with [`RegressError`].
pub type Result<T> = std::result::Result<T, RegressError>;

pub(crate) fn check_param(
    name: &'static str,
    value: f64,
    ok: bool,
    reason: &'static str,
) -> Result<()> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(RegressError::InvalidParameter {
            name,
            value: format!("{value}"),
            reason,
        })
    }
}
