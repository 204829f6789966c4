//! Solvers with their options as attributes, and their `Results`.

use std::sync::{Arc, Mutex};

use gharial::problem::{Problem, ProblemData};
use gharial::solvers::log::LogSink;
use gharial::solvers::{InitialGuess, IterationRecord, Solution, Solver, SolverOptions};
use pyo3::PyClassInitializer;
use pyo3::exceptions::{PyAttributeError, PyRuntimeError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{array1, array2, arrays1, err, value_error, vectors_into};
use crate::options::{field, option_names, solver_options};
use crate::problem::PyProblem;

/// A solver of the `TrajOptProblem`s (base class of `SolverProxDDP`, `SolverFDDP`, ...):
/// `setup(problem)`, `run(problem, xs_init, us_init)`, `results`; every option is an
/// attribute (`solver.tol = 1e-8`), checked when set.
#[pyclass(subclass, name = "Solver", module = "gharial")]
pub struct PySolver {
    options: SolverOptions,
    verbose: bool,
    /// The Rust solver, set up for `setup_key`; taken out while it runs.
    solver: Mutex<Option<Box<dyn Solver>>>,
    dirty: bool,
    /// The problem generation the solver was set up for.
    setup_for: u64,
    /// Whether a solve has run on the current Rust solver (its solution is the results).
    has_results: bool,
    /// The results, copied from the solver at the first access after a solve; the copy
    /// of an earlier solve is released by that access, not by the solve.
    results: Option<Py<PyResults>>,
    /// Whether `results` is the copy of the last solve.
    results_current: bool,
    /// The guess of the next solve, read into buffers kept between solves.
    guess: GuessBuffers,
}

/// The `snake_case` name of a status.
pub fn status_name(s: gharial::solvers::Status) -> String {
    s.name().to_string()
}

impl PySolver {
    /// A solver named `name` with `kwargs` applied to its defaults.
    pub fn with(name: &str, kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Self::with_options(solver_options(SolverOptions::from_name(name))?, kwargs)
    }

    /// A solver with `kwargs` applied to `options`.
    pub fn with_options(options: SolverOptions, kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut s = Self {
            options,
            verbose: false,
            solver: Mutex::new(None),
            dirty: true,
            setup_for: 0,
            has_results: false,
            results: None,
            results_current: false,
            guess: GuessBuffers::default(),
        };
        if let Some(kw) = kwargs {
            for (k, v) in kw.iter() {
                s.set_option(&k.extract::<String>()?, &v)?;
            }
        }
        Ok(s)
    }

    fn set_option(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        if name == "verbose" {
            self.verbose = value.is_truthy()?;
            self.dirty = true;
            return Ok(());
        }
        let previous = self.options.clone();
        let solver = self.options.name();
        let mut option = field(&mut self.options, name)
            .ok_or_else(|| PyAttributeError::new_err(format!("solver `{solver}` has no option `{name}`")))?;
        option.set(name, value)?;
        if let Err(e) = self.options.validate() {
            self.options = previous;
            return Err(value_error(e.to_string()));
        }
        self.dirty = true;
        Ok(())
    }

    /// A new Rust solver with these options (not set up).
    pub fn build(&self) -> Box<dyn Solver> {
        self.effective_options().build()
    }

    /// The Rust options with the log sink that `verbose` asks for.
    fn effective_options(&self) -> SolverOptions {
        let mut o = self.options.clone();
        if self.verbose {
            o.set_log(LogSink::Function(Arc::new(|line: &str| {
                Python::attach(|py| {
                    let _ = py.import("builtins").and_then(|b| b.call_method1("print", (line,)));
                })
            })));
        }
        o
    }

    fn setup_rust(&mut self, problem: &Problem, generation: u64) -> PyResult<()> {
        let mut solver = self.effective_options().build();
        solver.setup(problem).map_err(err)?;
        self.setup_for = generation;
        self.has_results = false;
        self.results = None;
        *self
            .solver
            .get_mut()
            .map_err(|_| PyRuntimeError::new_err("solver lock poisoned"))? = Some(solver);
        self.dirty = false;
        Ok(())
    }
}

/// A list of vectors (states, controls, multipliers).
pub type Trajectory = Vec<Vec<f64>>;

/// Co-states and path multipliers of a warm start.
pub type Duals<'a> = (&'a [Vec<f64>], &'a [Vec<f64>]);

/// Solves `problem` with a set-up `solver` from the guess, without the GIL; returns
/// whether it converged (the solution stays in the solver).
pub fn solve_detached(
    py: Python<'_>,
    solver: &mut dyn Solver,
    problem: &Problem,
    xs: &[Vec<f64>],
    us: &[Vec<f64>],
    duals: Option<Duals<'_>>,
) -> gharial::Result<bool> {
    py.detach(|| {
        let mut guess = InitialGuess::primal(xs, us);
        if let Some((l, n)) = duals {
            guess.lambdas = Some(l);
            guess.nus = Some(n);
        }
        solver.solve(problem, guess).map(|s| s.status.converged())
    })
}

/// The guess of a solve (states, controls, multipliers), kept between solves so that a
/// guess of the same shape is read without allocation.
#[derive(Default)]
pub struct GuessBuffers {
    /// States.
    pub xs: Trajectory,
    /// Controls.
    pub us: Trajectory,
    /// Co-states (warm start).
    pub lambdas: Trajectory,
    /// Path multipliers (warm start).
    pub nus: Trajectory,
    /// The evaluation buffers of the default guess's rollout and the problem generation
    /// they were made for.
    rollout: Option<(u64, ProblemData)>,
}

impl GuessBuffers {
    /// Reads `[xs, us, lams, vs]` (each optional, given in pairs; no states and controls:
    /// zero controls and their rollout); returns whether multipliers were given.
    pub fn fill(
        &mut self,
        problem: &Bound<'_, PyProblem>,
        p: &Problem,
        [xs, us, lams, vs]: [Option<&Bound<'_, PyAny>>; 4],
    ) -> PyResult<bool> {
        match (xs, us) {
            (Some(xs), Some(us)) => {
                vectors_into(xs, "xs_init", &mut self.xs)?;
                vectors_into(us, "us_init", &mut self.us)?;
            }
            (None, None) => self.rollout_zero_controls(problem, p)?,
            _ => return Err(value_error("give both xs_init and us_init, or neither")),
        }
        match (lams, vs) {
            (Some(l), Some(v)) => {
                vectors_into(l, "lams_init", &mut self.lambdas)?;
                vectors_into(v, "vs_init", &mut self.nus)?;
                Ok(true)
            }
            (None, None) => Ok(false),
            _ => Err(value_error("give both lams_init and vs_init, or neither")),
        }
    }

    /// The default guess: zero controls and their rollout from the initial state (the
    /// neutral point under an initial constraint), without the GIL.
    fn rollout_zero_controls(&mut self, problem: &Bound<'_, PyProblem>, p: &Problem) -> PyResult<()> {
        let generation = problem.borrow().generation();
        let (xs, us) = (&mut self.xs, &mut self.us);
        let cached = self.rollout.take().filter(|(g, _)| *g == generation).map(|(_, d)| d);
        let rolled = problem.py().detach(|| {
            let n = p.horizon();
            us.resize_with(n, Vec::new);
            xs.resize_with(n + 1, Vec::new);
            for (t, u) in us.iter_mut().enumerate() {
                u.clear();
                u.resize(p.nu(t), 0.0);
            }
            for (t, x) in xs.iter_mut().enumerate() {
                x.resize(p.space(t).nx(), 0.0);
            }
            match p.x0() {
                Some(x0) => xs[0].copy_from_slice(x0),
                None => p.space(0).neutral(&mut xs[0]),
            }
            let mut data = match cached {
                Some(d) => d,
                None => ProblemData::new(p, 1)?,
            };
            data.rollout(p, xs, us).map(|()| data)
        });
        problem.borrow().raise_python_errors(problem.py())?;
        self.rollout = Some((generation, rolled.map_err(err)?));
        Ok(())
    }
}

#[pymethods]
impl PySolver {
    #[new]
    #[pyo3(signature = (name, **options))]
    fn py_new(name: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Self::with(name, options)
    }

    /// The solver's name (`proxddp`, `fddp`, ...).
    #[getter]
    fn name(&self) -> &'static str {
        self.options.name()
    }

    /// The option names of this solver.
    #[getter]
    fn option_names(&self) -> Vec<&'static str> {
        let mut v = option_names(&self.options).to_vec();
        v.push("verbose");
        v
    }

    fn __getattr__(&mut self, py: Python<'_>, name: &str) -> PyResult<Py<PyAny>> {
        if name == "verbose" {
            return Ok(pyo3::types::PyBool::new(py, self.verbose)
                .to_owned()
                .into_any()
                .unbind());
        }
        let solver = self.options.name();
        match field(&mut self.options, name) {
            Some(f) => f.get(py),
            None => Err(PyAttributeError::new_err(format!(
                "solver `{solver}` has no attribute `{name}`"
            ))),
        }
    }

    fn __setattr__(&mut self, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.set_option(name, value)
    }

    /// Allocates the solver's workspace for `problem` (done by `run` when needed).
    fn setup(&mut self, problem: &Bound<'_, PyProblem>) -> PyResult<()> {
        let p = problem.borrow_mut().problem(problem.py())?;
        self.setup_rust(&p, problem.borrow().generation())
    }

    /// Solves `problem` from the guess (default: zero controls rolled out; `lams_init`,
    /// `vs_init`: multipliers for a warm start) and returns whether it converged. The
    /// GIL is released during the solve.
    #[pyo3(signature = (problem, xs_init = None, us_init = None, lams_init = None, vs_init = None))]
    fn run(
        slf: &Bound<'_, Self>,
        problem: &Bound<'_, PyProblem>,
        xs_init: Option<&Bound<'_, PyAny>>,
        us_init: Option<&Bound<'_, PyAny>>,
        lams_init: Option<&Bound<'_, PyAny>>,
        vs_init: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        let py = slf.py();
        let p = problem.borrow_mut().problem(problem.py())?;
        let generation = problem.borrow().generation();
        let mut guess = std::mem::take(&mut slf.borrow_mut().guess);
        let filled = guess.fill(problem, &p, [xs_init, us_init, lams_init, vs_init]);
        slf.borrow_mut().guess = guess;
        let with_duals = filled?;
        let mut solver = {
            let mut s = slf.borrow_mut();
            let missing = s.solver.get_mut().map(|o| o.is_none()).unwrap_or(true);
            if s.dirty || missing || s.setup_for != generation {
                s.setup_rust(&p, generation)?;
            }
            s.solver
                .get_mut()
                .ok()
                .and_then(|o| o.take())
                .ok_or_else(|| PyRuntimeError::new_err("the solver is running in another thread"))?
        };
        let g = std::mem::take(&mut slf.borrow_mut().guess);
        let duals = with_duals.then_some((g.lambdas.as_slice(), g.nus.as_slice()));
        let result = solve_detached(py, solver.as_mut(), &p, &g.xs, &g.us, duals);
        let mut s = slf.borrow_mut();
        s.guess = g;
        if let Ok(slot) = s.solver.get_mut() {
            *slot = Some(solver);
        }
        s.results_current = false;
        problem.borrow().raise_python_errors(py)?;
        let converged = result.map_err(err)?;
        s.has_results = true;
        Ok(converged)
    }

    /// The results of the last `run`.
    #[getter]
    fn results(&mut self, py: Python<'_>) -> PyResult<Py<PyResults>> {
        if let Some(r) = &self.results
            && self.results_current
        {
            return Ok(r.clone_ref(py));
        }
        if !self.has_results {
            return Err(PyRuntimeError::new_err("no results: call run() first"));
        }
        let solver = self
            .solver
            .get_mut()
            .map_err(|_| PyRuntimeError::new_err("solver lock poisoned"))?
            .as_ref()
            .ok_or_else(|| PyRuntimeError::new_err("the solver is running in another thread"))?;
        let r = Py::new(
            py,
            PyResults {
                s: solver.solution().clone(),
            },
        )?;
        self.results = Some(r.clone_ref(py));
        self.results_current = true;
        Ok(r)
    }
}

