//! Term grammar, candidate libraries evaluated into one `faer::Mat<f64>`, models with the
//! `tfs-model/1` JSON format, a compiled allocation-free model evaluator, and the restoring
//! force / potential of a model.
//!
//! Architecture invariant: this crate does no regression and no integration; it names terms,
//! evaluates them on columns, and stores and evaluates fitted equations.
//!
//! Term names: `x`, `x^k`, `x'`, products `x^2*x'`, relative coordinates
//! `(x2-x1)^k` and `(x2-x1)'`, inputs by column name (`xb_acc`), `abs(v)`, `sign(v)`,
//! `tanh(v/ε)`, `below(v, c)`, `above(v, c)`, the constant `1`, internal states
//! `maxwell(v', τ)`, `bouc_wen(v', a, b)`, `dahl(v', κ)` (memory effects, see [`state`]); in
//! library specs also ranges `x^1..7` and the generator `poly(x, x'; 0..7)` (every monomial of
//! total degree 0..7).
//!
//! ```
//! use tfs_library::{Library, Model, ColumnSet};
//! use tfs_data::Record;
//!
//! let lib = Library::parse("x^1..3, x', xb_acc", &["x"]).unwrap();
//! assert_eq!(lib.required_columns(), ["x", "x'", "xb_acc"]);
//!
//! let rec = Record::new("demo", vec![0.0, 0.1],
//!     vec![("x".into(), vec![1.0, 2.0]), ("xb_acc".into(), vec![0.5, -0.5])]).unwrap();
//! let cols = ColumnSet::new(&rec).with("x'", vec![3.0, 4.0]).unwrap();
//! let theta = lib.evaluate(&cols).unwrap();
//! assert_eq!(theta[(1, 2)], 8.0); // x^3 at x = 2
//!
//! // A model x'' = -2 x' - x^3 - xb_acc, compiled for fast evaluation.
//! let model = Model::from_coefficients(&lib, &[vec![0.0, 0.0, -1.0, -2.0, -1.0]], "demo").unwrap();
//! let fast = model.compile().unwrap();
//! let mut a = [0.0];
//! fast.accel(&[1.0], &[0.5], &[0.25], &mut a);
//! assert_eq!(a[0], -1.0 - 1.0 - 0.25);
//! assert_eq!(model.restoring_force("x", 2.0).unwrap(), 8.0);
//! assert_eq!(model.potential("x", 2.0).unwrap(), 4.0);
//! let back = tfs_library::Model::from_json_str(&model.to_json_string().unwrap()).unwrap();
//! assert_eq!(back, model);
//! ```

mod compiled;
mod gains;
mod library;
mod model;
mod parse;
mod potential;
pub mod state;
mod term;

pub use compiled::CompiledModel;
pub use gains::{GainMoments, LocalGains};
pub use library::{ColumnSet, Library, evaluate_term};
pub use model::{
    Equation, HistoryEntry, MAX_MODEL_BYTES, MODEL_FORMAT, Model, ModelTerm, RecordScore, sig4,
};
pub use parse::{MAX_POWER, MAX_SPEC_TERMS};
pub use potential::{Polynomial, Restoring};
pub use state::StateLaw;
pub use term::{Coord, ExactDerivative, Factor, Term, Var, quote_name};

/// Errors of term parsing, library evaluation and model handling.
#[derive(Debug, thiserror::Error)]
pub enum LibraryError {
    /// A term or library spec could not be parsed.
    #[error("cannot parse \"{input}\" at position {position}: found {found}, expected {expected}")]
    Parse {
        /// The whole text being parsed.
        input: String,
        /// Character offset of the problem (0-based).
        position: usize,
        /// The offending token (or "end of input").
        found: String,
        /// What the grammar expected there.
        expected: String,
    },
    /// A column a term needs is not in the data.
    #[error(
        "column '{column}' is missing but term '{term}' needs it; supply it (velocities as \"x'\", base velocity as \"xb_vel\")"
    )]
    MissingColumn {
        /// The missing column.
        column: String,
        /// The term that needs it.
        term: String,
    },
    /// A column has the wrong number of rows.
    #[error(
        "column '{column}' has {len} rows but the data has {rows}; give every column the same length"
    )]
    ColumnLength {
        /// The column.
        column: String,
        /// Its length.
        len: usize,
        /// The expected number of rows.
        rows: usize,
    },
    /// A term evaluated to NaN or infinity.
    #[error(
        "term '{term}' is not finite at row {row}; check the input columns for NaN/inf or overflow"
    )]
    NonFinite {
        /// The term.
        term: String,
        /// The first bad row (0-based).
        row: usize,
    },
    /// A library, model or argument failed validation.
    #[error("{field}: {message}")]
    Invalid {
        /// The offending field or parameter (`format`, `equations[0].dof`, …).
        field: String,
        /// What is wrong and what to do.
        message: String,
    },
    /// Malformed JSON.
    #[error("{source_name}: invalid model JSON: {message}")]
    Json {
        /// File or source name.
        source_name: String,
        /// The parser's message (with line and column).
        message: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The system's message.
        message: String,
    },
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, LibraryError>;
