//! Forward dynamics with a free body welded to its parent frame by a 6D bilateral
//! constraint: an object held by a gripper, whose free-flyer joint is a child of the
//! gripper's body (ProxDDP paper, §VII-B, (54) and (55)).

use std::sync::Arc;

use faer::Mat;
use gharial::dynamics::{Ode, OdeData};
use gharial::functions::Workspace;
use gharial::linalg::slice_mut;
use gharial::spaces::Manifold;
use gharial::{Error, Result};
use gharial_multibody::spatial::{Motion, Se3, Vec3};
use gharial_multibody::{Data, JointType, aba, compute_aba_derivatives, compute_minverse, jlog6_blocks, log6};
use nalgebra::{Matrix6, UnitQuaternion, Vector6};

use super::{Actuation, PhaseOde, nan_jacobians, nan_xdot, workspace};
use crate::MultibodyPhaseSpace;
use crate::inverse::QuasiStatic;

const NAME: &str = "MultibodyWeldFwdDynamics";

/// Forward dynamics of a model whose free-flyer joint `j` (placement `M_j(q)` of the
/// body in its parent frame, body twist `v_j`) is held by a 6D constraint with
/// Baumgarte stabilisation:
/// ```text
/// M(q) a + b(q, v) = B u + S λ          S = the 6 columns of the dofs of j
/// Sᵀ a = −Kp c(q) − Kd ċ               c(q) = log6(M_j(q)), ċ = v_j      (55)
/// ```
/// The constraint is `c(q) = 0`: the body's frame coincides with the joint's placement
/// in its parent frame (e.g. a grasp frame on the end effector). Its Jacobian `Sᵀ` is
/// constant and `γ = 0`, so the KKT system reduces to the 6 × 6 Delassus matrix
/// `Λ = Sᵀ M⁻¹ S`: `λ = Λ⁻¹ (r − Sᵀ a_free)`, `a = a_free + M⁻¹ S λ`, with
/// `a_free = ABA(q, v, B u)` and `r = −Kp c − Kd ċ`. `λ` is the wrench the parent applies
/// to the body, in the body's frame (`[force, torque]`).
///
/// Derivatives: `a = ABA(q, v, τ + S λ)` and `Sᵀ a = r(q, v)` give
/// `Λ ∂λ/∂x = ∂r/∂x − Sᵀ ∂ABA/∂x` (at `τ + S λ`), `Λ ∂λ/∂τ = −Sᵀ M⁻¹`, and
/// `∂a = ∂ABA + M⁻¹ S ∂λ`.
///
/// Removing the constraint (the free dynamics of the same model) releases the body.
#[derive(Clone)]
pub struct MultibodyWeldFwdDynamics {
    core: PhaseOde,
    joint: usize,
    idx_q: usize,
    idx_v: usize,
    kp: f64,
    kd: f64,
}

impl std::fmt::Debug for MultibodyWeldFwdDynamics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct(NAME)
            .field("model", &self.core.model().name)
            .field("joint", &self.core.model().joint_names()[self.joint])
            .field("kp", &self.kp)
            .field("kd", &self.kd)
            .finish_non_exhaustive()
    }
}

/// Preallocated memory of the welded dynamics at one point `(x, u)`: the solution
/// `(a, λ)` and its derivatives, kept for the last point (asking again at the same
/// `(x, u)`, bit for bit, does not solve again).
#[derive(Debug, Clone)]
pub struct WeldData {
    data: Data,
    tau: Vec<f64>,
    /// `M⁻¹ S` (nv × 6).
    minv_s: Mat<f64>,
    a: Vec<f64>,
    lambda: [f64; 6],
    x: Vec<f64>,
    u: Vec<f64>,
    solved: bool,
    differentiated: bool,
    da_dq: Mat<f64>,
    da_dv: Mat<f64>,
    da_dtau: Mat<f64>,
    dlambda_dq: Mat<f64>,
    dlambda_dv: Mat<f64>,
    dlambda_dtau: Mat<f64>,
    error: Option<Error>,
}

impl WeldData {
    /// The constraint wrench `λ` (parent on body, body frame) of the last solve.
    pub fn lambda(&self) -> &[f64; 6] {
        &self.lambda
    }

    /// The joint accelerations `a` (`nv`) of the last solve.
    pub fn acceleration(&self) -> &[f64] {
        &self.a
    }

