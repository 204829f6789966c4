//! `gharial.manifolds`: state spaces.

use std::sync::Arc;

use faer::{Mat, MatMut};
use gharial::spaces::{Arg, CartesianProduct, Manifold, SE2, SE3, SO2, SO3, TangentBundle, VectorSpace};
use numpy::{PyArray1, PyArray2};
use pyo3::PyClassInitializer;
use pyo3::prelude::*;

use crate::convert::{array1, array2, value_error, vector};

/// A state manifold (base class of every space).
#[pyclass(subclass, frozen, name = "Manifold", module = "gharial.manifolds")]
pub struct PyManifold {
    /// The space.
    pub inner: Arc<dyn Manifold>,
}

impl PyManifold {
    /// Wraps a space.
    pub fn new(inner: Arc<dyn Manifold>) -> Self {
        Self { inner }
    }

    fn point(&self, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        vector(obj, what, Some(self.inner.nx()))
    }

    fn tangent(&self, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        vector(obj, what, Some(self.inner.ndx()))
    }

    /// A point that must be valid (the Jacobians are defined on the manifold only).
    fn valid_point(&self, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        let x = self.point(obj, what)?;
        if !self.inner.is_valid(&x) {
            return Err(value_error(format!(
                "{what} is not a valid point of the space (e.g. a quaternion that is not unit)"
            )));
        }
        Ok(x)
    }

    /// The Jacobian `ndx × ndx` written by `f` into a fresh matrix.
    fn jacobian<'py>(&self, py: Python<'py>, f: impl FnOnce(MatMut<'_, f64>)) -> Bound<'py, PyArray2<f64>> {
        let n = self.inner.ndx();
        let mut j = Mat::<f64>::zeros(n, n);
        f(j.as_mut());
        array2(py, j.as_ref())
    }
}

/// The argument of a Jacobian: 0 (`x`, `x0`) or 1 (`v`, `x1`), ALIGATOR's `ARG0`, `ARG1`.
fn arg(a: usize) -> PyResult<Arg> {
    match a {
        0 => Ok(Arg::First),
        1 => Ok(Arg::Second),
        _ => Err(value_error(format!("arg: expected 0 or 1, got {a}"))),
    }
}

#[pymethods]
impl PyManifold {
    /// Representation size.
    #[getter]
    fn nx(&self) -> usize {
        self.inner.nx()
    }

    /// Tangent size.
    #[getter]
    fn ndx(&self) -> usize {
        self.inner.ndx()
    }

    /// The neutral element.
    fn neutral<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let mut x = vec![0.0; self.inner.nx()];
        self.inner.neutral(&mut x);
        array1(py, &x)
    }

    /// `x ⊕ v`.
    fn integrate<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x, v) = (self.point(x, "x")?, self.tangent(v, "v")?);
        let mut out = vec![0.0; self.inner.nx()];
        self.inner.integrate(&x, &v, &mut out);
        Ok(array1(py, &out))
    }

    /// `x1 ⊖ x0`, the tangent vector at `x0` leading to `x1`.
    fn difference<'py>(
        &self,
        py: Python<'py>,
        x0: &Bound<'py, PyAny>,
        x1: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x0, x1) = (self.point(x0, "x0")?, self.point(x1, "x1")?);
        let mut out = vec![0.0; self.inner.ndx()];
        self.inner.difference(&x0, &x1, &mut out);
        Ok(array1(py, &out))
    }

    /// The Jacobian of `x ⊕ v` with respect to `x` (`arg = 0`) or `v` (`arg = 1`),
    /// `ndx × ndx` (ALIGATOR's `Jintegrate`).
    #[pyo3(name = "Jintegrate")]
    fn jintegrate<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
        arg: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (x, v, a) = (self.valid_point(x, "x")?, self.tangent(v, "v")?, self::arg(arg)?);
        Ok(self.jacobian(py, |j| self.inner.jintegrate(&x, &v, a, j)))
    }

    /// The Jacobian of `x1 ⊖ x0` with respect to `x0` (`arg = 0`) or `x1` (`arg = 1`),
    /// `ndx × ndx` (ALIGATOR's `Jdifference`).
    #[pyo3(name = "Jdifference")]
    fn jdifference<'py>(
        &self,
        py: Python<'py>,
        x0: &Bound<'py, PyAny>,
        x1: &Bound<'py, PyAny>,
        arg: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (x0, x1) = (self.valid_point(x0, "x0")?, self.valid_point(x1, "x1")?);
        let a = self::arg(arg)?;
        Ok(self.jacobian(py, |j| self.inner.jdifference(&x0, &x1, a, j)))
    }

    /// Whether `x` is a valid point (e.g. unit quaternions).
    fn is_valid(&self, x: &Bound<'_, PyAny>) -> PyResult<bool> {
        Ok(self.inner.is_valid(&self.point(x, "x")?))
    }

    /// The Cartesian product `self × other`.
    fn __mul__(&self, other: &Bound<'_, PyManifold>) -> PyManifold {
        PyManifold::new(Arc::new(CartesianProduct::new(vec![
            self.inner.clone(),
            other.get().inner.clone(),
        ])))
    }

    fn __repr__(&self) -> String {
        format!("{:?}", self.inner)
    }
}

