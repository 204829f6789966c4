//! Constrained forward dynamics with rigid contacts (as ALIGATOR's
//! `MultibodyConstraintFwdDynamics` and Crocoddyl's
//! `DifferentialActionModelContactFwdDynamics`).

use std::ops::Range;
use std::sync::{Arc, Mutex, MutexGuard};

use faer::Mat;
use gharial::dynamics::{Ode, OdeData};
use gharial::functions::{Workspace, lock, shared_data};
use gharial::linalg::{copy, slice_mut};
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::{
    ContactData, ContactModel, Data, ReferenceFrame, compute_constraint_dynamics_derivatives, constraint_dynamics,
};

use super::contacts::{ContactSpec, contacts_at_frames};
use super::{Actuation, PhaseOde, nan_jacobians, nan_xdot, workspace};
use crate::MultibodyPhaseSpace;
use crate::inverse::QuasiStatic;

const NAME: &str = "MultibodyConstraintFwdDynamics";

/// Forward dynamics with a set of rigid contacts (ProxDDP paper, (56)):
/// ```text
/// M(q) a + b(q, v) = B u + Jcᵀ λ
/// Jc a + γ(q, v)   = −Kp c(q) − Kd ċ      (Baumgarte, (55))
/// ```
/// solved exactly for `(a, λ)` through the KKT system; `ẋ = (v, a)`, Jacobians from the
/// analytical derivatives of the KKT solution. `λ` is the force (3D) or wrench (6D) the
/// environment applies to the robot, in each contact's reference frame, stacked in the
/// order of the contacts. One ODE per contact set (phase); building one is cheap (the
/// space and the actuation are shared).
#[derive(Clone)]
pub struct MultibodyConstraintFwdDynamics {
    core: PhaseOde,
    contacts: Vec<ContactModel>,
    /// First row of each contact in `λ`, and `nc` at the end.
    offsets: Vec<usize>,
}

impl std::fmt::Debug for MultibodyConstraintFwdDynamics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct(NAME)
            .field("model", &self.core.model().name)
            .field("nu", &self.core.actuation.nu())
            .field("contacts", &self.contacts)
            .finish_non_exhaustive()
    }
}

/// Preallocated memory of the constrained dynamics at one point `(x, u)`: the KKT
/// solution (`a`, `λ`), its derivatives and `∂λ/∂x`, `∂λ/∂u`. Created with
/// [`MultibodyConstraintFwdDynamics::create_contact_data`]; the ODE and the contact-force
/// residuals of one stage share one through
/// [`MultibodyConstraintFwdDynamics::shared_contact_data`].
///
/// The solution and the derivatives are kept for the last point: asking again at the
/// same `(x, u)` (bit for bit) does not solve again.
#[derive(Debug, Clone)]
pub struct ContactDynamicsData {
    data: Data,
    cdata: ContactData,
    tau: Vec<f64>,
    /// The point of the solution held in `cdata`.
    x: Vec<f64>,
    u: Vec<f64>,
    solved: bool,
    differentiated: bool,
    dlambda_dx: Mat<f64>,
    dlambda_du: Mat<f64>,
}

/// A [`ContactDynamicsData`] shared by the models of a stage (see
/// [`gharial::functions::shared_data`]).
pub type SharedContactData = Arc<Mutex<ContactDynamicsData>>;

/// The ODE's workspace: the (shared) contact solution and the error of its last call.
pub(super) struct ContactOdeWs {
    contact: SharedContactData,
    pub(super) error: Option<Error>,
}

impl ContactDynamicsData {
    /// The stacked contact forces `λ` (`nc`) of the last solve.
    pub fn lambda(&self) -> &[f64] {
        self.cdata.lambda()
    }

    /// The joint accelerations `a` (`nv`) of the last solve.
    pub fn acceleration(&self) -> &[f64] {
        self.cdata.ddq()
    }

    /// `∂λ/∂x` (`nc × 2 nv`, tangent coordinates) of the last
    /// [`MultibodyConstraintFwdDynamics::contact_force_jacobians`].
    pub fn dlambda_dx(&self) -> faer::MatRef<'_, f64> {
        self.dlambda_dx.as_ref()
    }

    /// `∂λ/∂u` (`nc × nu`) of the last
    /// [`MultibodyConstraintFwdDynamics::contact_force_jacobians`].
    pub fn dlambda_du(&self) -> faer::MatRef<'_, f64> {
        self.dlambda_du.as_ref()
    }

    /// The multibody contact data (constraint Jacobian, all derivatives).
    pub fn contact_data(&self) -> &ContactData {
        &self.cdata
    }
}

