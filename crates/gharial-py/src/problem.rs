//! `StageModel` and `TrajOptProblem`.

use std::sync::Arc;

use gharial::costs::Cost;
use gharial::problem::{InitialCondition, Problem, StageConstraint, StageModel};
use pyo3::prelude::*;

use crate::constraints::PyConstraintSet;
use crate::convert::{GharialError, err, value_error, vector};
use crate::costs::cost_of;
use crate::dynamics::PyDynamics;
use crate::functions::function_of;
use crate::pymodel::Slots;
use crate::spaces::PyManifold;

/// One stage: cost, dynamics and path constraints `h(x, u) ∈ C`. A problem holds its
/// stage objects (ALIGATOR's shared pointers): a constraint added to one later reaches
/// every problem holding it at its next solve.
#[pyclass(name = "StageModel", module = "gharial")]
#[derive(Clone)]
pub struct PyStageModel {
    /// The stage.
    pub model: StageModel,
    /// Slots of the Python models inside.
    pub slots: Slots,
    /// Counts the changes (added constraints), for the problems' caches.
    version: u64,
}

fn constraint_of(
    name: String,
    func: &Bound<'_, PyAny>,
    set: &Bound<'_, PyConstraintSet>,
    scale: f64,
) -> PyResult<(StageConstraint, Slots)> {
    let (f, slots) = function_of(func)?;
    Ok((
        StageConstraint::new(name, f, set.get().inner.clone()).with_scale(scale),
        slots,
    ))
}

#[pymethods]
impl PyStageModel {
    #[new]
    fn new(cost: &Bound<'_, PyAny>, dynamics: &Bound<'_, PyDynamics>) -> PyResult<Self> {
        let (cost, mut slots) = cost_of(cost)?;
        let d = dynamics.get();
        slots.extend(d.slots.iter().cloned());
        let model = StageModel::new(cost, d.inner.clone()).map_err(err)?;
        Ok(Self {
            model,
            slots,
            version: 0,
        })
    }

    /// Adds the path constraint `func(x, u) ∈ set` (`scale` multiplies its penalty).
    #[pyo3(name = "addConstraint", signature = (func, set, scale = 1.0))]
    fn add_constraint(
        &mut self,
        func: &Bound<'_, PyAny>,
        set: &Bound<'_, PyConstraintSet>,
        scale: f64,
    ) -> PyResult<()> {
        let name = format!("constraint {}", self.model.constraints().len());
        let (c, slots) = constraint_of(name, func, set, scale)?;
        self.model.add_constraint(c).map_err(err)?;
        self.slots.extend(slots);
        self.version += 1;
        Ok(())
    }

    /// Control size.
    #[getter]
    fn nu(&self) -> usize {
        self.model.nu()
    }

    /// Total constraint size.
    #[getter]
    fn nc(&self) -> usize {
        self.model.nc()
    }

    /// Number of path constraints.
    #[getter]
    fn num_constraints(&self) -> usize {
        self.model.constraints().len()
    }

    /// The state space.
    #[getter]
    fn space(&self) -> PyManifold {
        PyManifold::new(self.model.space().clone())
    }
}

/// An optimal control problem (ALIGATOR's `TrajOptProblem`): `TrajOptProblem(x0,
/// stages, term_cost)`, or `TrajOptProblem(x0, nu, space, term_cost)` followed by
/// `addStage`.
#[pyclass(name = "TrajOptProblem", module = "gharial")]
pub struct PyProblem {
    init: InitialCondition,
    /// The stage objects (shared with Python).
    stages: Vec<Py<PyStageModel>>,
    /// The stages' versions when `cached` was built.
    built_versions: Vec<u64>,
    terminal_cost: Arc<dyn Cost>,
    terminal_slots: Slots,
    terminal_constraints: Vec<StageConstraint>,
    cached: Option<Arc<Problem>>,
    generation: u64,
}

