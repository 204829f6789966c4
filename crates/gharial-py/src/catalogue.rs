//! `gharial.problems`: the catalogue of built-in problems.

use gharial::mpc::Record;
use gharial_problems::Example;
use gharial_problems::mpc::{Metric, Mismatch, MpcScenario, ScenarioSettings};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{arrays1, err};
use crate::options::solver_options;
use crate::problem::PyProblem;
use crate::solvers::{PySolver, status_name};

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
    let problem = Py::new(py, PyProblem::from_rust(py, &example.problem)?)?;
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

/// The closed-loop scenarios (`simulate`): `(name, summary)` pairs.
#[pyfunction]
fn scenarios() -> Vec<(&'static str, &'static str)> {
    gharial_problems::mpc::SCENARIOS.to_vec()
}

/// Runs the closed-loop scenario `name` (see `scenarios()`) for `duration` seconds, as
/// `gharial simulate`: the MPC with the solver `solver` (the scenario's settings, then
/// `options`), at most `max_iters` iterations (default the scenario's) and
/// `cycle_budget` milliseconds per cycle; the plant carries an unmodelled `payload` (kg);
/// `pushes` are `(time, (vx, vy, vz))` changes of a floating base's linear velocity;
/// `slope` and `speed` set the Solo-12 walking scenarios' ground tilt and command.
///
/// Returns a dict: `scenario`, `plant_dt`, `steps_per_cycle`, `xs` and `us` (the plant's
/// states and controls at every step, 2-D arrays), `cycles` (one dict per MPC cycle:
/// `step`, `time`, `solve_time_ms`, `iterations`, `status`, `cost`, `prim_err`,
/// `dual_err`), `metrics` (name: `(value, unit)`) and `stopped`: `None`, or for a loop
/// that could not go on (a failed cycle, a plant step that failed or left a non-finite
/// state: a diverging loop) a dict `step`, `time`, `reason`, the arrays then holding the
/// steps done; `metrics_error`: `None`, or why the metrics could not be evaluated on
/// the record (`metrics` is then empty).
#[pyfunction]
#[pyo3(signature = (
    name, duration = std::f64::consts::PI, solver = "proxddp", payload = 0.0, pushes = Vec::new(),
    slope = None, speed = None, max_iters = None, cycle_budget = None, **options
))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    name: &str,
    duration: f64,
    solver: &str,
    payload: f64,
    pushes: Vec<(f64, [f64; 3])>,
    slope: Option<f64>,
    speed: Option<f64>,
    max_iters: Option<usize>,
    cycle_budget: Option<f64>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut settings = ScenarioSettings::default();
    (settings.slope, settings.speed) = (slope, speed);
    settings.mismatch = Mismatch::payload(payload);
    let mut sc = gharial_problems::mpc::scenario_with(name, &settings).map_err(err)?;
    for (t, dv) in pushes {
        sc.push_base(t, dv).map_err(err)?;
    }
    if let Some(n) = max_iters {
        sc.options.max_iters = n;
    }
    if let Some(ms) = cycle_budget {
        sc.options.max_time = gharial_problems::mpc::cycle_budget_ms(ms).map_err(err)?;
    }
    let solver = PySolver::with_options(solver_options(sc.example.options(solver))?, options)?;
    let mut mpc = sc.controller(solver.build()).map_err(err)?;
    let rec = sc.run(&mut mpc, duration).map_err(err)?;
    let (metrics, metrics_error) = match sc.metrics(&rec) {
        Ok(m) => (m, None),
        Err(e) => (Vec::new(), Some(e.to_string())),
    };
    let out = record_dict(py, &sc, &rec, &metrics)?;
    out.set_item("metrics_error", metrics_error)?;
    Ok(out)
}

/// The dict of [`simulate`].
fn record_dict<'py>(
    py: Python<'py>,
    sc: &MpcScenario,
    rec: &Record,
    metrics: &[Metric],
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("scenario", sc.name)?;
    out.set_item("plant_dt", sc.plant_dt)?;
    out.set_item("steps_per_cycle", sc.steps_per_cycle)?;
    out.set_item("xs", rows(py, &rec.xs)?)?;
    out.set_item("us", rows(py, &rec.us)?)?;
    let cycles = PyList::empty(py);
    for c in &rec.cycles {
        let d = PyDict::new(py);
        d.set_item("step", c.step)?;
        d.set_item("time", c.step as f64 * sc.plant_dt)?;
        d.set_item("solve_time_ms", c.solve_time.as_secs_f64() * 1e3)?;
        d.set_item("iterations", c.iterations)?;
        d.set_item("status", status_name(c.status))?;
        d.set_item("cost", c.cost)?;
        d.set_item("prim_err", c.prim_err)?;
        d.set_item("dual_err", c.dual_err)?;
        cycles.append(d)?;
    }
    out.set_item("cycles", cycles)?;
    let m = PyDict::new(py);
    for metric in metrics {
        m.set_item(metric.name, (metric.value, metric.unit))?;
    }
    out.set_item("metrics", m)?;
    let stopped = match &rec.stopped {
        Some(s) => {
            let d = PyDict::new(py);
            d.set_item("step", s.step)?;
            d.set_item("time", s.step as f64 * sc.plant_dt)?;
            d.set_item("reason", &s.reason)?;
            Some(d)
        }
        None => None,
    };
    out.set_item("stopped", stopped)?;
    Ok(out)
}

/// Rows of one length as a 2-D numpy array.
fn rows<'py>(py: Python<'py>, vs: &[Vec<f64>]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = vs.first().map_or(0, Vec::len);
    let flat: Vec<f64> = vs.iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([vs.len(), m])
}

/// Registers the catalogue as the submodule `problems`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let sub = PyModule::new(m.py(), "problems")?;
    sub.add_class::<PyExample>()?;
    sub.add_function(wrap_pyfunction!(build, &sub)?)?;
    sub.add_function(wrap_pyfunction!(names, &sub)?)?;
    sub.add_function(wrap_pyfunction!(catalogue, &sub)?)?;
    sub.add_function(wrap_pyfunction!(scenarios, &sub)?)?;
    sub.add_function(wrap_pyfunction!(simulate, &sub)?)?;
    m.add_submodule(&sub)?;
    Ok(())
}
