//! The facade's error type: every layer's error, a bad argument, or an error with what was being
//! done when it happened.

use tfs_dynamics::DynError;

/// Errors of the workflows in this crate (`identify`, `compare`, `refit`, …): a layer's error
/// unchanged, a bad argument (the message names it and says what to give), or an error with the
/// step it happened in.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading or validating records.
    #[error(transparent)]
    Data(Box<tfs_data::DataError>),
    /// Parsing a library or reading a model.
    #[error(transparent)]
    Library(Box<tfs_library::LibraryError>),
    /// Simulating.
    #[error(transparent)]
    Dynamics(Box<DynError>),
    /// Identification.
    #[error(transparent)]
    Criteria(Box<tfs_criteria::CriteriaError>),
    /// Diagnosis and refit.
    #[error(transparent)]
    Diagnose(Box<tfs_diagnose::DiagnoseError>),
    /// Simulation-error refinement.
    #[error(transparent)]
    Refine(Box<tfs_refine::RefineError>),
    /// Basins and wells.
    #[error(transparent)]
    Basin(Box<tfs_basin::BasinError>),
    /// The Kresling simulators.
    #[error(transparent)]
    Origami(Box<tfs_origami::OrigamiError>),
    /// Figures.
    #[error(transparent)]
    Plot(Box<tfs_plot::PlotError>),
    /// A bad argument: the message names it and says what to give instead.
    #[error("{0}")]
    Invalid(String),
    /// An error with what was being done (`reading model m.json`, `r.csv: simulating the model`).
    #[error("{context}: {source}")]
    Context {
        /// What was being done.
        context: String,
        /// What went wrong.
        #[source]
        source: Box<Error>,
    },
}

/// `From` each layer's error (boxed: the enum stays small on the happy path).
macro_rules! from_layer {
    ($($variant:ident: $ty:ty),* $(,)?) => {
        $(impl From<$ty> for Error {
            fn from(e: $ty) -> Self {
                Error::$variant(Box::new(e))
            }
        })*
    };
}

from_layer!(
    Data: tfs_data::DataError,
    Library: tfs_library::LibraryError,
    Dynamics: DynError,
    Criteria: tfs_criteria::CriteriaError,
    Diagnose: tfs_diagnose::DiagnoseError,
    Refine: tfs_refine::RefineError,
    Basin: tfs_basin::BasinError,
    Origami: tfs_origami::OrigamiError,
    Plot: tfs_plot::PlotError,
);

/// Result alias of the facade's workflows.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Wraps the error with what was being done when it happened.
    pub fn context(self, context: impl Into<String>) -> Self {
        Error::Context {
            context: context.into(),
            source: Box::new(self),
        }
    }

    /// The simulation blow-up somewhere in the chain of causes, if that is what failed:
    /// the time and the state where it happened.
    pub fn blow_up(&self) -> Option<&DynError> {
        let found = match self {
            Error::Dynamics(d) => Some(&**d),
            Error::Diagnose(d) => match &**d {
                tfs_diagnose::DiagnoseError::Dynamics(d) => Some(d),
                _ => None,
            },
            Error::Origami(o) => match &**o {
                tfs_origami::OrigamiError::Simulation { source, .. } => Some(source),
                _ => None,
            },
            Error::Context { source, .. } => return source.blow_up(),
            _ => None,
        };
        found.filter(|d| matches!(d, DynError::BlowUp { .. }))
    }

    /// Whether the error is about the input (a file, a column, an argument) rather than a
    /// computation that failed on good input.
    pub fn is_bad_input(&self) -> bool {
        use tfs_basin::BasinError as B;
        use tfs_criteria::CriteriaError as C;
        use tfs_diagnose::DiagnoseError as D;
        use tfs_refine::RefineError as R;
        match self {
            Error::Data(_) | Error::Library(_) | Error::Invalid(_) => true,
            Error::Criteria(e) => matches!(**e, C::Invalid(_) | C::Library(_) | C::Data(_)),
            Error::Diagnose(e) => match &**e {
                D::Dynamics(d) => bad_dynamics(d),
                other => !matches!(other, D::Signal(_) | D::Regress(_)),
            },
            Error::Refine(e) => matches!(
                **e,
                R::Invalid { .. } | R::MissingColumn { .. } | R::NonFinite { .. }
            ),
            Error::Basin(e) => matches!(**e, B::InvalidParameter { .. }),
            Error::Origami(e) => matches!(**e, tfs_origami::OrigamiError::Param(_)),
            Error::Dynamics(e) => bad_dynamics(e),
            Error::Plot(_) => false,
            Error::Context { source, .. } => source.is_bad_input(),
        }
    }
}

