//! `gharial.problems`: the catalogue of built-in problems.

use gharial_problems::Example;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{arrays1, err};
use crate::options::solver_options;
use crate::problem::PyProblem;
use crate::solvers::PySolver;

/// A built-in problem: the problem, its initial guess, time step and recommended
/// ProxDDP settings.
#[pyclass(name = "Example", module = "gharial.problems")]
pub struct PyExample {
    example: Example,
    /// The problem as one `TrajOptProblem` object, so that repeated solves of
    /// `ex.problem` reuse the solver's set-up.
    problem: Py<PyProblem>,
}

#[pymethods]
impl PyExample {
    /// Catalogue name.
    #[getter]
    fn name(&self) -> &'static str {
        self.example.name
    }

    /// A few lines describing the problem.
    #[getter]
    fn description(&self) -> &'static str {
        self.example.description
    }

    /// Time step (`None` for discrete-time problems).
    #[getter]
    fn dt(&self) -> Option<f64> {
        self.example.dt
    }

    /// The problem, as a `TrajOptProblem` (the same object at every access).
    #[getter]
    fn problem(&self, py: Python<'_>) -> Py<PyProblem> {
        self.problem.clone_ref(py)
    }

    /// Initial state guess.
    #[getter]
    fn xs0<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyList>> {
        arrays1(py, &self.example.xs0)
    }

    /// Initial control guess.
    #[getter]
    fn us0<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyList>> {
        arrays1(py, &self.example.us0)
    }

    /// The solver `name` with this problem's settings, as `gharial solve` uses them:
    /// ProxDDP with the problem's recommended settings, the others with their defaults;
    /// `options` override them.
    #[pyo3(signature = (name = "proxddp", **options))]
    fn solver(&self, name: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<PySolver> {
        PySolver::with_options(solver_options(self.example.options(name))?, options)
    }

    fn __repr__(&self) -> String {
        format!("Example({}, N = {})", self.example.name, self.example.problem.horizon())
    }
}

/// Builds the catalogue problem `name` (see `names()`).
#[pyfunction]
fn build(py: Python<'_>, name: &str) -> PyResult<PyExample> {
    let example = gharial_problems::build(name).map_err(err)?;
    let problem = Py::new(py, PyProblem::from_rust(&example.problem))?;
    Ok(PyExample { example, problem })
}

/// The catalogue's problem names.
#[pyfunction]
fn names() -> Vec<&'static str> {
    gharial_problems::catalogue().iter().map(|p| p.name).collect()
}

/// The catalogue: `(name, summary)` pairs.
#[pyfunction]
fn catalogue() -> Vec<(&'static str, &'static str)> {
    gharial_problems::catalogue()
        .iter()
        .map(|p| (p.name, p.summary))
        .collect()
}

/// Registers the catalogue as the submodule `problems`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let sub = PyModule::new(m.py(), "problems")?;
    sub.add_class::<PyExample>()?;
    sub.add_function(wrap_pyfunction!(build, &sub)?)?;
    sub.add_function(wrap_pyfunction!(names, &sub)?)?;
    sub.add_function(wrap_pyfunction!(catalogue, &sub)?)?;
    m.add_submodule(&sub)?;
    Ok(())
}
