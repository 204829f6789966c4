//! `gharial.constraints`: constraint sets `C` of constraints `h(x, u) ∈ C`.

use std::sync::Arc;

use gharial::constraints::{BoxConstraint, ConstraintSet, EqualityConstraintSet, NegativeOrthant, SecondOrderCone};
use pyo3::PyClassInitializer;
use pyo3::prelude::*;

use crate::convert::{err, vector};

/// A closed convex set (base class of every constraint set).
#[pyclass(subclass, frozen, name = "ConstraintSet", module = "gharial.constraints")]
pub struct PyConstraintSet {
    /// The set.
    pub inner: Arc<dyn ConstraintSet>,
}

#[pymethods]
impl PyConstraintSet {
    fn __repr__(&self) -> String {
        format!("{:?}", self.inner)
    }
}

fn base(set: impl ConstraintSet + 'static) -> PyConstraintSet {
    PyConstraintSet { inner: Arc::new(set) }
}

/// `h = 0`.
#[pyclass(extends = PyConstraintSet, frozen, name = "EqualityConstraintSet", module = "gharial.constraints")]
pub struct PyEquality;

#[pymethods]
impl PyEquality {
    #[new]
    fn new() -> PyClassInitializer<Self> {
        PyClassInitializer::from(base(EqualityConstraintSet)).add_subclass(Self)
    }
}

/// `h ≤ 0`.
#[pyclass(extends = PyConstraintSet, frozen, name = "NegativeOrthantSet", module = "gharial.constraints")]
pub struct PyNegativeOrthant;

#[pymethods]
impl PyNegativeOrthant {
    #[new]
    fn new() -> PyClassInitializer<Self> {
        PyClassInitializer::from(base(NegativeOrthant)).add_subclass(Self)
    }
}

/// `lower ≤ h ≤ upper`.
#[pyclass(extends = PyConstraintSet, frozen, name = "BoxConstraint", module = "gharial.constraints")]
pub struct PyBox;

#[pymethods]
impl PyBox {
    #[new]
    fn new(lower: &Bound<'_, PyAny>, upper: &Bound<'_, PyAny>) -> PyResult<PyClassInitializer<Self>> {
        let lower = vector(lower, "BoxConstraint lower", None)?;
        let upper = vector(upper, "BoxConstraint upper", Some(lower.len()))?;
        let set = BoxConstraint::new(&lower, &upper).map_err(err)?;
        Ok(PyClassInitializer::from(base(set)).add_subclass(Self))
    }
}

/// The second-order cone `‖h[1:]‖ ≤ h[0]` of dimension `n` (scalar part first).
#[pyclass(extends = PyConstraintSet, frozen, name = "SecondOrderCone", module = "gharial.constraints")]
pub struct PySecondOrderCone;

#[pymethods]
impl PySecondOrderCone {
    #[new]
    fn new(n: usize) -> PyResult<PyClassInitializer<Self>> {
        let set = SecondOrderCone::new(n).map_err(err)?;
        Ok(PyClassInitializer::from(base(set)).add_subclass(Self))
    }
}

/// Registers the classes of `gharial.constraints`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyConstraintSet>()?;
    m.add_class::<PyEquality>()?;
    m.add_class::<PyNegativeOrthant>()?;
    m.add_class::<PyBox>()?;
    m.add_class::<PySecondOrderCone>()?;
    Ok(())
}
