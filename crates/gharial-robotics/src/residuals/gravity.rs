//! The gravity-compensation residual `r = B u − g(q)`.

use std::sync::Arc;

use faer::Mat;
use faer::reborrow::ReborrowMut;
use gharial::functions::{StageFunction, StageFunctionData, Workspace};
use gharial::linalg::{copy, slice_mut};
use gharial::{Error, Result};
use gharial_multibody::{Model, compute_rnea_derivatives, generalized_gravity};

use super::{MultibodyWs, StateLayout, ok_or_nan_mat, ws};
use crate::MultibodyPhaseSpace;
use crate::dynamics::Actuation;

/// The static torque balance `r = B u − g(q)` (ALIGATOR's
/// `GravityCompensationResidual`), `nr = nv`, with `g` the generalized gravity and `B`
/// the actuation matrix: zero when the controls hold the robot still against gravity.
///
/// Jacobians `[−∂g/∂q, 0]` (the RNEA derivatives at `v = a = 0`) and `B`.
#[derive(Debug)]
pub struct GravityCompensationResidual {
    model: Arc<Model>,
    layout: StateLayout,
    actuation: Arc<Actuation>,
    /// `B` as a dense matrix, the control Jacobian.
    b: Mat<f64>,
}

/// Scratch of [`GravityCompensationResidual`].
struct GravityWs {
    mb: MultibodyWs,
    tau: Vec<f64>,
}

impl GravityCompensationResidual {
    /// The residual of the phase space's model with actuation `actuation`.
    ///
    /// # Errors
    /// If the actuation matrix does not have `nv` rows.
    pub fn new(space: &MultibodyPhaseSpace, actuation: Arc<Actuation>) -> Result<Self> {
        gharial::error::check_dim(
            "GravityCompensationResidual: rows of the actuation matrix B (nv of the model)",
            space.nv(),
            actuation.nv(),
        )?;
        if space.nv() == 0 {
            return Err(Error::InvalidModel(
                "GravityCompensationResidual: the model has no degree of freedom".into(),
            ));
        }
        Ok(Self {
            model: space.model().clone(),
            layout: StateLayout::of(space),
            b: actuation.to_matrix(),
            actuation,
        })
    }

    /// The actuation.
    pub fn actuation(&self) -> &Arc<Actuation> {
        &self.actuation
    }
}

impl StageFunction for GravityCompensationResidual {
    fn nx(&self) -> usize {
        self.layout.nx()
    }
    fn ndx(&self) -> usize {
        self.layout.ndx()
    }
    fn nu(&self) -> usize {
        self.actuation.nu()
    }
    fn nr(&self) -> usize {
        self.layout.nv
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(GravityWs {
            mb: MultibodyWs::new(&self.model),
            tau: vec![0.0; self.layout.nv],
        })
    }

    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut StageFunctionData) {
        let w: &mut GravityWs = ws(&mut data.ws);
        let out = slice_mut(&mut data.value);
        match generalized_gravity(&self.model, &mut w.mb.data, self.layout.q(x)) {
            Ok(g) => {
                self.actuation.torque(u, &mut w.tau);
                for ((o, t), gi) in out.iter_mut().zip(&w.tau).zip(g) {
                    *o = t - gi;
                }
            }
            Err(_) => out.fill(f64::NAN),
        }
    }

    fn jacobians(&self, x: &[f64], _u: &[f64], data: &mut StageFunctionData) {
        let w: &mut GravityWs = ws(&mut data.ws);
        let (nv, mb) = (self.layout.nv, &mut w.mb);
        let res = compute_rnea_derivatives(&self.model, &mut mb.data, self.layout.q(x), &mb.zeros, &mb.zeros);
        let mut jx = data.jx.as_mut();
        if ok_or_nan_mat(res, jx.rb_mut()) {
            let (mut dq, mut dv) = jx.split_at_col_mut(nv);
            copy(dq.rb_mut(), mb.data.dtau_dq());
            gharial::linalg::negate(dq);
            dv.fill(0.0);
        }
        copy(data.ju.as_mut(), self.b.as_ref());
    }
}
