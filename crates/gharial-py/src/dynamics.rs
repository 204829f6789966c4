//! `gharial.dynamics`: ODEs (also written in Python), integrators and discrete dynamics.

use std::sync::Arc;

use faer::Mat;

use gharial::dynamics::{
    Dynamics, ExplicitDynamics, ExplicitRungeKutta, ImplicitEuler, ImplicitMidpoint, LinearDiscreteDynamics, LinearOde,
    Ode, RkMethod, SemiImplicitEuler,
};
use gharial::spaces::{Manifold, VectorSpace};
use pyo3::PyClassInitializer;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{array1, array2, err, matrix, value_error, vector};
use crate::functions::subclass_init;
use crate::pymodel::{PyOdeModel, Slots};
use crate::spaces::PyManifold;

/// Continuous-time dynamics `ẋ = f(x, u)` (ALIGATOR's `ODEAbstract`).
///
/// Subclass it in Python with `super().__init__(space, nu)`, `forward(x, u) -> xdot`
/// (a tangent vector, `ndx`) and `jacobians(x, u) -> (Jx, Ju)` (`ndx x ndx`, `ndx x nu`).
#[pyclass(subclass, name = "ODEAbstract", module = "gharial.dynamics")]
pub struct PyOde {
    inner: Option<Arc<dyn Ode>>,
    slots: Slots,
    py_dims: Option<(Arc<dyn Manifold>, usize)>,
    /// The configuration manifold `q` of a phase space `(q, v)`, for the semi-implicit
    /// Euler step (set by the multibody ODEs).
    configuration: Option<Arc<dyn Manifold>>,
}

impl PyOde {
    /// A Rust ODE; `configuration`: the `q` part of its phase space, when it has one.
    pub fn rust(inner: Arc<dyn Ode>, configuration: Option<Arc<dyn Manifold>>) -> Self {
        Self {
            inner: Some(inner),
            slots: Vec::new(),
            py_dims: None,
            configuration,
        }
    }
}

/// An ODE, the slots of its Python models and its configuration space if known.
pub type OdeParts = (Arc<dyn Ode>, Slots, Option<Arc<dyn Manifold>>);

/// The Rust ODE of an `ODEAbstract` object (a Python subclass is wrapped, after one
/// checked call of its methods), the slots of its Python models and its configuration
/// space if known.
pub fn ode_of(obj: &Bound<'_, PyAny>) -> PyResult<OdeParts> {
    let o = obj
        .cast::<PyOde>()
        .map_err(|_| PyTypeError::new_err("expected a gharial.dynamics.ODEAbstract"))?;
    let b = o.borrow();
    if let Some(inner) = &b.inner {
        return Ok((inner.clone(), b.slots.clone(), b.configuration.clone()));
    }
    let (space, nu) = b
        .py_dims
        .clone()
        .ok_or_else(|| PyTypeError::new_err("an ODEAbstract subclass must call super().__init__(space, nu)"))?;
    drop(b);
    let (model, slot) = PyOdeModel::new(obj, space, nu)?;
    Ok((model, vec![slot], None))
}

#[pymethods]
impl PyOde {
    #[new]
    #[pyo3(signature = (*_args, **_kwargs))]
    fn py_new(_args: &Bound<'_, PyTuple>, _kwargs: Option<&Bound<'_, PyDict>>) -> Self {
        Self {
            inner: None,
            slots: Vec::new(),
            py_dims: None,
            configuration: None,
        }
    }

    #[pyo3(signature = (*args, **kwargs))]
    fn __init__(&mut self, args: &Bound<'_, PyTuple>, kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        if self.inner.is_some() {
            return Ok(());
        }
        let (space, n) = subclass_init(args, kwargs, &["nu"], "ODEAbstract")?;
        self.py_dims = Some((space, n[0]));
        Ok(())
    }

    /// The state space.
    #[getter]
    fn space(&self) -> Option<PyManifold> {
        match (&self.inner, &self.py_dims) {
            (Some(o), _) => Some(PyManifold::new(o.space().clone())),
            (None, Some((s, _))) => Some(PyManifold::new(s.clone())),
            _ => None,
        }
    }

    /// Control size.
    #[getter]
    fn nu(&self) -> usize {
        match (&self.inner, &self.py_dims) {
            (Some(o), _) => o.nu(),
            (None, Some((_, nu))) => *nu,
            _ => 0,
        }
    }
}

