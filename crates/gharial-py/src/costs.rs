//! Costs `ℓ(x, u)`; `CostAbstract` subclassed in Python; cost stacks with named weights.

use std::sync::Arc;

use faer::Mat;
use gharial::costs::{Cost, CostStack, QuadraticControlCost, QuadraticCost, QuadraticResidualCost, QuadraticStateCost};
use gharial::spaces::Manifold;
use pyo3::PyClassInitializer;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{array1, array2, err, matrix, value_error, vector};
use crate::functions::{function_of, subclass_init};
use crate::pymodel::{PyCostModel, Slots};
use crate::spaces::PyManifold;

/// A cost `ℓ(x, u)` (ALIGATOR's `CostAbstract`; base class of every cost).
///
/// Subclass it in Python with `super().__init__(space, nu)`, `evaluate(x, u) -> float`
/// and `derivatives(x, u) -> (lx, lu, lxx, lxu, luu)` (`ndx`, `nu`, `ndx x ndx`,
/// `ndx x nu`, `nu x nu`).
#[pyclass(subclass, name = "CostAbstract", module = "gharial")]
pub struct PyCost {
    inner: Option<Arc<dyn Cost>>,
    slots: Slots,
    py_dims: Option<(Arc<dyn Manifold>, usize)>,
}

impl PyCost {
    /// A Rust cost with the slots of the Python models inside it.
    pub fn rust(inner: Arc<dyn Cost>, slots: Slots) -> Self {
        Self {
            inner: Some(inner),
            slots,
            py_dims: None,
        }
    }
}

/// The Rust cost of a `CostAbstract` object (a Python subclass is wrapped, after one
/// checked call of its methods) and the slots of the Python models inside it.
pub fn cost_of(obj: &Bound<'_, PyAny>) -> PyResult<(Arc<dyn Cost>, Slots)> {
    let c = obj
        .cast::<PyCost>()
        .map_err(|_| PyTypeError::new_err("expected a gharial.CostAbstract"))?;
    let b = c.borrow();
    if let Some(inner) = &b.inner {
        return Ok((inner.clone(), b.slots.clone()));
    }
    let (space, nu) = b
        .py_dims
        .clone()
        .ok_or_else(|| PyTypeError::new_err("a CostAbstract subclass must call super().__init__(space, nu)"))?;
    drop(b);
    let (model, slot) = PyCostModel::new(obj, space.as_ref(), nu)?;
    Ok((model, vec![slot]))
}

#[pymethods]
impl PyCost {
    #[new]
    #[pyo3(signature = (*_args, **_kwargs))]
    fn py_new(_args: &Bound<'_, PyTuple>, _kwargs: Option<&Bound<'_, PyDict>>) -> Self {
        Self {
            inner: None,
            slots: Vec::new(),
            py_dims: None,
        }
    }

    #[pyo3(signature = (*args, **kwargs))]
    fn __init__(&mut self, args: &Bound<'_, PyTuple>, kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        if self.inner.is_some() {
            return Ok(());
        }
        let (space, n) = subclass_init(args, kwargs, &["nu"], "CostAbstract")?;
        self.py_dims = Some((space, n[0]));
        Ok(())
    }

    /// Tangent size of the state.
    #[getter]
    fn ndx(&self) -> usize {
        match (&self.inner, &self.py_dims) {
            (Some(c), _) => c.ndx(),
            (None, Some((s, _))) => s.ndx(),
            _ => 0,
        }
    }

    /// Control size (0 for terminal costs).
    #[getter]
    fn nu(&self) -> usize {
        match (&self.inner, &self.py_dims) {
            (Some(c), _) => c.nu(),
            (None, Some((_, nu))) => *nu,
            _ => 0,
        }
    }

    /// `ℓ(x, u)` of a Rust cost.
    #[pyo3(name = "value")]
    fn py_value(slf: &Bound<'_, Self>, x: &Bound<'_, PyAny>, u: &Bound<'_, PyAny>) -> PyResult<f64> {
        let (c, _) = cost_of(slf.as_any())?;
        let (x, u) = (vector(x, "x", Some(c.nx()))?, vector(u, "u", Some(c.nu()))?);
        let mut data = c.create_data();
        c.evaluate(&x, &u, &mut data);
        Ok(data.value)
    }

    /// `(lx, lu, lxx, lxu, luu)` of a Rust cost at `(x, u)`.
    #[pyo3(name = "gradient_hessian")]
    fn py_derivatives<'py>(
        slf: &Bound<'py, Self>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let (c, _) = cost_of(slf.as_any())?;
        let (x, u) = (vector(x, "x", Some(c.nx()))?, vector(u, "u", Some(c.nu()))?);
        let mut d = c.create_data();
        c.evaluate(&x, &u, &mut d);
        c.derivatives(&x, &u, &mut d);
        let py = slf.py();
        PyTuple::new(
            py,
            [
                array1(py, d.lx()).into_any(),
                array1(py, d.lu()).into_any(),
                array2(py, d.lxx.as_ref()).into_any(),
                array2(py, d.lxu.as_ref()).into_any(),
                array2(py, d.luu.as_ref()).into_any(),
            ],
        )
    }
}

