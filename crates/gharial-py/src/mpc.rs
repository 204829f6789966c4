//! `gharial.MPC`: the receding-horizon controller of `gharial::mpc` on a
//! `TrajOptProblem` with any solver.

use std::sync::Mutex;

use gharial::mpc::{Mpc, MpcOptions};
use gharial::solvers::{InitialGuess, Solver};
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::convert::{array1, err, value_error, vector, vectors};
use crate::problem::{PyProblem, PyStageModel, raise_slot_errors};
use crate::pymodel::Slots;
use crate::solvers::{PyResults, PySolver};

/// The wall-time budget `max_time` (seconds; `None` or `inf`: none).
fn budget(max_time: Option<f64>) -> PyResult<Option<std::time::Duration>> {
    max_time.map_or(Ok(None), |t| {
        gharial::error::time_budget("max_time", t).map_err(|e| value_error(e.to_string()))
    })
}

/// A receding-horizon controller (ALIGATOR's MPC loop, ProxDDP paper §VII-E):
/// `solve(x)` runs one cycle from the measured state `x` within the budget
/// (`max_iters`, `max_time` in seconds, `None` or `inf` for none), warm-started from the shifted last solution
/// (the first from `xs_init`, `us_init` and, if given, the multipliers `lams_init`,
/// `vs_init` of a converged solve: `Results.lams`, `Results.vs`);
/// `shift()` moves the horizon one stage along (the next stage of `queue` enters; with
/// no queue the stage that leaves comes back at the end) and returns the number of the
/// stage object that entered (horizon stages `0..N`, queued ones `N..`); `control(x)` is
/// the feedback policy `u = u_0 + K_0 (x ⊖ x_0)` of the last cycle at any state (before
/// the first cycle, the guess's first control).
#[pyclass(name = "MPC", module = "gharial")]
pub struct PyMpc {
    /// Behind a lock for Python's threads (the methods that run it take `&mut self`).
    mpc: Mutex<Mpc<Box<dyn Solver>>>,
    problem: Py<PyProblem>,
    /// The Python models of the queued stages (their exceptions are raised too).
    queue_slots: Vec<Slots>,
}

#[pymethods]
impl PyMpc {
    #[new]
    #[pyo3(signature = (
        problem, solver, xs_init, us_init, queue = Vec::new(), max_iters = 1, max_time = None,
        lams_init = None, vs_init = None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        problem: &Bound<'_, PyProblem>,
        solver: &Bound<'_, PySolver>,
        xs_init: &Bound<'_, PyAny>,
        us_init: &Bound<'_, PyAny>,
        queue: Vec<PyRef<'_, PyStageModel>>,
        max_iters: usize,
        max_time: Option<f64>,
        lams_init: Option<&Bound<'_, PyAny>>,
        vs_init: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let p = problem.borrow_mut().problem(problem.py())?;
        let (xs, us) = (vectors(xs_init, "xs_init")?, vectors(us_init, "us_init")?);
        let (lams, vs) = match (lams_init, vs_init) {
            (Some(l), Some(v)) => (Some(vectors(l, "lams_init")?), Some(vectors(v, "vs_init")?)),
            (None, None) => (None, None),
            _ => return Err(value_error("give both lams_init and vs_init, or neither")),
        };
        let max_time = budget(max_time)?;
        let options = MpcOptions::default().with(|o| {
            o.max_iters = max_iters;
            o.max_time = max_time;
        });
        let queue_slots = queue.iter().map(|s| s.slots.clone()).collect();
        let stages = queue.iter().map(|s| s.model.clone()).collect();
        let mpc = Mpc::new(
            (*p).clone(),
            solver.borrow().build(),
            stages,
            InitialGuess {
                xs: &xs,
                us: &us,
                lambdas: lams.as_deref(),
                nus: vs.as_deref(),
            },
            options,
        )
        .map_err(err)?;
        Ok(Self {
            mpc: Mutex::new(mpc),
            problem: problem.clone().unbind(),
            queue_slots,
        })
    }

    /// One cycle from the measured state `x`; returns the solution (`Results`), whose
    /// `status` says how the solve stopped.
    fn solve(&mut self, py: Python<'_>, x: &Bound<'_, PyAny>) -> PyResult<PyResults> {
        let mpc = self.mpc.get_mut().map_err(|_| poisoned())?;
        let x = vector(x, "x", Some(mpc.problem().space(0).nx()))?;
        let result = py.detach(|| mpc.solve(&x).map(|_| ()));
        let s = mpc.solution().clone();
        self.raise_python_errors(py)?;
        result.map_err(err)?;
        Ok(PyResults { s })
    }

    /// Moves the horizon one stage along; returns the number of the stage object that
    /// entered.
    fn shift(&mut self, py: Python<'_>) -> PyResult<usize> {
        let mpc = self.mpc.get_mut().map_err(|_| poisoned())?;
        let result = py.detach(|| mpc.shift());
        self.raise_python_errors(py)?;
        result.map_err(err)
    }

    /// Changes the per-cycle budget from the next cycle on (`max_time` in seconds, `None`
    /// or `inf`: none).
    #[pyo3(name = "set_budget", signature = (max_iters, max_time = None))]
    fn set_budget(&mut self, max_iters: usize, max_time: Option<f64>) -> PyResult<()> {
        let max_time = budget(max_time)?;
        let mpc = self.mpc.get_mut().map_err(|_| poisoned())?;
        mpc.set_budget(max_iters, max_time).map_err(err)
    }

    /// The control of the last cycle's feedback policy at the state `x`.
    fn control<'py>(&mut self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mpc = self.mpc.get_mut().map_err(|_| poisoned())?;
        let x = vector(x, "x", Some(mpc.problem().space(0).nx()))?;
        let mut u = vec![0.0; mpc.problem().nu(0)];
        mpc.control(&x, &mut u).map_err(err)?;
        Ok(array1(py, &u))
    }

    /// Shifts so far (completed cycles).
    #[getter]
    fn cycles(&self) -> PyResult<usize> {
        Ok(self.mpc.lock().map_err(|_| poisoned())?.cycles())
    }

    /// The stage object at each knot of the horizon (horizon stages `0..N`, queued
    /// ones `N..`).
    #[getter]
    fn stage_ids(&self) -> PyResult<Vec<usize>> {
        Ok(self.mpc.lock().map_err(|_| poisoned())?.stage_ids().to_vec())
    }

    fn __repr__(&self) -> String {
        match self.mpc.lock() {
            Ok(m) => format!(
                "MPC({}, N = {}, cycles = {})",
                m.solver().name(),
                m.problem().horizon(),
                m.cycles()
            ),
            Err(_) => "MPC(poisoned)".into(),
        }
    }
}

impl PyMpc {
    /// Raises the first exception a Python model of the horizon or the queue recorded.
    fn raise_python_errors(&self, py: Python<'_>) -> PyResult<()> {
        self.problem.borrow(py).raise_python_errors(py)?;
        let queued = self
            .queue_slots
            .iter()
            .enumerate()
            .map(|(i, s)| (format!("queued stage {i}"), s));
        raise_slot_errors(py, queued)
    }
}

fn poisoned() -> PyErr {
    pyo3::exceptions::PyRuntimeError::new_err("MPC lock poisoned")
}

/// Registers `MPC`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyMpc>()
}
