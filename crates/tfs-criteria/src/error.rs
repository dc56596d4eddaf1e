//! The crate's error type and `Result` alias.

/// Errors raised by the criteria and the identification pipelines.
#[derive(Debug, thiserror::Error)]
pub enum CriteriaError {
    /// A parameter or input was invalid; the message names it and says what to do.
    #[error("{0}")]
    Invalid(String),
    /// A library specification or evaluation failed.
    #[error(transparent)]
    Library(#[from] tfs_library::LibraryError),
    /// A regression failed.
    #[error(transparent)]
    Regress(#[from] tfs_regress::RegressError),
    /// A signal-processing step failed.
    #[error(transparent)]
    Signal(#[from] tfs_signal::SignalError),
    /// A dense decomposition failed (non-finite data).
    #[error("numerics: {0}; check the data for NaN or infinite values")]
    Numerics(String),
    /// A lower-level data error.
    #[error(transparent)]
    Data(#[from] tfs_data::DataError),
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, CriteriaError>;

pub(crate) fn invalid<T>(msg: impl Into<String>) -> Result<T> {
    Err(CriteriaError::Invalid(msg.into()))
}
