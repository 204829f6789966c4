//! Error type of the crate.

use crate::spatial::all_finite;
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
    /// A configuration whose quaternion or (cos, sin) pair is not of unit norm within
    /// [`Model::UNIT_NORM_TOLERANCE`](crate::Model::UNIT_NORM_TOLERANCE).
    #[error(
        "{what}: joint `{joint}`: its {block} has norm {norm}, not 1 within {tolerance:e} (normalize the configuration with `normalize`)"
    )]
    NotNormalized {
        /// Argument name.
        what: String,
        /// Joint name.
        joint: String,
        /// `quaternion` or `(cos, sin) pair`.
        block: String,
        /// The norm found.
        norm: f64,
        /// The tolerance on |norm − 1|.
        tolerance: f64,
    },
    /// An algorithm's result is not finite although its inputs are: they are so large
    /// that the computation overflowed.
    #[error(
        "{what}: entry {index} of the result is not finite: the inputs are finite but so large that the computation overflowed"
    )]
    NonFiniteResult {
        /// Result name.
        what: String,
        /// Index of the first non-finite entry.
        index: usize,
    },
    /// A body inertia that is not physically valid (see
    /// [`Model::INERTIA_TOLERANCE`](crate::Model::INERTIA_TOLERANCE)).
    #[error("{what}: inertia is not physically valid: {message}")]
    InvalidInertia {
        /// The body (joint name or index).
        what: String,
        /// What is wrong.
        message: String,
    },
    /// A model with more degrees of freedom than [`Model::MAX_NV`](crate::Model::MAX_NV).
    #[error(
        "joint `{joint}`: the model would have nv = {nv} degrees of freedom, more than Model::MAX_NV = {max} (the dense nv × nv matrices of its Data would not fit in reasonable memory)"
    )]
    ModelTooLarge {
        /// Joint whose addition exceeds the limit.
        joint: String,
        /// The tangent size the model would have.
        nv: usize,
        /// The limit.
        max: usize,
    },
    /// A matrix that must be positive definite is not (e.g. the mass matrix of a model
    /// with a massless leaf body, or a rank-deficient contact Jacobian).
    #[error("{what} is not positive definite (pivot {index} = {value:e})")]
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
    if all_finite(x) {
        return Ok(());
    }
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NotFinite {
            what: what.to_string(),
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// Checks that every item of an algorithm's result is finite; `index` in the error
/// counts items (entries for `f64`, spatial vectors or placements otherwise). The
/// check itself is branch-free; the index is looked for only on failure.
pub(crate) fn check_result<T>(what: &str, items: &[T], finite: impl Fn(&T) -> bool) -> Result<()> {
    if items.iter().fold(true, |ok, x| ok & finite(x)) {
        return Ok(());
    }
    Err(Error::NonFiniteResult {
        what: what.to_string(),
        index: items.iter().position(|x| !finite(x)).unwrap_or(0),
    })
}

/// [`check_result`] for a slice of numbers.
pub(crate) fn check_result_vec(what: &str, x: &[f64]) -> Result<()> {
    if all_finite(x) {
        return Ok(());
    }
    check_result(what, x, |v| v.is_finite())
}

/// [`check_result_vec`] for several results at once: one branch-free pass over all of
/// them, the first non-finite one named only on failure (the order of `items`).
pub(crate) fn check_results(items: &[(&str, &[f64])]) -> Result<()> {
    let mut acc = [0.0f64; 4];
    for (_, x) in items {
        crate::spatial::add_times_zero(&mut acc, x);
    }
    if (acc[0] + acc[1]) + (acc[2] + acc[3]) == 0.0 {
        return Ok(());
    }
    for (what, x) in items {
        check_result_vec(what, x)?;
    }
    Ok(())
}

/// [`check_result`] for a matrix view (index in column-major order).
pub(crate) fn check_result_mat(what: &str, m: faer::MatRef<'_, f64>) -> Result<()> {
    let nrows = m.nrows();
    for j in 0..m.ncols() {
        let col = m.col(j);
        let ok = match col.try_as_col_major() {
            Some(c) => all_finite(c.as_slice()),
            None => (0..nrows).all(|i| col[i].is_finite()),
        };
        if !ok {
            let i = (0..nrows).position(|i| !col[i].is_finite()).unwrap_or(0);
            return Err(Error::NonFiniteResult {
                what: what.to_string(),
                index: j * nrows + i,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_results_names_the_first_non_finite_item() {
        let (a, b, c) = ([1.0, 2.0], [0.0; 9], [3.0, -4.0, 5.0]);
        assert!(check_results(&[("a", &a), ("b", &b), ("c", &c)]).is_ok());
        assert!(check_results(&[]).is_ok());
        let mut b2 = b;
        b2[7] = f64::INFINITY;
        let c2 = [3.0, f64::NAN, 5.0];
        match check_results(&[("a", &a), ("b", &b2), ("c", &c2)]) {
            Err(Error::NonFiniteResult { what, index }) => assert_eq!((what.as_str(), index), ("b", 7)),
            other => panic!("expected b[7], got {other:?}"),
        }
        match check_results(&[("a", &a), ("c", &c2)]) {
            Err(Error::NonFiniteResult { what, index }) => assert_eq!((what.as_str(), index), ("c", 1)),
            other => panic!("expected c[1], got {other:?}"),
        }
    }
}
