//! Measurement records: named, uniformly sampled columns, read from and written to CSV with
//! validation that names the file, row and column of every problem.
//!
//! Architecture invariant: this crate knows nothing about models or numerics beyond checking data.
//!
//! ```
//! use tfs_data::Record;
//! let r = Record::new("demo", vec![0.0, 0.1, 0.2], vec![("x".into(), vec![1.0, 2.0, 3.0])]).unwrap();
//! assert_eq!(r.column("x").unwrap()[2], 3.0);
//! assert!((r.dt() - 0.1).abs() < 1e-12);
//! ```

mod record;
pub use record::{Columns, Record};

/// Errors raised while building, reading or writing records.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A record was built from inconsistent parts.
    #[error("{source_name}: {message}")]
    Invalid {
        /// The file or record name.
        source_name: String,
        /// What is wrong and what to do.
        message: String,
    },
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, DataError>;