/// Weights: a vector (the diagonal, kept as such by the diagonal constructors) or a
/// square matrix of size `n`.
enum Weights {
    Diagonal(Vec<f64>),
    Full(Mat<f64>),
}

fn weights(obj: &Bound<'_, PyAny>, what: &str, n: usize) -> PyResult<Weights> {
    let ndim: usize = obj.py().import("numpy")?.call_method1("ndim", (obj,))?.extract()?;
    if ndim == 1 {
        Ok(Weights::Diagonal(vector(obj, what, Some(n))?))
    } else {
        Ok(Weights::Full(matrix(obj, what, Some((n, n)))?))
    }
}

/// `½ xᵀ Q x + xᵀ N u + ½ uᵀ R u + qᵀ x + rᵀ u` on a vector space.
#[pyclass(extends = PyCost, name = "QuadraticCost", module = "gharial")]
pub struct PyQuadraticCost;

#[pymethods]
impl PyQuadraticCost {
    #[new]
    #[pyo3(signature = (w_x, w_u, w_cross = None, q = None, r = None))]
    fn new(
        w_x: &Bound<'_, PyAny>,
        w_u: &Bound<'_, PyAny>,
        w_cross: Option<&Bound<'_, PyAny>>,
        q: Option<&Bound<'_, PyAny>>,
        r: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let wq = matrix(w_x, "QuadraticCost w_x", None)?;
        let wr = matrix(w_u, "QuadraticCost w_u", None)?;
        let (nx, nu) = (wq.nrows(), wr.nrows());
        let n = match w_cross {
            Some(n) => matrix(n, "QuadraticCost w_cross", Some((nx, nu)))?,
            None => Mat::zeros(nx, nu),
        };
        let q = q.map(|q| vector(q, "QuadraticCost q", Some(nx))).transpose()?;
        let r = r.map(|r| vector(r, "QuadraticCost r", Some(nu))).transpose()?;
        let (q, r) = (q.unwrap_or(vec![0.0; nx]), r.unwrap_or(vec![0.0; nu]));
        let c = QuadraticCost::new(wq.as_ref(), n.as_ref(), wr.as_ref(), &q, &r).map_err(err)?;
        Ok(PyClassInitializer::from(PyCost::rust(Arc::new(c), Vec::new())).add_subclass(Self))
    }
}

/// `½ ‖x ⊖ x_ref‖²_W` (ALIGATOR's `QuadraticStateCost(space, nu, target, weights)`;
/// weights: a diagonal vector or an `ndx x ndx` matrix).
#[pyclass(extends = PyCost, name = "QuadraticStateCost", module = "gharial")]
pub struct PyQuadraticStateCost;

#[pymethods]
impl PyQuadraticStateCost {
    #[new]
    fn new(
        space: &Bound<'_, PyManifold>,
        nu: usize,
        target: &Bound<'_, PyAny>,
        weights: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let space = space.get().inner.clone();
        let target = vector(target, "QuadraticStateCost target", Some(space.nx()))?;
        let c = match self::weights(weights, "QuadraticStateCost weights", space.ndx())? {
            Weights::Diagonal(w) => QuadraticStateCost::diagonal(space, &target, &w, nu),
            Weights::Full(w) => QuadraticStateCost::new(space, &target, w.as_ref(), nu),
        }
        .map_err(err)?;
        Ok(PyClassInitializer::from(PyCost::rust(Arc::new(c), Vec::new())).add_subclass(Self))
    }
}

/// `½ ‖u - u_ref‖²_W` (ALIGATOR's `QuadraticControlCost(space, target, weights)`).
#[pyclass(extends = PyCost, name = "QuadraticControlCost", module = "gharial")]
pub struct PyQuadraticControlCost;