/// `(A, B, c)` of a linear model (`c` zero when absent).
fn linear_parts(
    a: &Bound<'_, PyAny>,
    b: &Bound<'_, PyAny>,
    c: Option<&Bound<'_, PyAny>>,
    what: &str,
) -> PyResult<(Mat<f64>, Mat<f64>, Vec<f64>)> {
    let a = matrix(a, &format!("{what} A"), None)?;
    let b = matrix(b, &format!("{what} B"), None)?;
    let c = match c {
        Some(c) => vector(c, &format!("{what} c"), Some(a.nrows()))?,
        None => vec![0.0; a.nrows()],
    };
    Ok((a, b, c))
}

/// `ẋ = A x + B u + c` (ALIGATOR's `LinearODE`).
#[pyclass(extends = PyOde, name = "LinearODE", module = "gharial.dynamics")]
pub struct PyLinearOde;

#[pymethods]
impl PyLinearOde {
    #[new]
    #[pyo3(signature = (a, b, c = None))]
    fn new(
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        c: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (a, b, c) = linear_parts(a, b, c, "LinearODE")?;
        let ode = LinearOde::new(a.as_ref(), b.as_ref(), &c).map_err(err)?;
        Ok(PyClassInitializer::from(PyOde::rust(Arc::new(ode), None)).add_subclass(Self))
    }
}

/// Discrete dynamics of a stage (base class of integrators and discrete models).
#[pyclass(subclass, frozen, name = "DynamicsModel", module = "gharial.dynamics")]
pub struct PyDynamics {
    /// The dynamics.
    pub inner: Dynamics,
    /// Slots of the Python models inside.
    pub slots: Slots,
}

impl PyDynamics {
    fn explicit(&self) -> PyResult<&Arc<dyn ExplicitDynamics>> {
        match &self.inner {
            Dynamics::Explicit(d) => Ok(d),
            Dynamics::Implicit(_) => Err(value_error("implicit dynamics have no forward map")),
        }
    }
}

#[pymethods]
impl PyDynamics {
    /// Control size.
    #[getter]
    fn nu(&self) -> usize {
        self.inner.nu()
    }

    /// The state space.
    #[getter]
    fn space(&self) -> PyManifold {
        PyManifold::new(self.inner.space().clone())
    }

    /// The next state `φ(x, u)` of explicit dynamics.
    fn forward<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        let d = self.explicit()?;
        let x = vector(x, "x", Some(d.space().nx()))?;
        let u = vector(u, "u", Some(d.nu()))?;
        let mut data = d.create_data();
        d.forward(&x, &u, &mut data);
        Ok(array1(py, gharial::linalg::slice(&data.xnext)))
    }

    /// `(Jx, Ju)` of explicit dynamics at `(x, u)` (tangent convention).
    fn jacobians<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let d = self.explicit()?;
        let x = vector(x, "x", Some(d.space().nx()))?;
        let u = vector(u, "u", Some(d.nu()))?;
        let mut data = d.create_data();
        d.forward(&x, &u, &mut data);
        d.jacobians(&x, &u, &mut data);
        Ok((
            array2(py, data.jx.as_ref()).into_any(),
            array2(py, data.ju.as_ref()).into_any(),
        ))
    }
}

fn explicit(d: impl ExplicitDynamics + 'static, slots: Slots) -> PyDynamics {
    PyDynamics {
        inner: Dynamics::Explicit(Arc::new(d)),
        slots,
    }
}

/// `x⁺ = A x + B u + c`.
#[pyclass(extends = PyDynamics, frozen, name = "LinearDiscreteDynamics", module = "gharial.dynamics")]
pub struct PyLinearDiscrete;

#[pymethods]
impl PyLinearDiscrete {
    #[new]
    #[pyo3(signature = (a, b, c = None))]
    fn new(
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        c: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (a, b, c) = linear_parts(a, b, c, "LinearDiscreteDynamics")?;
        let d = LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &c).map_err(err)?;
        Ok(PyClassInitializer::from(explicit(d, Vec::new())).add_subclass(Self))
    }
}