/// Whether a simulation error is about its arguments rather than the run.
fn bad_dynamics(e: &DynError) -> bool {
    matches!(
        e,
        DynError::InvalidParameter { .. }
            | DynError::Dimension { .. }
            | DynError::MissingColumn { .. }
            | DynError::Unresolved { .. }
    )
}

/// Adds what was being done to an error, as `anyhow::Context` does for a binary.
pub trait Context<T> {
    /// Wraps the error with `what`.
    fn context(self, what: impl Into<String>) -> Result<T>;
    /// Wraps the error with a lazily built description.
    fn with_context<F: FnOnce() -> String>(self, what: F) -> Result<T>;
}

impl<T, E: Into<Error>> Context<T> for std::result::Result<T, E> {
    fn context(self, what: impl Into<String>) -> Result<T> {
        self.map_err(|e| e.into().context(what))
    }
    fn with_context<F: FnOnce() -> String>(self, what: F) -> Result<T> {
        self.map_err(|e| e.into().context(what()))
    }
}

/// An error and its causes on one line, each cause once: errors that already print their cause
/// (`… failed: {source}`) also return it as `source()`, and a cause whose text is already in the
/// line is not repeated. The CLI prints this; the Python package raises it.
pub fn one_line(e: &(dyn std::error::Error + 'static)) -> String {
    let mut msg = String::new();
    let mut cur = Some(e);
    while let Some(c) = cur {
        let text = c.to_string();
        if !msg.contains(&text) {
            if !msg.is_empty() {
                msg.push_str(": ");
            }
            msg.push_str(&text);
        }
        cur = c.source();
    }
    msg.replace('\n', " ")
}

/// Builds an [`Error::Invalid`] from a format string, like `anyhow::bail!` in a binary.
#[macro_export]
macro_rules! invalid {
    ($($arg:tt)*) => {
        return Err($crate::Error::Invalid(format!($($arg)*)))
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blow() -> DynError {
        DynError::BlowUp {
            t: 3.5,
            x: vec![1e9],
            v: vec![-2e9],
        }
    }

    /// A blow-up is found under any wrapping with its time and state, and is not bad input;
    /// a bad argument is, through a context too.
    #[test]
    fn blow_up_and_bad_input_are_found_through_the_chain() {
        let e = Error::from(tfs_diagnose::DiagnoseError::Dynamics(blow())).context("r.csv");
        match e.blow_up() {
            Some(DynError::BlowUp { t, x, .. }) => assert_eq!((*t, x[0]), (3.5, 1e9)),
            other => panic!("{other:?}"),
        }
        assert!(!e.is_bad_input());
        let e = Error::Invalid("--threshold -1: must be ≥ 0".into()).context("identify");
        assert!(e.is_bad_input() && e.blow_up().is_none());
        let missing = DynError::MissingColumn {
            record: "r".into(),
            column: "u".into(),
            available: "x".into(),
        };
        assert!(Error::from(missing).is_bad_input());
    }

    /// The one-line message names the context once and each cause once.
    #[test]
    fn one_line_joins_context_and_cause() {
        let e = Error::from(blow()).context("r.csv: simulating the model");
        let msg = one_line(&e);
        assert!(msg.starts_with("r.csv: simulating the model: simulation blew up at t = 3.5"));
        assert_eq!(msg.matches("blew up").count(), 1, "{msg}");
    }
}