    /// `∂λ/∂q` (`6 × nv`, tangent) of the last Jacobian evaluation.
    pub fn dlambda_dq(&self) -> faer::MatRef<'_, f64> {
        self.dlambda_dq.as_ref()
    }

    /// `∂λ/∂v` (`6 × nv`) of the last Jacobian evaluation.
    pub fn dlambda_dv(&self) -> faer::MatRef<'_, f64> {
        self.dlambda_dv.as_ref()
    }

    /// `∂λ/∂τ` (`6 × nv`) of the last Jacobian evaluation.
    pub fn dlambda_dtau(&self) -> faer::MatRef<'_, f64> {
        self.dlambda_dtau.as_ref()
    }

    /// The error of the last failed `evaluate` or `jacobians` on this data.
    pub fn last_error(&self) -> Option<&Error> {
        self.error.as_ref()
    }
}

impl MultibodyWeldFwdDynamics {
    /// The dynamics of the model of `space` with actuation `B`, the free-flyer joint
    /// named `joint` held by the constraint with Baumgarte gains `kp`, `kd`.
    ///
    /// # Errors
    /// If `B` does not have `nv` rows, `joint` is not a free-flyer joint of the model, or
    /// a gain is negative or not finite.
    pub fn new(
        space: Arc<MultibodyPhaseSpace>,
        actuation: impl Into<Arc<Actuation>>,
        joint: &str,
        kp: f64,
        kd: f64,
    ) -> Result<Self> {
        let core = PhaseOde::new(NAME, space, actuation.into())?;
        let model = core.model();
        let id = model
            .joint_id(joint)
            .map_err(|e| Error::InvalidModel(format!("{NAME}: {e} in model `{}`", model.name)))?;
        let jm = model.joints()[id];
        if jm.kind != JointType::FreeFlyer {
            return Err(Error::InvalidModel(format!(
                "{NAME}: joint `{joint}` of model `{}` is a {:?} joint, not a free flyer",
                model.name, jm.kind
            )));
        }
        for (name, g) in [("kp", kp), ("kd", kd)] {
            if !(g.is_finite() && g >= 0.0) {
                return Err(Error::option(
                    format!("{NAME}::{name}"),
                    format!("Baumgarte gain must be finite and non-negative, got {g}"),
                ));
            }
        }
        Ok(Self {
            joint: id,
            idx_q: jm.idx_q,
            idx_v: jm.idx_v,
            kp,
            kd,
            core,
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

    /// Id of the welded joint in the model.
    pub fn joint(&self) -> usize {
        self.joint
    }

    /// The Baumgarte gains `(Kp, Kd)`.
    pub fn gains(&self) -> (f64, f64) {
        (self.kp, self.kd)
    }

    /// Checks `x` and `u` as `evaluate` does, with a `Result`.
    ///
    /// # Errors
    /// Wrong sizes, non-finite entries, or a configuration off its manifold.
    pub fn check_inputs(&self, x: &[f64], u: &[f64]) -> Result<()> {
        self.core.check_inputs(x, u)
    }

    /// The constraint value `(c(q), ċ) = (log6(M_j(q)), v_j)` at `x` (`[linear, angular]`
    /// each): zero when the body is held at its grasp frame at rest relative to it.
    ///
    /// # Errors
    /// As [`Self::check_inputs`] (with a zero control).
    pub fn constraint_error(&self, x: &[f64]) -> Result<([f64; 6], [f64; 6])> {
        self.core.check_inputs(x, &vec![0.0; self.core.actuation.nu()])?;
        let c = log6(&self.joint_placement(x));
        let v = &x[self.core.nq() + self.idx_v..self.core.nq() + self.idx_v + 6];
        Ok((c.to_array(), v.try_into().expect("6 velocity entries")))
    }

    /// Preallocated memory for [`Self::constraint_wrench`].
    pub fn create_weld_data(&self) -> WeldData {
        let model = self.core.model();
        let (nv, nu) = (self.core.nv(), self.core.actuation.nu());
        WeldData {
            data: model.create_data(),
            tau: vec![0.0; nv],
            minv_s: Mat::zeros(nv, 6),
            a: vec![0.0; nv],
            lambda: [0.0; 6],
            x: vec![0.0; self.core.nq() + nv],
            u: vec![0.0; nu],
            solved: false,
            differentiated: false,
            da_dq: Mat::zeros(nv, nv),
            da_dv: Mat::zeros(nv, nv),
            da_dtau: Mat::zeros(nv, nv),
            dlambda_dq: Mat::zeros(6, nv),
            dlambda_dv: Mat::zeros(6, nv),
            dlambda_dtau: Mat::zeros(6, nv),
            error: None,
        }
    }

    /// The constraint wrench `λ(x, u)` (parent on body, body frame).
    ///
    /// # Errors
    /// As [`Self::check_inputs`], or if the mass matrix is singular.
    pub fn constraint_wrench(&self, x: &[f64], u: &[f64], d: &mut WeldData) -> Result<[f64; 6]> {
        self.solve(x, u, d)?;
        Ok(d.lambda)
    }

    /// The quasi-static controls and constraint wrench at `q`: the minimum-norm
    /// `(u, λ)` with `B u + S λ = g(q)` (ProxDDP paper, §VII-B: gravity compensation with
    /// the attached body, whose weight the arm carries through `λ`).
    ///
    /// # Errors
    /// As [`crate::quasi_static_torque`].
    pub fn quasi_static_torque(&self, q: &[f64]) -> Result<QuasiStatic> {
        let model = self.core.model();
        let jc = Mat::from_fn(6, model.nv(), |r, k| f64::from(k == self.idx_v + r));
        crate::inverse::static_balance_with_jacobian(NAME, model, &self.core.actuation, &jc, q)
    }

    /// `M_j(q)` from the free-flyer entries of `q` (`[x, y, z, qx, qy, qz, qw]`).
    fn joint_placement(&self, x: &[f64]) -> Se3 {
        let qj = &x[self.idx_q..self.idx_q + 7];
        let quat = UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(qj[6], qj[3], qj[4], qj[5]));
        Se3::new(quat.to_rotation_matrix().into_inner(), Vec3::new(qj[0], qj[1], qj[2]))
    }

    /// `r = −Kp c(q) − Kd ċ` and `c(q)` (for the derivatives).
    fn baumgarte(&self, x: &[f64]) -> (Vector6<f64>, Motion) {
        let c = log6(&self.joint_placement(x));
        let v0 = self.core.nq() + self.idx_v;
        let r = Vector6::from_fn(|i, _| -self.kp * c.get(i) - self.kd * x[v0 + i]);
        (r, c)
    }

    /// The Delassus matrix `Λ = Sᵀ M⁻¹ S` from `M⁻¹ S`, factored.
    fn delassus(&self, minv_s: &Mat<f64>) -> Result<nalgebra::Cholesky<f64, nalgebra::U6>> {
        let l = Matrix6::from_fn(|i, j| minv_s[(self.idx_v + i, j)]);
        l.cholesky()
            .ok_or_else(|| Error::singular(format!("{NAME}: Delassus matrix Sᵀ M⁻¹ S is not positive definite")))
    }

    /// Solves for `(a, λ)` at `(x, u)` unless `d` holds its solution already.
    fn solve(&self, x: &[f64], u: &[f64], d: &mut WeldData) -> Result<()> {
        if d.solved && d.x == x && d.u == u {
            return Ok(());
        }
        d.solved = false;
        d.differentiated = false;
        self.core.check_inputs(x, u)?;
        let (nq, nv) = (self.core.nq(), self.core.nv());
        let model = self.core.model();
        let mb = |e| crate::multibody_error(NAME, e);
        self.core.actuation.torque(u, &mut d.tau);
        let (q, v) = x.split_at(nq);
        let minv = compute_minverse(model, &mut d.data, q).map_err(mb)?;
        for j in 0..6 {
            for i in 0..nv {
                d.minv_s[(i, j)] = minv[(i, self.idx_v + j)];
            }
        }
        let chol = self.delassus(&d.minv_s)?;
        let a_free = aba(model, &mut d.data, q, v, &d.tau).map_err(mb)?;
        d.a.copy_from_slice(a_free);
        let (r, _) = self.baumgarte(x);
        let rhs = Vector6::from_fn(|i, _| r[i] - d.a[self.idx_v + i]);
        let lambda = chol.solve(&rhs);
        for (i, ai) in d.a.iter_mut().enumerate() {
            *ai += (0..6).map(|j| d.minv_s[(i, j)] * lambda[j]).sum::<f64>();
        }
        d.lambda = std::array::from_fn(|i| lambda[i]);
        gharial::error::check_finite(format_args!("{NAME}: acceleration"), &d.a)?;
        d.x.copy_from_slice(x);
        d.u.copy_from_slice(u);
        d.solved = true;
        Ok(())
    }

    /// The solution and its derivatives at `(x, u)`.
    fn differentiate(&self, x: &[f64], u: &[f64], d: &mut WeldData) -> Result<()> {
        self.solve(x, u, d)?;
        if d.differentiated {
            return Ok(());
        }
        let (nq, nv, s) = (self.core.nq(), self.core.nv(), self.idx_v);
        let model = self.core.model();
        for j in 0..6 {
            d.tau[s + j] += d.lambda[j];
        }
        let (q, v) = x.split_at(nq);
        let res = compute_aba_derivatives(model, &mut d.data, q, v, &d.tau);
        self.core.actuation.torque(u, &mut d.tau);
        res.map_err(|e| crate::multibody_error(NAME, e))?;
        let chol = self.delassus(&d.minv_s)?;
        let (_, c) = self.baumgarte(x);
        let (jl, jc) = jlog6_blocks(&c);
        // ∂r/∂q on the columns of S: −Kp Jlog6(M_j) = −Kp [[Jl, C], [0, Jl]].
        let dr_dq = |i: usize, k: usize| -> f64 {
            match (i < 3, k < 3) {
                (true, true) => jl[(i, k)],
                (true, false) => jc[(i, k - 3)],
                (false, true) => 0.0,
                (false, false) => jl[(i - 3, k - 3)],
            }
        };
        let data = &d.data;
        let (ddq_dq, ddq_dv, minv) = (data.ddq_dq(), data.ddq_dv(), data.minv());
        for k in 0..nv {
            let in_s = (s..s + 6).contains(&k);
            let rq = Vector6::from_fn(|i, _| {
                let dr = if in_s { -self.kp * dr_dq(i, k - s) } else { 0.0 };
                dr - ddq_dq[(s + i, k)]
            });
            let rv = Vector6::from_fn(|i, _| {
                let dr = if in_s && k - s == i { -self.kd } else { 0.0 };
                dr - ddq_dv[(s + i, k)]
            });
            let rt = Vector6::from_fn(|i, _| -minv[(s + i, k)]);
            for (rhs, dl, da, base) in [
                (rq, &mut d.dlambda_dq, &mut d.da_dq, ddq_dq),
                (rv, &mut d.dlambda_dv, &mut d.da_dv, ddq_dv),
                (rt, &mut d.dlambda_dtau, &mut d.da_dtau, minv),
            ] {
                let l = chol.solve(&rhs);
                for j in 0..6 {
                    dl[(j, k)] = l[j];
                }
                for i in 0..nv {
                    da[(i, k)] = base[(i, k)] + (0..6).map(|j| d.minv_s[(i, j)] * l[j]).sum::<f64>();
                }
            }
        }
        let finite = |m: &Mat<f64>| (0..nv).all(|k| (0..nv).all(|i| m[(i, k)].is_finite()));
        if !(finite(&d.da_dq) && finite(&d.da_dv) && finite(&d.da_dtau)) {
            return Err(Error::non_finite(format!("{NAME}: acceleration derivatives")));
        }
        d.differentiated = true;
        Ok(())
    }
}

impl Ode for MultibodyWeldFwdDynamics {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.core.manifold
    }

    fn nu(&self) -> usize {
        self.core.actuation.nu()
    }

    fn create_workspace(&self) -> Workspace {
        Box::new(self.create_weld_data())
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let d: &mut WeldData = workspace(&mut data.ws);
        match self.solve(x, u, d) {
            Ok(()) => {
                self.core.write_xdot(x, &d.a, slice_mut(&mut data.xdot));
                d.error = None;
            }
            Err(e) => {
                d.error = Some(e);
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

impl MultibodyWeldFwdDynamics {
    /// [`Ode::jacobians`] (`full`) or [`Ode::acceleration_jacobians`].
    fn write_jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData, full: bool) {
        let d: &mut WeldData = workspace(&mut data.ws);
        match self.differentiate(x, u, d) {
            Ok(()) => {
                let j = (data.jx.as_mut(), data.ju.as_mut());
                self.core
                    .write_jacobians(d.da_dq.as_ref(), d.da_dv.as_ref(), d.da_dtau.as_ref(), j, full);
                d.error = None;
            }
            Err(e) => {
                d.error = Some(e);
                nan_jacobians(data);
            }
        }
    }
}