#[pymethods]
impl PyQuadraticControlCost {
    #[new]
    fn new(
        space: &Bound<'_, PyManifold>,
        target: &Bound<'_, PyAny>,
        weights: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let target = vector(target, "QuadraticControlCost target", None)?;
        let space = space.get().inner.clone();
        let c = match self::weights(weights, "QuadraticControlCost weights", target.len())? {
            Weights::Diagonal(w) => QuadraticControlCost::diagonal(space.as_ref(), &target, &w),
            Weights::Full(w) => QuadraticControlCost::new(space.as_ref(), &target, w.as_ref()),
        }
        .map_err(err)?;
        Ok(PyClassInitializer::from(PyCost::rust(Arc::new(c), Vec::new())).add_subclass(Self))
    }
}

/// `½ r(x, u)ᵀ W r(x, u)` of any stage function (ALIGATOR's
/// `QuadraticResidualCost(space, function, weights)`).
#[pyclass(extends = PyCost, name = "QuadraticResidualCost", module = "gharial")]
pub struct PyQuadraticResidualCost;

#[pymethods]
impl PyQuadraticResidualCost {
    #[new]
    fn new(
        space: &Bound<'_, PyManifold>,
        function: &Bound<'_, PyAny>,
        weights: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (f, slots) = function_of(function)?;
        if f.nx() != space.get().inner.nx() {
            return Err(value_error(format!(
                "QuadraticResidualCost: function on states of size {}, space of size {}",
                f.nx(),
                space.get().inner.nx()
            )));
        }
        let c = match self::weights(weights, "QuadraticResidualCost weights", f.nr())? {
            Weights::Diagonal(w) => QuadraticResidualCost::diagonal(f, &w),
            Weights::Full(w) => QuadraticResidualCost::new(f, w.as_ref()),
        }
        .map_err(err)?;
        Ok(PyClassInitializer::from(PyCost::rust(Arc::new(c), slots)).add_subclass(Self))
    }
}

/// A weighted sum of named costs (ALIGATOR's `CostStack(space, nu)` with
/// `addCost(name, cost, weight)`); weights can be changed between solves with
/// `set_weight`, on every stage that holds the stack.
#[pyclass(extends = PyCost, name = "CostStack", module = "gharial")]
pub struct PyCostStack {
    space: Arc<dyn Manifold>,
    nu: usize,
    stack: Arc<CostStack>,
    components: Vec<(String, Arc<dyn Cost>, f64)>,
}

#[pymethods]
impl PyCostStack {
    #[new]
    fn new(space: &Bound<'_, PyManifold>, nu: usize) -> PyClassInitializer<Self> {
        let space = space.get().inner.clone();
        let stack = Arc::new(CostStack::new(space.as_ref(), nu));
        let base = PyCost::rust(stack.clone(), Vec::new());
        PyClassInitializer::from(base).add_subclass(Self {
            space,
            nu,
            stack,
            components: Vec::new(),
        })
    }

    /// Adds the component `name` with weight `weight` (the stack object is rebuilt:
    /// stages made before keep the components they had).
    #[pyo3(name = "addCost", signature = (name, cost, weight = 1.0))]
    fn add_cost(mut slf: PyRefMut<'_, Self>, name: String, cost: &Bound<'_, PyAny>, weight: f64) -> PyResult<()> {
        let (c, slots) = cost_of(cost)?;
        let mut stack = CostStack::new(slf.space.as_ref(), slf.nu);
        for (n, c, w) in &slf.components {
            stack = stack.with(n.clone(), c.clone(), *w).map_err(err)?;
        }
        stack = stack.with(name.clone(), c.clone(), weight).map_err(err)?;
        slf.components.push((name, c, weight));
        slf.stack = Arc::new(stack);
        let stack: Arc<dyn Cost> = slf.stack.clone();
        let mut base = slf.into_super();
        base.inner = Some(stack);
        base.slots.extend(slots);
        Ok(())
    }

    /// Changes the weight of component `name` (through every stage holding this stack).
    fn set_weight(&self, name: &str, weight: f64) -> PyResult<()> {
        self.stack.set_weight(name, weight).map_err(err)
    }

    /// The weight of component `name`.
    fn weight(&self, name: &str) -> PyResult<f64> {
        self.stack.weight(name).map_err(err)
    }

    /// Component names, in order.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.stack.names().to_vec()
    }

    fn __len__(&self) -> usize {
        self.stack.len()
    }
}

/// Registers the classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCost>()?;
    m.add_class::<PyQuadraticCost>()?;
    m.add_class::<PyQuadraticStateCost>()?;
    m.add_class::<PyQuadraticControlCost>()?;
    m.add_class::<PyQuadraticResidualCost>()?;
    m.add_class::<PyCostStack>()?;
    Ok(())
}