/// R^n.
#[pyclass(extends = PyManifold, frozen, name = "VectorSpace", module = "gharial.manifolds")]
pub struct PyVectorSpace;

#[pymethods]
impl PyVectorSpace {
    #[new]
    fn new(dim: usize) -> PyClassInitializer<Self> {
        PyClassInitializer::from(PyManifold::new(Arc::new(VectorSpace::new(dim)))).add_subclass(Self)
    }
}

macro_rules! lie_group {
    ($rust:ident, $py:ident, $name:literal, $doc:literal) => {
        #[doc = $doc]
        #[pyclass(extends = PyManifold, frozen, name = $name, module = "gharial.manifolds")]
        pub struct $py;

        #[pymethods]
        impl $py {
            #[new]
            fn new() -> PyClassInitializer<Self> {
                PyClassInitializer::from(PyManifold::new(Arc::new($rust::new()))).add_subclass(Self)
            }
        }
    };
}

lie_group!(SO2, PySO2, "SO2", "Planar rotations, as (cos θ, sin θ).");
lie_group!(SO3, PySO3, "SO3", "Rotations in space, as quaternions (x, y, z, w).");
lie_group!(SE2, PySE2, "SE2", "Planar rigid motions, as (x, y, cos θ, sin θ).");
lie_group!(
    SE3,
    PySE3,
    "SE3",
    "Rigid motions, as (translation, quaternion x, y, z, w)."
);

/// The Cartesian product of spaces.
#[pyclass(extends = PyManifold, frozen, name = "CartesianProduct", module = "gharial.manifolds")]
pub struct PyCartesianProduct;

#[pymethods]
impl PyCartesianProduct {
    #[new]
    #[pyo3(signature = (*parts))]
    fn new(parts: Vec<Bound<'_, PyManifold>>) -> PyResult<PyClassInitializer<Self>> {
        if parts.is_empty() {
            return Err(value_error("CartesianProduct: needs at least one space"));
        }
        let parts = parts.iter().map(|p| p.get().inner.clone()).collect();
        Ok(PyClassInitializer::from(PyManifold::new(Arc::new(CartesianProduct::new(parts)))).add_subclass(Self))
    }
}

/// The tangent bundle `(x, v)` of a space (a phase space).
#[pyclass(extends = PyManifold, frozen, name = "TangentBundle", module = "gharial.manifolds")]
pub struct PyTangentBundle;

#[pymethods]
impl PyTangentBundle {
    #[new]
    fn new(base: &Bound<'_, PyManifold>) -> PyClassInitializer<Self> {
        PyClassInitializer::from(PyManifold::new(Arc::new(TangentBundle::new(base.get().inner.clone()))))
            .add_subclass(Self)
    }
}

/// Registers the classes of `gharial.manifolds`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyManifold>()?;
    m.add_class::<PyVectorSpace>()?;
    m.add_class::<PySO2>()?;
    m.add_class::<PySO3>()?;
    m.add_class::<PySE2>()?;
    m.add_class::<PySE3>()?;
    m.add_class::<PyCartesianProduct>()?;
    m.add_class::<PyTangentBundle>()?;
    Ok(())
}
