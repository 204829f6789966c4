//! Python bindings of gharial: the extension module `gharial._gharial` behind the
//! pure-Python package `gharial` (see the package README for the API and its mapping to
//! ALIGATOR's names).

mod catalogue;
mod constraints;
mod convert;
mod costs;
mod dynamics;
mod functions;
mod mpc;
mod options;
mod problem;
mod pymodel;
mod robot_residuals;
mod robots;
mod solvers;
mod spaces;
mod viz;

use pyo3::prelude::*;

/// The extension module. Its classes are re-exported by the submodules of the Python
/// package (`gharial.manifolds`, `gharial.dynamics`, ...).
#[pymodule]
fn _gharial(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("GharialError", m.py().get_type::<convert::GharialError>())?;
    spaces::register(m)?;
    functions::register(m)?;
    dynamics::register(m)?;
    costs::register(m)?;
    constraints::register(m)?;
    problem::register(m)?;
    solvers::register(m)?;
    mpc::register(m)?;
    robots::register(m)?;
    catalogue::register(m)?;
    viz::register(m)?;
    Ok(())
}