macro_rules! named_solver {
    ($py:ident, $name:literal, $solver:literal, $doc:literal) => {
        #[doc = $doc]
        #[pyclass(extends = PySolver, name = $name, module = "gharial")]
        pub struct $py;

        #[pymethods]
        impl $py {
            #[new]
            #[pyo3(signature = (tol = None, max_iters = None, verbose = false, **options))]
            fn new(
                py: Python<'_>,
                tol: Option<f64>,
                max_iters: Option<usize>,
                verbose: bool,
                options: Option<&Bound<'_, PyDict>>,
            ) -> PyResult<PyClassInitializer<Self>> {
                let all = options.cloned().unwrap_or_else(|| PyDict::new(py));
                let base = named_solver_base($solver, tol, max_iters, verbose, &all)?;
                Ok(PyClassInitializer::from(base).add_subclass(Self))
            }
        }
    };
}

/// ProxDDP (Jallet et al. 2023), ALIGATOR's solver, with ALIGATOR's constructor
/// `SolverProxDDP(tol, mu_init, max_iters=..., verbose=...)`.
#[pyclass(extends = PySolver, name = "SolverProxDDP", module = "gharial")]
pub struct PyProxDdp;

#[pymethods]
impl PyProxDdp {
    #[new]
    #[pyo3(signature = (tol = None, mu_init = None, max_iters = None, verbose = false, **options))]
    fn new(
        py: Python<'_>,
        tol: Option<f64>,
        mu_init: Option<f64>,
        max_iters: Option<usize>,
        verbose: bool,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let all = options.cloned().unwrap_or_else(|| PyDict::new(py));
        if let Some(m) = mu_init {
            all.set_item("mu_init", m)?;
        }
        let base = named_solver_base("proxddp", tol, max_iters, verbose, &all)?;
        Ok(PyClassInitializer::from(base).add_subclass(Self))
    }
}