impl MultibodyConstraintFwdDynamics {
    /// Constrained dynamics of the model of `space` with actuation `B` and `contacts`.
    ///
    /// # Errors
    /// If `B` does not have `nv` rows, a contact is not attached to a moving joint of
    /// the model, is expressed in `World`, or has negative or non-finite gains.
    pub fn new(
        space: Arc<MultibodyPhaseSpace>,
        actuation: impl Into<Arc<Actuation>>,
        contacts: Vec<ContactModel>,
    ) -> Result<Self> {
        let core = PhaseOde::new(NAME, space, actuation.into())?;
        ContactData::new(core.model(), &contacts).map_err(|e| crate::multibody_error(NAME, e))?;
        for (k, c) in contacts.iter().enumerate() {
            check_contact(k, c)?;
        }
        let mut offsets = vec![0];
        offsets.extend(contacts.iter().scan(0, |n, c| {
            *n += c.size();
            Some(*n)
        }));
        Ok(Self {
            core,
            contacts,
            offsets,
        })
    }

    /// Constrained dynamics with one contact per named frame, as `spec` says (see
    /// [`contacts_at_frames`]).
    ///
    /// # Errors
    /// As [`contacts_at_frames`] and [`MultibodyConstraintFwdDynamics::new`].
    pub fn at_frames(
        space: Arc<MultibodyPhaseSpace>,
        actuation: impl Into<Arc<Actuation>>,
        frames: &[&str],
        spec: ContactSpec,
    ) -> Result<Self> {
        let contacts = contacts_at_frames(space.model(), frames, spec)?;
        Self::new(space, actuation, contacts)
    }

    /// The phase space.
    pub fn phase_space(&self) -> &Arc<MultibodyPhaseSpace> {
        &self.core.space
    }

    /// The actuation matrix.
    pub fn actuation(&self) -> &Arc<Actuation> {
        &self.core.actuation
    }

    /// The contacts.
    pub fn contacts(&self) -> &[ContactModel] {
        &self.contacts
    }

    /// Total number of contact rows `nc` (size of `λ`).
    pub fn nc(&self) -> usize {
        self.offsets[self.contacts.len()]
    }

    /// The rows of contact `k` in `λ`.
    ///
    /// # Panics
    /// If `k` is not below the number of contacts.
    pub fn contact_rows(&self, k: usize) -> Range<usize> {
        self.offsets[k]..self.offsets[k + 1]
    }

    /// Checks `x` and `u` as `evaluate` does, with a `Result`.
    ///
    /// # Errors
    /// Wrong sizes, non-finite entries, or a configuration off its manifold (the error
    /// names the joint).
    pub fn check_inputs(&self, x: &[f64], u: &[f64]) -> Result<()> {
        self.core.check_inputs(x, u)
    }

    /// Preallocated memory for [`Self::contact_forces`] and
    /// [`Self::contact_force_jacobians`].
    pub fn create_contact_data(&self) -> ContactDynamicsData {
        let model = self.core.model();
        let (nv, nc, nu) = (self.core.nv(), self.nc(), self.core.actuation.nu());
        ContactDynamicsData {
            data: model.create_data(),
            cdata: ContactData::new(model, &self.contacts).expect("contacts checked at construction"),
            tau: vec![0.0; nv],
            x: vec![0.0; self.core.nq() + nv],
            u: vec![0.0; nu],
            solved: false,
            differentiated: false,
            dlambda_dx: Mat::zeros(nc, 2 * nv),
            dlambda_du: Mat::zeros(nc, nu),
        }
    }

    /// The contact data of the stage being created: one object for this model's ODE and
    /// contact residuals within a stage's data
    /// ([`gharial::problem::StageData::new`]), a new one elsewhere.
    pub fn shared_contact_data(&self) -> SharedContactData {
        shared_data(self as *const Self as usize, || self.create_contact_data())
    }

    /// Solves the KKT system at `(x, u)` unless `d` holds its solution already.
    fn solve(&self, x: &[f64], u: &[f64], d: &mut ContactDynamicsData) -> Result<()> {
        if d.solved && d.x == x && d.u == u {
            return Ok(());
        }
        d.solved = false;
        d.differentiated = false;
        self.core.check_inputs(x, u)?;
        self.core.actuation.torque(u, &mut d.tau);
        let (q, v) = x.split_at(self.core.nq());
        let model = self.core.model();
        constraint_dynamics(model, &mut d.data, &self.contacts, &mut d.cdata, q, v, &d.tau)
            .map_err(|e| crate::multibody_error(NAME, e))?;
        d.x.copy_from_slice(x);
        d.u.copy_from_slice(u);
        d.solved = true;
        Ok(())
    }