/// Counts the problems built, so that a solver knows whether it was set up for this one.
static GENERATION: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl PyProblem {
    /// An identifier of the Rust problem last built (changes with every rebuild).
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Wraps a problem built in Rust (the catalogue's).
    pub fn from_rust(py: Python<'_>, p: &Problem) -> PyResult<Self> {
        let stages = p
            .stages()
            .iter()
            .map(|s| {
                let stage = PyStageModel {
                    model: s.clone(),
                    slots: Vec::new(),
                    version: 0,
                };
                Py::new(py, stage)
            })
            .collect::<PyResult<Vec<_>>>()?;
        Ok(Self {
            init: p.initial_condition().clone(),
            built_versions: vec![0; stages.len()],
            stages,
            terminal_cost: p.terminal_cost().clone(),
            terminal_slots: Vec::new(),
            terminal_constraints: p.terminal_constraints().to_vec(),
            cached: Some(Arc::new(p.clone())),
            generation: GENERATION.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        })
    }

    /// The Rust problem (built once after each change, of the problem or of one of its
    /// stage objects).
    pub fn problem(&mut self, py: Python<'_>) -> PyResult<Arc<Problem>> {
        let current = self.stages.iter().map(|s| s.borrow(py).version);
        if let Some(p) = &self.cached
            && current.eq(self.built_versions.iter().copied())
        {
            return Ok(p.clone());
        }
        let stages: Vec<PyRef<'_, PyStageModel>> = self.stages.iter().map(|s| s.borrow(py)).collect();
        self.built_versions = stages.iter().map(|s| s.version).collect();
        let stages = stages.iter().map(|s| s.model.clone()).collect();
        let mut p = Problem::with_initial(self.init.clone(), stages, self.terminal_cost.clone()).map_err(err)?;
        for c in &self.terminal_constraints {
            p.add_terminal_constraint(c.clone()).map_err(err)?;
        }
        let p = Arc::new(p);
        self.cached = Some(p.clone());
        self.generation = GENERATION.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(p)
    }

    /// Raises the first exception a Python model of this problem recorded, naming its
    /// stage (the first stage holding the model), and clears the others.
    pub fn raise_python_errors(&self, py: Python<'_>) -> PyResult<()> {
        let stages: Vec<PyRef<'_, PyStageModel>> = self.stages.iter().map(|s| s.borrow(py)).collect();
        let named = stages
            .iter()
            .enumerate()
            .map(|(t, s)| (format!("stage {t}"), &s.slots))
            .chain(std::iter::once((
                "the terminal stage".to_string(),
                &self.terminal_slots,
            )));
        raise_slot_errors(py, named)
    }
}

/// Raises the first exception recorded in `slots` (each with where its stage is), and
/// clears the others.
pub fn raise_slot_errors<'a>(py: Python<'_>, slots: impl Iterator<Item = (String, &'a Slots)>) -> PyResult<()> {
    let mut first: Option<PyErr> = None;
    for (where_, slots) in slots {
        for slot in slots {
            if let Some(e) = slot.take()
                && first.is_none()
            {
                let kind = e.get_type(py).name().map(|n| n.to_string()).unwrap_or_default();
                let new = GharialError::new_err(format!(
                    "{kind}: a Python model ({}) raised at {where_}: {}",
                    slot.label,
                    e.value(py)
                ));
                new.set_cause(py, Some(e));
                first = Some(new);
            }
        }
    }
    first.map_or(Ok(()), Err)
}

#[pymethods]
impl PyProblem {
    #[new]
    #[pyo3(signature = (x0, stages_or_nu, space_or_term_cost, term_cost = None))]
    fn new(
        x0: &Bound<'_, PyAny>,
        stages_or_nu: &Bound<'_, PyAny>,
        space_or_term_cost: &Bound<'_, PyAny>,
        term_cost: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let x0 = vector(x0, "x0", None)?;
        let (stages, cost) = match term_cost {
            Some(c) => {
                let space = space_or_term_cost.cast::<PyManifold>()?.get().inner.clone();
                if space.nx() != x0.len() {
                    return Err(value_error(format!(
                        "x0: expected {} entries, got {}",
                        space.nx(),
                        x0.len()
                    )));
                }
                (Vec::new(), c)
            }
            None => {
                let stages: Vec<Py<PyStageModel>> = stages_or_nu.extract()?;
                (stages, space_or_term_cost)
            }
        };
        let (terminal_cost, terminal_slots) = cost_of(cost)?;
        let mut p = Self {
            init: InitialCondition::Fixed(x0),
            built_versions: Vec::new(),
            stages,
            terminal_cost,
            terminal_slots,
            terminal_constraints: Vec::new(),
            cached: None,
            generation: 0,
        };
        if term_cost.is_none() {
            p.problem(stages_or_nu.py())?;
        }
        Ok(p)
    }

    /// Appends a stage.
    #[pyo3(name = "addStage")]
    fn add_stage(&mut self, stage: Py<PyStageModel>) {
        self.stages.push(stage);
        self.cached = None;
    }

    /// Adds the terminal constraint `func(x_N) ∈ set` (a function with `nu = 0`).
    #[pyo3(name = "addTerminalConstraint", signature = (func, set, scale = 1.0))]
    fn add_terminal_constraint(
        &mut self,
        func: &Bound<'_, PyAny>,
        set: &Bound<'_, PyConstraintSet>,
        scale: f64,
    ) -> PyResult<()> {
        let name = format!("terminal constraint {}", self.terminal_constraints.len());
        let (c, slots) = constraint_of(name, func, set, scale)?;
        self.terminal_constraints.push(c);
        self.terminal_slots.extend(slots);
        self.cached = None;
        if !self.stages.is_empty()
            && let Err(e) = self.problem(func.py())
        {
            self.terminal_constraints.pop();
            self.cached = None;
            return Err(e);
        }
        Ok(())
    }

    /// The initial state (settable: the next solve starts from it).
    #[getter]
    fn get_x0_init<'py>(&self, py: Python<'py>) -> Option<Bound<'py, numpy::PyArray1<f64>>> {
        match &self.init {
            InitialCondition::Fixed(x0) => Some(crate::convert::array1(py, x0)),
            InitialCondition::Constraint(_) => None,
        }
    }
    #[setter]
    fn set_x0_init(&mut self, x0: &Bound<'_, PyAny>) -> PyResult<()> {
        let x0 = vector(x0, "x0", None)?;
        if let Some(p) = &mut self.cached {
            Arc::make_mut(p).set_x0(&x0).map_err(err)?;
        }
        self.init = InitialCondition::Fixed(x0);
        Ok(())
    }

    /// Number of stages N.
    #[getter]
    fn num_steps(&self) -> usize {
        self.stages.len()
    }

    /// The stage objects, as a tuple (the same objects at every access: a constraint
    /// added to one reaches the problem; replacing an entry is not possible, which a list
    /// would have allowed without effect).
    #[getter]
    fn stages<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
        pyo3::types::PyTuple::new(py, self.stages.iter().map(|s| s.clone_ref(py)))
    }

    /// The rollout `x_{t+1} = φ(x_t, u_t)` of `us` from the initial state (implicit
    /// dynamics by Newton's method).
    fn rollout<'py>(&mut self, py: Python<'py>, us: &Bound<'py, PyAny>) -> PyResult<Bound<'py, pyo3::types::PyList>> {
        let p = self.problem(py)?;
        let us = crate::convert::vectors(us, "us")?;
        let mut data = gharial::problem::ProblemData::new(&p, 1).map_err(err)?;
        let mut xs: Vec<Vec<f64>> = (0..=p.horizon()).map(|t| vec![0.0; p.space(t).nx()]).collect();
        if let Some(x0) = p.x0() {
            xs[0].copy_from_slice(x0);
        }
        let result = py.detach(|| data.rollout(&p, &mut xs, &us));
        self.raise_python_errors(py)?;
        result.map_err(err)?;
        crate::convert::arrays1(py, &xs)
    }
}

/// Registers the classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyStageModel>()?;
    m.add_class::<PyProblem>()?;
    Ok(())
}
