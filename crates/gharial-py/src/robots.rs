//! `gharial.robots`: multibody models from URDF, their algorithms on numpy arrays, and
//! the robotics spaces, dynamics and residuals.

use pyo3::prelude::*;

/// Registers the classes and functions of `gharial.robots`.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
