//! Error type of the crate.

use thiserror::Error;

/// Errors of model construction, file parsing and algorithm inputs.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// A file could not be read.
    #[error("cannot read {path}: {message}")]
    Io {
        /// File path.
        path: String,
        /// System message.
        message: String,
    },
    /// Malformed XML.
    #[error("{file}: malformed XML: {message}")]
    Xml {
        /// File kind or path.
        file: String,
        /// Parser message.
        message: String,
    },
    /// A URDF or SRDF element is missing, invalid or inconsistent.
    #[error("{file}: element <{element}>{name}: {message}")]
    Element {
        /// File kind or path.
        file: String,
        /// Element tag.
        element: String,
        /// ` name="..."` of the element, or empty.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// An input vector has the wrong size.
    #[error("{what}: expected length {expected}, got {got}")]
    Dimension {
        /// Argument name.
        what: String,
        /// Expected length.
        expected: usize,
        /// Given length.
        got: usize,
    },
    /// An input contains NaN or infinity.
    #[error("{what}: entry {index} is not finite ({value})")]
    NotFinite {
        /// Argument name.
        what: String,
        /// Index of the first non-finite entry.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A name or index that the model does not contain.
    #[error("{what} not found: {name}")]
    NotFound {
        /// Kind of object (joint, frame).
        what: String,
        /// Name or index.
        name: String,
    },
    /// A model or algorithm precondition does not hold.
    #[error("{0}")]
    Invalid(String),
    /// A matrix that must be positive definite is not (e.g. the mass matrix of a model
    /// with a massless leaf body, or a rank-deficient contact Jacobian).
    #[error("{what} is not positive definite (pivot {index} = {value})")]
    NotPositiveDefinite {
        /// Matrix name.
        what: String,
        /// Pivot index.
        index: usize,
        /// Pivot value.
        value: f64,
    },
}

/// Result alias of the crate.
pub type Result<T> = core::result::Result<T, Error>;

/// Checks a slice's length and finiteness.
pub(crate) fn check_vec(what: &str, x: &[f64], expected: usize) -> Result<()> {
    if x.len() != expected {
        return Err(Error::Dimension {
            what: what.to_string(),
            expected,
            got: x.len(),
        });
    }
    check_finite(what, x)
}

/// Checks that all entries are finite.
pub(crate) fn check_finite(what: &str, x: &[f64]) -> Result<()> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NotFinite {
            what: what.to_string(),
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}
