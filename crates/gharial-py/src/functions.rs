//! Stage functions `r(x, u)` and residuals; `StageFunction` subclassed in Python.

use std::sync::Arc;

use gharial::functions::{ControlError, LinearComposition, LinearFunction, Slice, StageFunction, StateError};
use numpy::PyArray1;
use pyo3::PyClassInitializer;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{array1, err, matrix, vector};
use crate::pymodel::{PyFunctionModel, Slots};
use crate::spaces::PyManifold;

/// The arguments `(space, sizes...)` of a Python subclass's `super().__init__(...)`,
/// by position or name: the space and the sizes named in `sizes`.
pub fn subclass_init(
    args: &Bound<'_, PyTuple>,
    kwargs: Option<&Bound<'_, PyDict>>,
    sizes: &[&str],
    class: &str,
) -> PyResult<(Arc<dyn gharial::spaces::Manifold>, Vec<usize>)> {
    let arg = |i: usize, name: &str| {
        args.get_item(i)
            .ok()
            .or_else(|| kwargs.and_then(|k| k.get_item(name).ok().flatten()))
            .ok_or_else(|| PyTypeError::new_err(format!("{class}.__init__: missing argument `{name}`")))
    };
    let space = arg(0, "space")?.cast::<PyManifold>()?.get().inner.clone();
    let sizes = sizes
        .iter()
        .enumerate()
        .map(|(i, name)| arg(i + 1, name)?.extract())
        .collect::<PyResult<_>>()?;
    Ok((space, sizes))
}

/// A function `r(x, u)` of a state and a control (base class of residuals).
///
/// Subclass it in Python with `super().__init__(space, nu, nr)`, `evaluate(x, u) -> r`
/// and `jacobians(x, u) -> (Jx, Ju)` (`nr x ndx`, `nr x nu`).
#[pyclass(subclass, name = "StageFunction", module = "gharial")]
pub struct PyStageFunction {
    inner: Option<Arc<dyn StageFunction>>,
    slots: Slots,
    py_dims: Option<(Arc<dyn gharial::spaces::Manifold>, usize, usize)>,
}

impl PyStageFunction {
    /// A Rust function.
    pub fn rust(inner: Arc<dyn StageFunction>, slots: Slots) -> Self {
        Self {
            inner: Some(inner),
            slots,
            py_dims: None,
        }
    }

    fn dims(&self) -> (usize, usize, usize, usize) {
        match (&self.inner, &self.py_dims) {
            (Some(f), _) => (f.nx(), f.ndx(), f.nu(), f.nr()),
            (None, Some((s, nu, nr))) => (s.nx(), s.ndx(), *nu, *nr),
            _ => (0, 0, 0, 0),
        }
    }
}

/// The Rust function of a `StageFunction` object (a Python subclass is wrapped, after
/// one checked call of its methods) and the slots of the Python models inside it.
pub fn function_of(obj: &Bound<'_, PyAny>) -> PyResult<(Arc<dyn StageFunction>, Slots)> {
    let f = obj
        .cast::<PyStageFunction>()
        .map_err(|_| PyTypeError::new_err("expected a gharial.StageFunction"))?;
    let b = f.borrow();
    if let Some(inner) = &b.inner {
        return Ok((inner.clone(), b.slots.clone()));
    }
    let (space, nu, nr) = b
        .py_dims
        .clone()
        .ok_or_else(|| PyTypeError::new_err("a StageFunction subclass must call super().__init__(space, nu, nr)"))?;
    drop(b);
    let (model, slot) = PyFunctionModel::new(obj, space.as_ref(), nu, nr)?;
    Ok((model, vec![slot]))
}

#[pymethods]
impl PyStageFunction {
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
        let (space, n) = subclass_init(args, kwargs, &["nu", "nr"], "StageFunction")?;
        self.py_dims = Some((space, n[0], n[1]));
        Ok(())
    }

    /// Representation size of the state.
    #[getter]
    fn nx(&self) -> usize {
        self.dims().0
    }
    /// Tangent size of the state.
    #[getter]
    fn ndx(&self) -> usize {
        self.dims().1
    }
    /// Control size.
    #[getter]
    fn nu(&self) -> usize {
        self.dims().2
    }
    /// Output size.
    #[getter]
    fn nr(&self) -> usize {
        self.dims().3
    }

    /// The rows `rows` of this function (`FunctionSlice`).
    fn __getitem__(slf: &Bound<'_, Self>, rows: &Bound<'_, PyAny>) -> PyResult<PyStageFunction> {
        let rows: Vec<usize> = match rows.extract::<usize>() {
            Ok(i) => vec![i],
            Err(_) => rows.extract()?,
        };
        let (f, slots) = function_of(slf.as_any())?;
        Ok(PyStageFunction::rust(
            Arc::new(Slice::new(f, &rows).map_err(err)?),
            slots,
        ))
    }

    /// `r(x, u)` (Rust functions; a Python subclass has its own `evaluate`).
    fn __call__<'py>(
        slf: &Bound<'py, Self>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (f, _) = function_of(slf.as_any())?;
        let x = vector(x, "x", Some(f.nx()))?;
        let u = vector(u, "u", Some(f.nu()))?;
        let mut data = f.create_data();
        f.evaluate(&x, &u, &mut data);
        Ok(array1(slf.py(), gharial::linalg::slice(&data.value)))
    }

    /// `(Jx, Ju)` at `(x, u)`.
    fn jacobians<'py>(
        slf: &Bound<'py, Self>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let (f, _) = function_of(slf.as_any())?;
        let x = vector(x, "x", Some(f.nx()))?;
        let u = vector(u, "u", Some(f.nu()))?;
        let mut data = f.create_data();
        f.evaluate(&x, &u, &mut data);
        f.jacobians(&x, &u, &mut data);
        let py = slf.py();
        Ok((
            crate::convert::array2(py, data.jx.as_ref()).into_any(),
            crate::convert::array2(py, data.ju.as_ref()).into_any(),
        ))
    }
}

