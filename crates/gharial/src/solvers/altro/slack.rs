//! Slack controls of the infeasible start (ALTRO paper, III-B): the dynamics
//! `x_{k+1} = f(x_k, u_k) + s_k` (30) with the controls `(u, s)`, which make any state
//! trajectory feasible; the cost (32) and the constraint `s = 0` enter the stage's
//! augmented Lagrangian ([`super::al_cost`]). Vector-space states only.

use std::sync::Arc;

use crate::dynamics::{ExplicitDynamics, ExplicitDynamicsData};
use crate::functions::Workspace;
use crate::linalg::{self, slice, slice_mut};
use crate::spaces::Manifold;

/// `y = f(x, u) + s` for the controls `(u, s)`.
pub(super) struct SlackDynamics {
    inner: Arc<dyn ExplicitDynamics>,
}

impl SlackDynamics {
    pub(super) fn new(inner: Arc<dyn ExplicitDynamics>) -> Self {
        Self { inner }
    }
}

impl ExplicitDynamics for SlackDynamics {
    fn space(&self) -> &Arc<dyn Manifold> {
        self.inner.space()
    }
    fn space_next(&self) -> &Arc<dyn Manifold> {
        self.inner.space_next()
    }
    fn nu(&self) -> usize {
        self.inner.nu() + self.inner.space_next().ndx()
    }
    fn create_workspace(&self) -> Workspace {
        Box::new(self.inner.create_data())
    }
    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let nu = self.inner.nu();
        let ExplicitDynamicsData { xnext, ws, .. } = data;
        let d = ws.downcast_mut::<ExplicitDynamicsData>().expect("slack dynamics data");
        self.inner.forward(x, &u[..nu], d);
        for ((y, f), s) in slice_mut(xnext).iter_mut().zip(slice(&d.xnext)).zip(&u[nu..]) {
            *y = f + s;
        }
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let nu = self.inner.nu();
        let ExplicitDynamicsData { jx, ju, ws, .. } = data;
        let d = ws.downcast_mut::<ExplicitDynamicsData>().expect("slack dynamics data");
        self.inner.jacobians(x, &u[..nu], d);
        linalg::copy(jx.as_mut(), d.jx.as_ref());
        linalg::copy(ju.as_mut().subcols_mut(0, nu), d.ju.as_ref());
        let ns = ju.nrows();
        for j in 0..ns {
            for i in 0..ns {
                ju[(i, nu + j)] = if i == j { 1.0 } else { 0.0 };
            }
        }
    }
}
