//! Centre-of-mass residuals: position and velocity in the world frame.
//!
//! The velocity `ċ = P / m` is the total linear momentum `P = Σ_i (Y_i ov_i)_lin` over
//! the mass. A tangent perturbation of dof k (joint j, parent λ) moves the subtree of j
//! rigidly with the world twist `J_k` while the joint velocities stay, so that each body
//! velocity changes by `J_k × ov_i + dVdq_k` with `dVdq_k = ov_λ × J_k`, and its
//! momentum by `J_k ×* h_i + Y_i dVdq_k`. Summed over the subtree (composite inertia
//! `Y_j^c`, momentum `P_j`):
//! `∂P/∂q_k = ω_k × P_j + (Y_j^c dVdq_k)_lin`.

use std::sync::Arc;

use faer::MatMut;
use faer::reborrow::ReborrowMut;
use gharial::functions::{StageFunctionData, UnaryFunction, Workspace};
use gharial::linalg::{copy, slice_mut};
use gharial::{Error, Result};
use gharial_multibody::spatial::Vec3;
use gharial_multibody::{
    Data, Model, ReferenceFrame, center_of_mass, forward_kinematics, jacobian_center_of_mass, joint_velocity,
};

use super::{MultibodyWs, StateLayout, VectorTarget, ok_or_nan_mat, put3, ws};
use crate::MultibodyPhaseSpace;

/// Checks that the model has mass (its centre of mass is defined).
fn check_mass(owner: &str, model: &Model) -> Result<()> {
    let m = model.total_mass();
    if m > 0.0 && m.is_finite() {
        Ok(())
    } else {
        Err(Error::InvalidModel(format!(
            "{owner}: model `{}` has total mass {m}: its centre of mass is not defined",
            model.name
        )))
    }
}

/// Writes `c − target` (or NaN when the multibody computation failed).
fn write_error(res: gharial_multibody::Result<Vec3>, target: &VectorTarget, out: &mut [f64]) {
    match res {
        Ok(c) => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = c[i] - target.at(i);
            }
        }
        Err(_) => out.fill(f64::NAN),
    }
}

/// Writes `∂c/∂q = Jcom` (or NaN) into the q-block and zero into the v-block of `jx`.
fn write_com_jacobian(model: &Model, data: &mut Data, q: &[f64], jx: MatMut<'_, f64>, nv: usize) {
    let (mut dq, mut dv) = jx.split_at_col_mut(nv);
    match jacobian_center_of_mass(model, data, q) {
        Ok(j) => copy(dq, j),
        Err(_) => dq.fill(f64::NAN),
    }
    dv.fill(0.0);
}

/// The centre-of-mass position error `r = c(q) − c_ref` in the world (ALIGATOR's
/// `CenterOfMassTranslationResidual`), `nr = 3`. Jacobian `[Jcom, 0]`.
#[derive(Debug)]
pub struct CenterOfMassTranslationResidual {
    model: Arc<Model>,
    layout: StateLayout,
    target: VectorTarget,
}

