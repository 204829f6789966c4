//! Free forward dynamics `ẋ = (v, ABA(q, v, B u))` (as ALIGATOR's
//! `MultibodyFreeFwdDynamics` and Crocoddyl's `DifferentialActionModelFreeFwdDynamics`).

use std::sync::Arc;

use gharial::dynamics::{Ode, OdeData};
use gharial::functions::Workspace;
use gharial::linalg::slice_mut;
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::{Data, aba, compute_aba_derivatives_reusing_aba};

use super::{Actuation, PhaseOde, nan_jacobians, nan_xdot, workspace};
use crate::MultibodyPhaseSpace;

const NAME: &str = "MultibodyFreeFwdDynamics";

/// Free forward dynamics on the phase space: `ẋ = (v, a)`, `a = M(q)⁻¹ (B u − b(q, v))`
/// by the articulated-body algorithm, Jacobians from the analytical ABA derivatives
/// (`∂a/∂u = M⁻¹ B`).
///
/// ```
/// use std::sync::Arc;
/// use gharial::dynamics::Ode;
/// use gharial_multibody::{Model, RootJoint};
/// use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace};
/// let urdf = r#"<robot name="r"><link name="a"/><link name="b">
///   <inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
///   <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
///   <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#;
/// let model = Arc::new(Model::from_urdf_str(urdf, RootJoint::Fixed)?);
/// let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
/// let ode = MultibodyFreeFwdDynamics::new(space, Actuation::full(&model))?;
/// let mut data = ode.create_data();
/// ode.evaluate(&[0.0, 0.5], &[2.0], &mut data);
/// assert_eq!(data.xdot(), &[0.5, 2.0]); // unit inertia about the axis
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone)]
pub struct MultibodyFreeFwdDynamics {
    core: PhaseOde,
}

impl std::fmt::Debug for MultibodyFreeFwdDynamics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct(NAME)
            .field("model", &self.core.model().name)
            .field("nu", &self.core.actuation.nu())
            .finish_non_exhaustive()
    }
}

/// The workspace: multibody data, `τ = B u`, the last error.
pub(super) struct FreeWs {
    data: Data,
    tau: Vec<f64>,
    pub(super) error: Option<Error>,
}

impl MultibodyFreeFwdDynamics {
    /// Free dynamics of the model of `space` with actuation `B` (an [`Actuation`] or a
    /// shared `Arc<Actuation>`).
    ///
    /// # Errors
    /// If `B` does not have `nv` rows.
    pub fn new(space: Arc<MultibodyPhaseSpace>, actuation: impl Into<Arc<Actuation>>) -> Result<Self> {
        Ok(Self {
            core: PhaseOde::new(NAME, space, actuation.into())?,
        })
    }

    /// The phase space.
    pub fn phase_space(&self) -> &Arc<MultibodyPhaseSpace> {
        &self.core.space
    }

    /// The actuation matrix.
    pub fn actuation(&self) -> &Arc<Actuation> {
        &self.core.actuation
    }

    /// Checks `x` and `u` as `evaluate` does, with a `Result`.
    ///
    /// # Errors
    /// Wrong sizes, non-finite entries, or a configuration off its manifold (the error
    /// names the joint).
    pub fn check_inputs(&self, x: &[f64], u: &[f64]) -> Result<()> {
        self.core.check_inputs(x, u)
    }

    /// `a = ABA(q, v, B u)` into the workspace.
    fn acceleration<'w>(&self, x: &[f64], u: &[f64], ws: &'w mut FreeWs) -> Result<&'w [f64]> {
        self.core.check_inputs(x, u)?;
        self.core.actuation.torque(u, &mut ws.tau);
        let (q, v) = x.split_at(self.core.nq());
        aba(self.core.model(), &mut ws.data, q, v, &ws.tau).map_err(|e| crate::multibody_error(NAME, e))
    }

    /// The ABA derivatives at `(x, u)`, left in `ws.data`; the ABA of an `evaluate` at
    /// the same point is reused (the model, behind an `Arc`, cannot have changed).
    fn derivatives(&self, x: &[f64], u: &[f64], ws: &mut FreeWs) -> Result<()> {
        self.core.check_sizes(x, u)?;
        self.core.actuation.torque(u, &mut ws.tau);
        let (q, v) = x.split_at(self.core.nq());
        compute_aba_derivatives_reusing_aba(self.core.model(), &mut ws.data, q, v, &ws.tau)
            .map_err(|e| crate::multibody_error(NAME, e))
    }

    /// Gravity compensation `u = B⁺ g(q)`; see [`crate::gravity_compensation`].
    ///
    /// # Errors
    /// As [`crate::gravity_compensation`].
    pub fn gravity_compensation(&self, q: &[f64]) -> Result<Vec<f64>> {
        crate::inverse::gravity_compensation(self.core.model(), &self.core.actuation, q)
    }
}

impl Ode for MultibodyFreeFwdDynamics {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.core.manifold
    }

    fn nu(&self) -> usize {
        self.core.actuation.nu()
    }

    fn create_workspace(&self) -> Workspace {
        Box::new(FreeWs {
            data: self.core.model().create_data(),
            tau: vec![0.0; self.core.nv()],
            error: None,
        })
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let ws: &mut FreeWs = workspace(&mut data.ws);
        match self.acceleration(x, u, ws) {
            Ok(a) => {
                self.core.write_xdot(x, a, slice_mut(&mut data.xdot));
                ws.error = None;
            }
            Err(e) => {
                ws.error = Some(e);
                nan_xdot(data);
            }
        }
    }

    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.write_jacobians(x, u, data, true);
    }

    fn acceleration_jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.write_jacobians(x, u, data, false);
    }
}

impl MultibodyFreeFwdDynamics {
    /// [`Ode::jacobians`] (`full`) or [`Ode::acceleration_jacobians`].
    fn write_jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData, full: bool) {
        let ws: &mut FreeWs = workspace(&mut data.ws);
        match self.derivatives(x, u, ws) {
            Ok(()) => {
                let d = &ws.data;
                let j = (data.jx.as_mut(), data.ju.as_mut());
                self.core.write_jacobians(d.ddq_dq(), d.ddq_dv(), d.minv(), j, full);
                ws.error = None;
            }
            Err(e) => {
                ws.error = Some(e);
                nan_jacobians(data);
            }
        }
    }
}