macro_rules! runge_kutta {
    ($py:ident, $name:literal, $method:expr, $doc:literal) => {
        #[doc = $doc]
        #[pyclass(extends = PyDynamics, frozen, name = $name, module = "gharial.dynamics")]
        pub struct $py;

        #[pymethods]
        impl $py {
            #[new]
            fn new(ode: &Bound<'_, PyAny>, timestep: f64) -> PyResult<PyClassInitializer<Self>> {
                let (ode, slots, _) = ode_of(ode)?;
                let d = ExplicitRungeKutta::new(ode, timestep, $method).map_err(err)?;
                Ok(PyClassInitializer::from(explicit(d, slots)).add_subclass(Self))
            }
        }
    };
}

runge_kutta!(
    PyEuler,
    "IntegratorEuler",
    RkMethod::Euler,
    "Explicit Euler step `x ⊕ dt f(x, u)`."
);
runge_kutta!(
    PyRk2,
    "IntegratorRK2",
    RkMethod::Rk2,
    "Explicit midpoint (second-order Runge-Kutta) step."
);
runge_kutta!(
    PyRk4,
    "IntegratorRK4",
    RkMethod::Rk4,
    "Classical fourth-order Runge-Kutta step."
);

/// Semi-implicit Euler `v⁺ = v + dt a(x, u)`, `q⁺ = q ⊕ dt v⁺` on a phase space `(q, v)`:
/// the configuration space is the multibody one for robot ODEs, `R^{n/2}` for an ODE on
/// `R^n`, or given as `configuration`.
#[pyclass(extends = PyDynamics, frozen, name = "IntegratorSemiImplEuler", module = "gharial.dynamics")]
pub struct PySemiImplicitEuler;

#[pymethods]
impl PySemiImplicitEuler {
    #[new]
    #[pyo3(signature = (ode, timestep, configuration = None))]
    fn new(
        ode: &Bound<'_, PyAny>,
        timestep: f64,
        configuration: Option<&Bound<'_, PyManifold>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (ode, slots, known) = ode_of(ode)?;
        let space = ode.space().clone();
        let config: Arc<dyn Manifold> = match (configuration, known) {
            (Some(c), _) => c.get().inner.clone(),
            (None, Some(c)) => c,
            (None, None) if space.is_vector_space() && space.ndx() % 2 == 0 => {
                Arc::new(VectorSpace::new(space.ndx() / 2))
            }
            (None, None) => {
                return Err(value_error(
                    "IntegratorSemiImplEuler: pass `configuration`, the q part of the ODE's phase space",
                ));
            }
        };
        let d = SemiImplicitEuler::new(ode, config, timestep).map_err(err)?;
        Ok(PyClassInitializer::from(explicit(d, slots)).add_subclass(Self))
    }
}

macro_rules! implicit {
    ($py:ident, $rust:ident, $name:literal, $doc:literal) => {
        #[doc = $doc]
        #[pyclass(extends = PyDynamics, frozen, name = $name, module = "gharial.dynamics")]
        pub struct $py;

        #[pymethods]
        impl $py {
            #[new]
            fn new(ode: &Bound<'_, PyAny>, timestep: f64) -> PyResult<PyClassInitializer<Self>> {
                let (ode, slots, _) = ode_of(ode)?;
                let d = $rust::new(ode, timestep).map_err(err)?;
                let base = PyDynamics {
                    inner: Dynamics::Implicit(Arc::new(d)),
                    slots,
                };
                Ok(PyClassInitializer::from(base).add_subclass(Self))
            }
        }
    };
}

implicit!(
    PyImplicitEuler,
    ImplicitEuler,
    "IntegratorImplicitEuler",
    "Implicit Euler `x⁺ ⊖ x - dt f(x⁺, u) = 0` (solved by the solvers' Newton step)."
);
implicit!(
    PyImplicitMidpoint,
    ImplicitMidpoint,
    "IntegratorMidpoint",
    "Implicit midpoint rule (symplectic, second order)."
);

/// Registers the classes of `gharial.dynamics`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyOde>()?;
    m.add_class::<PyLinearOde>()?;
    m.add_class::<PyDynamics>()?;
    m.add_class::<PyLinearDiscrete>()?;
    m.add_class::<PyEuler>()?;
    m.add_class::<PyRk2>()?;
    m.add_class::<PyRk4>()?;
    m.add_class::<PySemiImplicitEuler>()?;
    m.add_class::<PyImplicitEuler>()?;
    m.add_class::<PyImplicitMidpoint>()?;
    Ok(())
}
