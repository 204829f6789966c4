//! The error type shared by every part of the library.
//!
//! Construction, validation and setup return [`Result`]; messages name the offending
//! object (stage index, function, field) and the dimensions involved, so that a user can
//! find the mistake without reading the library's code.

use std::fmt;

/// Errors raised when a model, a problem, an option or a linear system is invalid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A vector or matrix does not have the size the model expects.
    #[error("dimension mismatch in {what}: expected {expected}, got {got}")]
    Dimension {
        /// What was being checked, e.g. `"stage 3: dynamics Jx rows"`.
        what: String,
        /// Expected size.
        expected: usize,
        /// Size found.
        got: usize,
    },
    /// A value is NaN or infinite.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Where the value was found, e.g. `"initial guess us[4]"`.
        what: String,
    },
    /// A linear system that must be solved is singular or has the wrong inertia.
    #[error("singular or indefinite system in {what}")]
    Singular {
        /// Which system, e.g. `"LQ knot 7: stage KKT block"`.
        what: String,
    },
    /// An option is outside its valid range.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// Option name as in the options struct.
        name: String,
        /// Why it is invalid.
        reason: String,
    },
    /// A model or problem is ill-formed in a way not covered by the other variants.
    #[error("invalid model: {0}")]
    InvalidModel(String),
    /// A simulated plant cannot go on (a robot that fell, a contact problem without a
    /// solution at a diverged state): the closed loop stops there.
    #[error("simulation: {0}")]
    Simulation(String),
}

/// Checks that option `name` is positive and finite.
///
/// # Errors
/// [`Error::InvalidOption`] naming the option and its value.
pub fn check_positive(name: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::option(
            name,
            format!("must be positive and finite, got {}", Num(v)),
        ))
    }
}

/// A wall-time budget of `seconds` (`max_time` of the solvers and the MPC cycles):
/// `None` for `+∞` (no budget).
///
/// # Errors
/// [`Error::InvalidOption`] naming option `name` if `seconds` is NaN, not positive, or
/// finite but too large for a [`std::time::Duration`] (about 1.8e19 s).
pub fn time_budget(name: &str, seconds: f64) -> Result<Option<std::time::Duration>> {
    if seconds == f64::INFINITY {
        return Ok(None);
    }
    match std::time::Duration::try_from_secs_f64(seconds) {
        Ok(d) if seconds > 0.0 => Ok(Some(d)),
        _ => Err(Error::option(
            name,
            format!(
                "must be a positive number of seconds (inf: no budget), got {}",
                Num(seconds)
            ),
        )),
    }
}

/// Result type of the library.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shorthand for [`Error::Dimension`].
    pub fn dim(what: impl fmt::Display, expected: usize, got: usize) -> Self {
        Error::Dimension {
            what: what.to_string(),
            expected,
            got,
        }
    }

    /// Shorthand for [`Error::NonFinite`].
    pub fn non_finite(what: impl fmt::Display) -> Self {
        Error::NonFinite { what: what.to_string() }
    }

    /// Shorthand for [`Error::Singular`].
    pub fn singular(what: impl fmt::Display) -> Self {
        Error::Singular { what: what.to_string() }
    }

    /// Shorthand for [`Error::InvalidOption`].
    pub fn option(name: impl fmt::Display, reason: impl fmt::Display) -> Self {
        Error::InvalidOption {
            name: name.to_string(),
            reason: reason.to_string(),
        }
    }
}

/// Returns an error if `got != expected`.
pub fn check_dim(what: impl fmt::Display, expected: usize, got: usize) -> Result<()> {
    if expected == got {
        Ok(())
    } else {
        Err(Error::dim(what, expected, got))
    }
}

/// Returns an error if a slice contains a NaN or an infinity.
pub fn check_finite(what: impl fmt::Display, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::non_finite(what))
    }
}

/// A number as messages and tables show it: plain decimals for ordinary magnitudes,
/// scientific notation for very large or small ones (`f64::MAX` prints as
/// `1.7976931348623157e308`, not as 309 digits), `inf` and `NaN` as such.
///
/// ```
/// use gharial::error::Num;
/// assert_eq!(Num(0.25).to_string(), "0.25");
/// assert_eq!(Num(f64::MAX).to_string(), "1.7976931348623157e308");
/// assert_eq!(Num(-f64::INFINITY).to_string(), "-inf");
/// assert_eq!(Num(1e-9).to_string(), "1e-9");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        let plain = x == 0.0 || (1e-4..1e15).contains(&x.abs());
        if plain || !x.is_finite() {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `+∞` is no budget; NaN, non-positive and finite values too large for a
    /// `Duration` (a panic of `Duration::from_secs_f64`) are named errors.
    #[test]
    fn time_budgets_are_checked() {
        assert_eq!(time_budget("max_time", f64::INFINITY).unwrap(), None);
        assert_eq!(
            time_budget("max_time", 0.25).unwrap(),
            Some(std::time::Duration::from_millis(250))
        );
        for bad in [f64::NAN, -1.0, 0.0, f64::NEG_INFINITY, 1e20, 1e300] {
            let e = time_budget("max_time", bad).unwrap_err().to_string();
            assert!(e.contains("max_time") && e.contains("seconds"), "{bad}: {e}");
        }
    }
}