/// The solver `name` with the options of a named class's constructor.
fn named_solver_base(
    name: &str,
    tol: Option<f64>,
    max_iters: Option<usize>,
    verbose: bool,
    all: &Bound<'_, PyDict>,
) -> PyResult<PySolver> {
    if let Some(t) = tol {
        all.set_item("tol", t)?;
    }
    if let Some(m) = max_iters {
        all.set_item("max_iters", m)?;
    }
    all.set_item("verbose", verbose)?;
    PySolver::with(name, Some(all))
}
named_solver!(PyDdp, "SolverDDP", "ddp", "DDP / iLQR (crocoddyl's SolverDDP).");
named_solver!(
    PyFddp,
    "SolverFDDP",
    "fddp",
    "Feasibility-driven DDP (crocoddyl's SolverFDDP)."
);
named_solver!(
    PyBoxDdp,
    "SolverBoxDDP",
    "box-ddp",
    "DDP with control bounds (crocoddyl's SolverBoxDDP)."
);
named_solver!(
    PyBoxFddp,
    "SolverBoxFDDP",
    "box-fddp",
    "FDDP with control bounds (crocoddyl's SolverBoxFDDP)."
);
named_solver!(PySqp, "SolverSQP", "sqp", "Stagewise SQP (mim_solvers' SolverSQP).");
named_solver!(
    PyCsqp,
    "SolverCSQP",
    "csqp",
    "Constrained stagewise SQP (mim_solvers' SolverCSQP)."
);
named_solver!(
    PyBclDdp,
    "SolverBCLDDP",
    "bcl-ddp",
    "Equality-constrained DDP with the BCL globalisation (El Kazdadi et al. 2021)."
);
named_solver!(
    PyAltro,
    "SolverALTRO",
    "altro",
    "AL-iLQR with the Newton projection (ALTRO, Howell et al. 2019)."
);
named_solver!(
    PyProxNlp,
    "SolverProxNLP",
    "proxnlp",
    "ProxNLP on the whole problem, its KKT system solved densely or sparsely (proxnlp's solver)."
);