impl CenterOfMassTranslationResidual {
    /// The residual with target `c_ref` (3, world).
    ///
    /// # Errors
    /// If `c_ref` does not have 3 finite entries or the model has no mass.
    pub fn new(space: &MultibodyPhaseSpace, c_ref: &[f64]) -> Result<Self> {
        let model = space.model().clone();
        check_mass("CenterOfMassTranslationResidual", &model)?;
        Ok(Self {
            target: VectorTarget::new("CenterOfMassTranslationResidual target c_ref", c_ref, 3)?,
            layout: StateLayout::of(space),
            model,
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `c_ref` does not have 3 finite entries; the target is then unchanged.
    pub fn set_target(&self, c_ref: &[f64]) -> Result<()> {
        self.target.set(c_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.target.get()
    }
}

impl UnaryFunction for CenterOfMassTranslationResidual {
    unary_sizes!(3);

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut MultibodyWs = ws(&mut data.ws);
        let res = center_of_mass(&self.model, &mut w.data, self.layout.q(x), &w.zeros, &w.zeros).copied();
        write_error(res, &self.target, slice_mut(&mut data.value));
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut MultibodyWs = ws(&mut data.ws);
        write_com_jacobian(
            &self.model,
            &mut w.data,
            self.layout.q(x),
            data.jx.as_mut(),
            self.layout.nv,
        );
    }
}

/// The centre-of-mass velocity error `r = ċ(q, v) − ċ_ref` in the world, `nr = 3`.
/// Jacobian `[∂ċ/∂q, Jcom]` (see the module documentation for `∂ċ/∂q`).
#[derive(Debug)]
pub struct CenterOfMassVelocityResidual {
    model: Arc<Model>,
    layout: StateLayout,
    target: VectorTarget,
}

/// Mass, first moment and linear momentum of a body or a subtree (world frame).
#[derive(Debug, Clone, Copy, Default)]
struct Momentum {
    mass: f64,
    first_moment: Vec3,
    linear: Vec3,
}

impl std::ops::AddAssign for Momentum {
    fn add_assign(&mut self, o: Momentum) {
        self.mass += o.mass;
        self.first_moment += o.first_moment;
        self.linear += o.linear;
    }
}

/// Scratch of [`CenterOfMassVelocityResidual`].
struct ComVelocityWs {
    mb: MultibodyWs,
    /// Per joint: the subtree's [`Momentum`].
    subtree: Vec<Momentum>,
}

impl CenterOfMassVelocityResidual {
    /// The residual with target `v_ref` (3, world).
    ///
    /// # Errors
    /// If `v_ref` does not have 3 finite entries or the model has no mass.
    pub fn new(space: &MultibodyPhaseSpace, v_ref: &[f64]) -> Result<Self> {
        let model = space.model().clone();
        check_mass("CenterOfMassVelocityResidual", &model)?;
        Ok(Self {
            target: VectorTarget::new("CenterOfMassVelocityResidual target v_ref", v_ref, 3)?,
            layout: StateLayout::of(space),
            model,
        })
    }

    /// Moves the target.
    ///
    /// # Errors
    /// If `v_ref` does not have 3 finite entries; the target is then unchanged.
    pub fn set_target(&self, v_ref: &[f64]) -> Result<()> {
        self.target.set(v_ref)
    }

    /// The current target.
    pub fn target(&self) -> Vec<f64> {
        self.target.get()
    }

    /// `∂ċ/∂q` (3 × nv) after `forward_kinematics(q, v)` and `jacobian_center_of_mass(q)`.
    fn velocity_dq(
        &self,
        data: &Data,
        subtree: &mut [Momentum],
        mut out: MatMut<'_, f64>,
    ) -> gharial_multibody::Result<()> {
        let (model, nj) = (&*self.model, self.model.njoints());
        for i in 1..nj {
            let y = model.inertias()[i].transformed(data.joint_placement(i));
            let ov = joint_velocity(data, i, ReferenceFrame::World)?;
            subtree[i] = Momentum {
                mass: y.mass,
                first_moment: y.first_moment,
                linear: y.mul_motion(&ov).linear,
            };
        }
        for i in (1..nj).rev() {
            let p = model.parents()[i];
            if p != 0 {
                let s = subtree[i];
                subtree[p] += s;
            }
        }
        let m = data.total_mass();
        for i in 1..nj {
            let (jm, s) = (&model.joints()[i], subtree[i]);
            let ov_parent = joint_velocity(data, model.parents()[i], ReferenceFrame::World)?;
            for k in jm.idx_v..jm.idx_v + jm.nv {
                let jk = data.joint_jacobian_column(k);
                let dvdq = ov_parent.cross(jk);
                let dp = jk.angular.cross(&s.linear) + dvdq.linear * s.mass - s.first_moment.cross(&dvdq.angular);
                put3(&mut out, 0, k, &(dp / m));
            }
        }
        Ok(())
    }
}

impl UnaryFunction for CenterOfMassVelocityResidual {
    unary_dims!(3);

    fn create_workspace(&self) -> Workspace {
        Box::new(ComVelocityWs {
            mb: MultibodyWs::new(&self.model),
            subtree: vec![Momentum::default(); self.model.njoints()],
        })
    }

    fn evaluate(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut ComVelocityWs = ws(&mut data.ws);
        let (q, v) = (self.layout.q(x), self.layout.v(x));
        let mb = &mut w.mb;
        let res = center_of_mass(&self.model, &mut mb.data, q, v, &mb.zeros).map(|_| ());
        let res = res.map(|()| *mb.data.vcom());
        write_error(res, &self.target, slice_mut(&mut data.value));
    }

    fn jacobian(&self, x: &[f64], data: &mut StageFunctionData) {
        let w: &mut ComVelocityWs = ws(&mut data.ws);
        let (q, v, nv) = (self.layout.q(x), self.layout.v(x), self.layout.nv);
        let mb = &mut w.mb;
        let mut jx = data.jx.as_mut();
        let res = forward_kinematics(&self.model, &mut mb.data, q, v, &mb.zeros)
            .and_then(|()| {
                jacobian_center_of_mass(&self.model, &mut mb.data, q).map(|j| copy(jx.rb_mut().subcols_mut(nv, nv), j))
            })
            .and_then(|()| self.velocity_dq(&mb.data, &mut w.subtree, jx.rb_mut().subcols_mut(0, nv)));
        ok_or_nan_mat(res, jx);
    }
}
