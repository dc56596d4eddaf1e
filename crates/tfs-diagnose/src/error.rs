//! The crate's error type and `Result` alias.

/// Everything that can go wrong while comparing, localising, explaining or refitting.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A record lacks a column the model needs (a DOF displacement or an input).
    #[error(
        "{record}: column '{column}' needed by the model (DOFs [{dofs}], inputs [{inputs}]) is missing; the record has [{available}]; use data with the model's DOFs or a model identified on this kind of data"
    )]
    DofMismatch {
        /// The record's source.
        record: String,
        /// The missing column.
        column: String,
        /// The model's DOFs.
        dofs: String,
        /// The model's inputs.
        inputs: String,
        /// The record's columns.
        available: String,
    },
    /// An effect name is not in the catalogue.
    #[error("unknown effect '{name}'; known effects: {known}")]
    UnknownEffect {
        /// The name given.
        name: String,
        /// The catalogue's names, comma-separated.
        known: String,
    },
    /// An effect cannot be added (already in the model, or not applicable to it).
    #[error("effect '{name}': {reason}")]
    NotApplicable {
        /// The effect.
        name: String,
        /// Why, and what to do.
        reason: String,
    },
    /// The records are too short for the blocks a scan needs.
    #[error(
        "{what}: too short for a diagnosis: {got} usable samples, at least {needed} are needed (8 blocks of 4 cut-off periods); record longer or pass more records"
    )]
    TooShort {
        /// Which record(s).
        what: String,
        /// Usable samples.
        got: usize,
        /// Samples needed.
        needed: usize,
    },
    /// No records were given.
    #[error("no records given; pass at least one measurement record")]
    NoRecords,
    /// A parameter is out of range.
    #[error("invalid parameter `{name}`: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// What is wrong and what to do.
        reason: String,
    },
    /// A model's short-horizon predictions of a record could not be simulated.
    #[error(
        "{record}: predicting it over pieces of {horizon} samples from the measured state failed (the model blew up or left the record's range); the model cannot be scored on this record"
    )]
    Prediction {
        /// The record's source.
        record: String,
        /// The piece length (samples).
        horizon: usize,
    },
    /// A record could not be built or sliced.
    #[error(transparent)]
    Data(#[from] tfs_data::DataError),
    /// A signal-processing step failed.
    #[error(transparent)]
    Signal(#[from] tfs_signal::SignalError),
    /// A regression failed.
    #[error(transparent)]
    Regress(#[from] tfs_regress::RegressError),
    /// A term or model was invalid.
    #[error(transparent)]
    Library(#[from] tfs_library::LibraryError),
    /// A simulation failed (blow-up, missing input).
    #[error(transparent)]
    Dynamics(#[from] tfs_dynamics::DynError),
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, DiagnoseError>;
