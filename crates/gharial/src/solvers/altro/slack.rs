//! Slack controls of the infeasible start (ALTRO paper, III-B): the dynamics
//! `x_{k+1} = f(x_k, u_k) ⊕ s_k` ((30) on the next state's manifold: `f + s` on vector
//! spaces, the slack a tangent vector at `f` elsewhere) with the controls `(u, s)`, which
//! make any state trajectory feasible; the cost (32) and the constraint `s = 0` enter the
//! stage's augmented Lagrangian ([`super::al_cost`]).

use std::sync::Arc;

use faer::{Accum, Mat};

use crate::dynamics::{ExplicitDynamics, ExplicitDynamicsData};
use crate::functions::Workspace;
use crate::linalg::{self, matmul, slice, slice_mut};
use crate::spaces::{Arg, Manifold};

/// `y = f(x, u) ⊕ s` for the controls `(u, s)`.
pub(super) struct SlackDynamics {
    inner: Arc<dyn ExplicitDynamics>,
}

impl SlackDynamics {
    pub(super) fn new(inner: Arc<dyn ExplicitDynamics>) -> Self {
        Self { inner }
    }
}

/// The inner dynamics' data and `d(f ⊕ s)/df`, `d(f ⊕ s)/ds`.
struct SlackWs {
    inner: ExplicitDynamicsData,
    j_f: Mat<f64>,
    j_s: Mat<f64>,
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
        let n = self.inner.space_next().ndx();
        Box::new(SlackWs {
            inner: self.inner.create_data(),
            j_f: Mat::zeros(n, n),
            j_s: Mat::zeros(n, n),
        })
    }
    fn forward(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let nu = self.inner.nu();
        let ExplicitDynamicsData { xnext, ws, .. } = data;
        let w = ws.downcast_mut::<SlackWs>().expect("slack dynamics data");
        self.inner.forward(x, &u[..nu], &mut w.inner);
        self.space_next()
            .integrate(slice(&w.inner.xnext), &u[nu..], slice_mut(xnext));
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut ExplicitDynamicsData) {
        let nu = self.inner.nu();
        let ExplicitDynamicsData { jx, ju, ws, .. } = data;
        let w = ws.downcast_mut::<SlackWs>().expect("slack dynamics data");
        self.inner.jacobians(x, &u[..nu], &mut w.inner);
        let (f, s) = (slice(&w.inner.xnext), &u[nu..]);
        let sn = self.space_next();
        if sn.is_vector_space() {
            linalg::copy(jx.as_mut(), w.inner.jx.as_ref());
            linalg::copy(ju.as_mut().subcols_mut(0, nu), w.inner.ju.as_ref());
            let ns = ju.nrows();
            for j in 0..ns {
                for i in 0..ns {
                    ju[(i, nu + j)] = if i == j { 1.0 } else { 0.0 };
                }
            }
            return;
        }
        sn.jintegrate(f, s, Arg::First, w.j_f.as_mut());
        sn.jintegrate(f, s, Arg::Second, w.j_s.as_mut());
        matmul(jx.as_mut(), Accum::Replace, w.j_f.as_ref(), w.inner.jx.as_ref(), 1.0);
        let ns = ju.nrows();
        matmul(
            ju.as_mut().subcols_mut(0, nu),
            Accum::Replace,
            w.j_f.as_ref(),
            w.inner.ju.as_ref(),
            1.0,
        );
        linalg::copy(ju.as_mut().subcols_mut(nu, ns), w.j_s.as_ref());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::{CheckOptions, check_explicit_dynamics};
    use crate::dynamics::ExplicitRungeKutta;
    use crate::dynamics::manifold_tests::{models, random_point};
    use crate::functions::testing::{random_vec, rng};

    /// `f(x, u) ⊕ s` on Lie groups and products (SO(2), SO(3), SE(3), tangent bundles):
    /// value and Jacobians against finite differences, and `s = 0` gives `f`.
    #[test]
    fn slack_dynamics_on_manifolds_match_finite_differences() {
        let mut g = rng(7);
        for (name, ode) in models() {
            let inner: Arc<dyn ExplicitDynamics> = Arc::new(ExplicitRungeKutta::rk4(ode.clone(), 0.05).unwrap());
            let d = SlackDynamics::new(inner.clone());
            let ns = inner.space_next().ndx();
            for _ in 0..3 {
                let x = random_point(ode.space().as_ref(), &mut g);
                let mut u = random_vec(&mut g, d.nu(), 1.0);
                check_explicit_dynamics(&d, &x, &u, CheckOptions::default()).assert_ok();
                let nu = inner.nu();
                u[nu..].fill(0.0);
                let (mut a, mut b) = (d.create_data(), inner.create_data());
                d.forward(&x, &u, &mut a);
                inner.forward(&x, &u[..nu], &mut b);
                assert_eq!(a.xnext(), b.xnext(), "{name}");
                assert_eq!(d.nu(), nu + ns);
            }
        }
    }
}
