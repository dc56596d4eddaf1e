//! The crate's error type and `Result` alias.

/// Errors raised by [`crate::refine`] and [`crate::choose_by_validation`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RefineError {
    /// An argument or option has an invalid value.
    #[error("invalid `{name}`: {message}")]
    Invalid {
        /// The parameter, option or record concerned.
        name: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// A column the model needs is missing from a record.
    #[error(
        "record '{record}': column '{column}' needed by the model is missing; the record has [{available}]; rename the column or refit the model with the record's names"
    )]
    MissingColumn {
        /// The record's source name.
        record: String,
        /// The missing column (a DOF displacement or a model input).
        column: String,
        /// Comma-separated available columns.
        available: String,
    },
    /// A record holds a NaN or infinite value.
    #[error(
        "record '{record}': column '{column}' row {row} is {value}; remove or fill non-finite samples before refining"
    )]
    NonFinite {
        /// The record's source name.
        record: String,
        /// The column.
        column: String,
        /// Zero-based row index.
        row: usize,
        /// The offending value.
        value: f64,
    },
    /// The model could not be compiled or rebuilt.
    #[error("model: {0}")]
    Model(String),
    /// Simulation or signal processing failed.
    #[error("{0}")]
    Dynamics(String),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, RefineError>;

impl From<tfs_library::LibraryError> for RefineError {
    fn from(e: tfs_library::LibraryError) -> Self {
        RefineError::Model(e.to_string())
    }
}

impl From<tfs_dynamics::DynError> for RefineError {
    fn from(e: tfs_dynamics::DynError) -> Self {
        RefineError::Dynamics(e.to_string())
    }
}

impl From<tfs_signal::SignalError> for RefineError {
    fn from(e: tfs_signal::SignalError) -> Self {
        RefineError::Dynamics(e.to_string())
    }
}

impl From<tfs_data::DataError> for RefineError {
    fn from(e: tfs_data::DataError) -> Self {
        RefineError::Invalid {
            name: "record".into(),
            message: e.to_string(),
        }
    }
}
