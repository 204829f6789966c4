//! `gharial.robots`' residuals of contact forces and frame velocities: what legged
//! problems (friction cones, force regularisation, swing-foot terms) are made of.

use std::sync::Arc;

use gharial_robotics::residuals::{
    ContactForceResidual, FlyHighResidual, FrameVelocityResidual, FrictionCone, FrictionConeResidual,
};
use pyo3::PyClassInitializer;
use pyo3::prelude::*;

use crate::convert::{err, vector};
use crate::functions::PyStageFunction;
use crate::robots::{PyConstraintFwdDynamics, PyMultibodyPhaseSpace, lifted, phase, reference_frame};

/// `r(x, u) = λ_k(x, u) − λ_ref`: the force of contact `contact` of the contact dynamics
/// (3 or 6 rows, in the contact's reference frame; ALIGATOR's `ContactForceResidual`).
#[pyclass(extends = PyStageFunction, name = "ContactForceResidual", module = "gharial.robots")]
pub struct PyContactForce;

#[pymethods]
impl PyContactForce {
    #[new]
    fn new(
        dynamics: &Bound<'_, PyConstraintFwdDynamics>,
        contact: usize,
        f_ref: &Bound<'_, PyAny>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let f_ref = vector(f_ref, "ContactForceResidual f_ref", None)?;
        let ode = dynamics.borrow().ode.clone();
        let f = ContactForceResidual::new(ode, contact, &f_ref).map_err(err)?;
        Ok(PyClassInitializer::from(PyStageFunction::rust(Arc::new(f), Vec::new())).add_subclass(Self))
    }
}

/// `r(x, u) = (μ f_n, f_t1, f_t2)` for the force `f` of contact `contact` about the unit
/// `normal` (default vertical), to be paired with `constraints.SecondOrderCone(3)`:
/// `‖f_t‖ ≤ μ f_n` (ALIGATOR's `MultibodyFrictionConeResidual`).
#[pyclass(extends = PyStageFunction, name = "FrictionConeResidual", module = "gharial.robots")]
pub struct PyFrictionCone;

#[pymethods]
impl PyFrictionCone {
    #[new]
    #[pyo3(signature = (dynamics, contact, mu, normal = [0.0, 0.0, 1.0]))]
    fn new(
        dynamics: &Bound<'_, PyConstraintFwdDynamics>,
        contact: usize,
        mu: f64,
        normal: [f64; 3],
    ) -> PyResult<PyClassInitializer<Self>> {
        let ode = dynamics.borrow().ode.clone();
        let cone = FrictionCone::new(mu, normal).map_err(err)?;
        let f = FrictionConeResidual::new(ode, contact, cone).map_err(err)?;
        Ok(PyClassInitializer::from(PyStageFunction::rust(Arc::new(f), Vec::new())).add_subclass(Self))
    }
}

/// `r(x) = v_f(q, v) − v_ref`: the spatial velocity of `frame` (6, `[linear, angular]`)
/// in `reference` coordinates (ALIGATOR's `FrameVelocityResidual`).
#[pyclass(extends = PyStageFunction, name = "FrameVelocityResidual", module = "gharial.robots")]
pub struct PyFrameVelocity;

#[pymethods]
impl PyFrameVelocity {
    #[new]
    #[pyo3(signature = (space, nu, frame, v_ref, reference = "local_world_aligned"))]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        nu: usize,
        frame: &str,
        v_ref: &Bound<'_, PyAny>,
        reference: &str,
    ) -> PyResult<PyClassInitializer<Self>> {
        let v_ref = vector(v_ref, "FrameVelocityResidual v_ref", Some(6))?;
        let rf = reference_frame(reference)?;
        let f = FrameVelocityResidual::new(&phase(space), frame, rf, &v_ref).map_err(err)?;
        Ok(PyClassInitializer::from(lifted(Arc::new(f), nu)).add_subclass(Self))
    }
}

/// `r(x) = v_xy(f) e^{−slope z(f)}`: the horizontal velocity of `frame` damped with its
/// height, the swing-foot penalty of legged gaits (ALIGATOR's `FlyHighResidual`).
#[pyclass(extends = PyStageFunction, name = "FlyHighResidual", module = "gharial.robots")]
pub struct PyFlyHigh;

#[pymethods]
impl PyFlyHigh {
    #[new]
    fn new(
        space: &Bound<'_, PyMultibodyPhaseSpace>,
        nu: usize,
        frame: &str,
        slope: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let f = FlyHighResidual::new(&phase(space), frame, slope).map_err(err)?;
        Ok(PyClassInitializer::from(lifted(Arc::new(f), nu)).add_subclass(Self))
    }
}

/// Registers the residuals in `gharial.robots`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyContactForce>()?;
    m.add_class::<PyFrictionCone>()?;
    m.add_class::<PyFrameVelocity>()?;
    m.add_class::<PyFlyHigh>()
}