    /// The solution and its derivatives at `(x, u)`.
    fn differentiate(&self, x: &[f64], u: &[f64], d: &mut ContactDynamicsData) -> Result<()> {
        self.solve(x, u, d)?;
        if !d.differentiated {
            compute_constraint_dynamics_derivatives(self.core.model(), &mut d.data, &self.contacts, &mut d.cdata)
                .map_err(|e| crate::multibody_error(NAME, e))?;
            d.differentiated = true;
        }
        Ok(())
    }

    /// The contact forces `λ(x, u)` (`nc`), in the order of [`Self::contacts`].
    ///
    /// # Errors
    /// As [`Self::check_inputs`], or if the KKT system is singular (rank-deficient
    /// contact Jacobian).
    pub fn contact_forces<'d>(&self, x: &[f64], u: &[f64], d: &'d mut ContactDynamicsData) -> Result<&'d [f64]> {
        self.solve(x, u, d)?;
        Ok(d.cdata.lambda())
    }

    /// `∂λ/∂x` (tangent coordinates) and `∂λ/∂u = ∂λ/∂τ B` at `(x, u)` into
    /// [`ContactDynamicsData::dlambda_dx`] and [`ContactDynamicsData::dlambda_du`] (and
    /// `λ` into [`ContactDynamicsData::lambda`]). Allocates nothing.
    ///
    /// # Errors
    /// As [`Self::contact_forces`].
    pub fn contact_force_jacobians(&self, x: &[f64], u: &[f64], d: &mut ContactDynamicsData) -> Result<()> {
        self.differentiate(x, u, d)?;
        let nv = self.core.nv();
        let (dq, dv) = d.dlambda_dx.as_mut().split_at_col_mut(nv);
        copy(dq, d.cdata.dlambda_dq());
        copy(dv, d.cdata.dlambda_dv());
        self.core
            .actuation
            .right_multiply(d.cdata.dlambda_dtau(), d.dlambda_du.as_mut());
        Ok(())
    }

    /// The contact data of an ODE data created by this type (`λ` of the last
    /// `evaluate`), or `None` for data of another model.
    pub fn contact_data(data: &OdeData) -> Option<MutexGuard<'_, ContactDynamicsData>> {
        data.ws.downcast_ref::<ContactOdeWs>().map(|w| lock(&w.contact))
    }

    /// The quasi-static controls and forces at `q` with these contacts; see
    /// [`crate::quasi_static_torque`].
    ///
    /// # Errors
    /// As [`crate::quasi_static_torque`].
    pub fn quasi_static_torque(&self, q: &[f64]) -> Result<QuasiStatic> {
        crate::inverse::quasi_static_torque(self.core.model(), &self.core.actuation, &self.contacts, q)
    }
}

/// Checks the frame convention and the gains of contact `k`.
fn check_contact(k: usize, c: &ContactModel) -> Result<()> {
    if c.reference_frame == ReferenceFrame::World {
        return Err(Error::InvalidModel(format!(
            "{NAME}: contact {k}: reference frame must be Local or LocalWorldAligned"
        )));
    }
    for (name, g) in [("kp", c.kp), ("kd", c.kd)] {
        if !(g.is_finite() && g >= 0.0) {
            return Err(Error::InvalidModel(format!(
                "{NAME}: contact {k}: Baumgarte gain {name} must be finite and non-negative, got {g}"
            )));
        }
    }
    Ok(())
}

impl Ode for MultibodyConstraintFwdDynamics {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.core.manifold
    }

    fn nu(&self) -> usize {
        self.core.actuation.nu()
    }

    fn create_workspace(&self) -> Workspace {
        Box::new(ContactOdeWs {
            contact: self.shared_contact_data(),
            error: None,
        })
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let w: &mut ContactOdeWs = workspace(&mut data.ws);
        let mut d = lock(&w.contact);
        match self.solve(x, u, &mut d) {
            Ok(()) => {
                self.core.write_xdot(x, d.cdata.ddq(), slice_mut(&mut data.xdot));
                w.error = None;
            }
            Err(e) => {
                drop(d);
                w.error = Some(e);
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

impl MultibodyConstraintFwdDynamics {
    /// [`Ode::jacobians`] (`full`) or [`Ode::acceleration_jacobians`].
    fn write_jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData, full: bool) {
        let w: &mut ContactOdeWs = workspace(&mut data.ws);
        let mut d = lock(&w.contact);
        match self.differentiate(x, u, &mut d) {
            Ok(()) => {
                let c = &d.cdata;
                let j = (data.jx.as_mut(), data.ju.as_mut());
                self.core.write_jacobians(c.ddq_dq(), c.ddq_dv(), c.ddq_dtau(), j, full);
                w.error = None;
            }
            Err(e) => {
                drop(d);
                w.error = Some(e);
                nan_jacobians(data);
            }
        }
    }
}