/// A solver by name (`proxddp`, `ddp`, `fddp`, `box-ddp`, `box-fddp`, `sqp`, `csqp`,
/// `bcl-ddp`, `altro`, `proxnlp`) with options.
#[pyfunction]
#[pyo3(signature = (name, **options))]
fn solver(name: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<PySolver> {
    PySolver::with(name, options)
}

/// The names of the solvers.
#[pyfunction]
fn solver_names() -> Vec<&'static str> {
    SolverOptions::names().to_vec()
}

/// The result of a solve (ALIGATOR's `Results`): trajectories and multipliers as numpy
/// arrays, gains, status, residuals and the iteration history.
#[pyclass(frozen, name = "Results", module = "gharial")]
pub struct PyResults {
    /// The Rust solution.
    pub s: Solution,
}

#[pymethods]
impl PyResults {
    /// States `x_0..x_N`.
    #[getter]
    fn xs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        arrays1(py, &self.s.xs)
    }
    /// Controls `u_0..u_{N-1}`.
    #[getter]
    fn us<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        arrays1(py, &self.s.us)
    }
    /// Co-states `λ_0..λ_N` (ALIGATOR's `lams`).
    #[getter]
    fn lams<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        arrays1(py, &self.s.lambdas)
    }
    /// Path multipliers `ν_0..ν_N`, the last the terminal ones (ALIGATOR's `vs`).
    #[getter]
    fn vs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        arrays1(py, &self.s.nus)
    }
    /// Feedback gains `K_t` (`nu x ndx`): `δu = k + K δx`.
    #[getter]
    fn gains<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        PyList::new(py, self.s.feedback.iter().map(|k| array2(py, k.as_ref())))
    }
    /// Feedforward terms `k_t`.
    #[getter]
    fn feedforward<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        PyList::new(
            py,
            self.s.feedforward.iter().map(|k| array1(py, gharial::linalg::slice(k))),
        )
    }
    /// Iterations taken.
    #[getter]
    fn num_iters(&self) -> usize {
        self.s.iterations
    }
    /// Augmented-Lagrangian iterations.
    #[getter]
    fn al_iter(&self) -> usize {
        self.s.al_iterations
    }
    /// Final cost.
    #[getter]
    fn traj_cost(&self) -> f64 {
        self.s.cost
    }
    /// Final primal residual.
    #[getter]
    fn primal_infeas(&self) -> f64 {
        self.s.prim_err
    }
    /// Final dual residual.
    #[getter]
    fn dual_infeas(&self) -> f64 {
        self.s.dual_err
    }
    /// Whether the solver converged.
    #[getter]
    fn conv(&self) -> bool {
        self.s.status.converged()
    }
    /// How the solver stopped (`converged`, `max_iterations`, `linesearch_failure`, ...).
    #[getter]
    fn status(&self) -> String {
        status_name(self.s.status)
    }
    /// Final penalty parameter.
    #[getter]
    fn mu(&self) -> f64 {
        self.s.mu
    }
    /// Wall time of the solve, in seconds.
    #[getter]
    fn solve_time(&self) -> f64 {
        self.s.solve_time.as_secs_f64()
    }
    /// Draws `<name>-convergence` and `<name>-trajectory` (PNG or SVG) into `directory`:
    /// the residuals per iteration, and the states and controls (against time when `dt`
    /// is given; with the control bounds when `problem`'s path constraints bound the
    /// controls). Returns the files written.
    #[pyo3(signature = (directory, name = "solution", dt = None, problem = None, format = "png"))]
    fn plot(
        &self,
        directory: &str,
        name: &str,
        dt: Option<f64>,
        problem: Option<&Bound<'_, PyProblem>>,
        format: &str,
    ) -> PyResult<Vec<String>> {
        crate::viz::plot_solution(&self.s, directory, name, dt, problem, format)
    }
    /// The iteration history: one numpy array per column.
    #[getter]
    fn history<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        history(py, &self.s.history)
    }

    /// Everything as a dict of plain values and numpy arrays.
    fn to_dict<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(slf.py());
        for key in [
            "xs",
            "us",
            "lams",
            "vs",
            "gains",
            "feedforward",
            "num_iters",
            "al_iter",
            "traj_cost",
            "primal_infeas",
            "dual_infeas",
            "conv",
            "status",
            "mu",
            "solve_time",
            "history",
        ] {
            d.set_item(key, slf.getattr(key)?)?;
        }
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Results(status={}, num_iters={}, traj_cost={:.6e}, primal_infeas={:.3e}, dual_infeas={:.3e})",
            status_name(self.s.status),
            self.s.iterations,
            self.s.cost,
            self.s.prim_err,
            self.s.dual_err
        )
    }
}