/// `r(x, u) = x ⊖ x_ref` (ALIGATOR's `StateErrorResidual(space, nu, target)`).
#[pyclass(extends = PyStageFunction, name = "StateErrorResidual", module = "gharial")]
pub struct PyStateError {
    f: Arc<StateError>,
}

#[pymethods]
impl PyStateError {
    #[new]
    fn new(space: &Bound<'_, PyManifold>, nu: usize, target: &Bound<'_, PyAny>) -> PyResult<PyClassInitializer<Self>> {
        let space = space.get().inner.clone();
        let target = vector(target, "StateErrorResidual target", Some(space.nx()))?;
        let f = Arc::new(StateError::new(space, &target).map_err(err)?);
        let lifted = Arc::new(gharial::functions::Unary::new(f.clone(), nu));
        Ok(PyClassInitializer::from(PyStageFunction::rust(lifted, Vec::new())).add_subclass(Self { f }))
    }

    /// The reference state (settable between solves).
    #[getter]
    fn get_target<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.f.target())
    }
    #[setter]
    fn set_target(&self, target: &Bound<'_, PyAny>) -> PyResult<()> {
        let t = vector(target, "target", Some(self.f.space().nx()))?;
        self.f.set_target(&t).map_err(err)
    }
}

/// `r(x, u) = u - u_ref` (ALIGATOR's `ControlErrorResidual`).
#[pyclass(extends = PyStageFunction, name = "ControlErrorResidual", module = "gharial")]
pub struct PyControlError {
    f: Arc<ControlError>,
}

#[pymethods]
impl PyControlError {
    #[new]
    fn new(space: &Bound<'_, PyManifold>, target: &Bound<'_, PyAny>) -> PyResult<PyClassInitializer<Self>> {
        let target = vector(target, "ControlErrorResidual target", None)?;
        let f = Arc::new(ControlError::new(space.get().inner.as_ref(), &target).map_err(err)?);
        Ok(PyClassInitializer::from(PyStageFunction::rust(f.clone(), Vec::new())).add_subclass(Self { f }))
    }

    /// The reference control (settable between solves).
    #[getter]
    fn get_target<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.f.target())
    }
    #[setter]
    fn set_target(&self, target: &Bound<'_, PyAny>) -> PyResult<()> {
        let t = vector(target, "target", Some(self.f.target().len()))?;
        self.f.set_target(&t).map_err(err)
    }
}

/// `r(x, u) = A x + B u + c` on vector states.
#[pyclass(extends = PyStageFunction, name = "LinearFunction", module = "gharial")]
pub struct PyLinearFunction;

#[pymethods]
impl PyLinearFunction {
    #[new]
    fn new(a: &Bound<'_, PyAny>, b: &Bound<'_, PyAny>, c: &Bound<'_, PyAny>) -> PyResult<PyClassInitializer<Self>> {
        let a = matrix(a, "LinearFunction A", None)?;
        let b = matrix(b, "LinearFunction B", None)?;
        let c = vector(c, "LinearFunction c", Some(a.nrows()))?;
        let f = LinearFunction::new(a.as_ref(), b.as_ref(), &c).map_err(err)?;
        Ok(PyClassInitializer::from(PyStageFunction::rust(Arc::new(f), Vec::new())).add_subclass(Self))
    }
}

/// Rows of another function (ALIGATOR's `FunctionSliceXpr`; also `f[rows]`).
#[pyclass(extends = PyStageFunction, name = "FunctionSlice", module = "gharial")]
pub struct PyFunctionSlice;

#[pymethods]
impl PyFunctionSlice {
    #[new]
    fn new(f: &Bound<'_, PyAny>, rows: Vec<usize>) -> PyResult<PyClassInitializer<Self>> {
        let (f, slots) = function_of(f)?;
        Ok(PyClassInitializer::from(PyStageFunction::rust(
            Arc::new(Slice::new(f, &rows).map_err(err)?),
            slots,
        ))
        .add_subclass(Self))
    }
}

/// `r(x, u) = A f(x, u) + b` (ALIGATOR's `LinearFunctionComposition`).
#[pyclass(extends = PyStageFunction, name = "LinearFunctionComposition", module = "gharial")]
pub struct PyLinearComposition;

#[pymethods]
impl PyLinearComposition {
    #[new]
    #[pyo3(signature = (f, a, b = None))]
    fn new(
        f: &Bound<'_, PyAny>,
        a: &Bound<'_, PyAny>,
        b: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (f, slots) = function_of(f)?;
        let a = matrix(a, "LinearFunctionComposition A", None)?;
        let b = match b {
            Some(b) => vector(b, "LinearFunctionComposition b", Some(a.nrows()))?,
            None => vec![0.0; a.nrows()],
        };
        let g = LinearComposition::new(f, a.as_ref(), &b).map_err(err)?;
        Ok(PyClassInitializer::from(PyStageFunction::rust(Arc::new(g), slots)).add_subclass(Self))
    }
}

/// Registers the classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyStageFunction>()?;
    m.add_class::<PyStateError>()?;
    m.add_class::<PyControlError>()?;
    m.add_class::<PyLinearFunction>()?;
    m.add_class::<PyFunctionSlice>()?;
    m.add_class::<PyLinearComposition>()?;
    Ok(())
}