fn history<'py>(py: Python<'py>, h: &[IterationRecord]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let col = |f: fn(&IterationRecord) -> f64| array1(py, &h.iter().map(f).collect::<Vec<_>>());
    d.set_item("iter", col(|r| r.iter as f64))?;
    d.set_item("alpha", col(|r| r.alpha))?;
    d.set_item("inner_crit", col(|r| r.inner_crit))?;
    d.set_item("prim_err", col(|r| r.prim_err))?;
    d.set_item("dual_err", col(|r| r.dual_err))?;
    d.set_item("preg", col(|r| r.preg))?;
    d.set_item("cost", col(|r| r.cost))?;
    d.set_item("merit", col(|r| r.merit))?;
    d.set_item("al_iter", col(|r| r.al_iter as f64))?;
    d.set_item("mu", col(|r| r.mu))?;
    d.set_item("stop", col(|r| r.stop))?;
    Ok(d)
}

/// Registers the classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySolver>()?;
    m.add_class::<PyProxDdp>()?;
    m.add_class::<PyDdp>()?;
    m.add_class::<PyFddp>()?;
    m.add_class::<PyBoxDdp>()?;
    m.add_class::<PyBoxFddp>()?;
    m.add_class::<PySqp>()?;
    m.add_class::<PyCsqp>()?;
    m.add_class::<PyBclDdp>()?;
    m.add_class::<PyAltro>()?;
    m.add_class::<PyProxNlp>()?;
    m.add_class::<PyResults>()?;
    m.add_function(wrap_pyfunction!(solver, m)?)?;
    m.add_function(wrap_pyfunction!(solver_names, m)?)?;
    Ok(())
}
