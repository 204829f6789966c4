//! The damped pendulum `θ'' = -sin θ - 0.1 θ' + u` of the solver and MPC tests: a small
//! nonlinear ODE with hand-written Jacobians.
#![allow(dead_code)]

use std::sync::Arc;

use gharial::dynamics::{Ode, OdeData};
use gharial::spaces::Manifold;

/// A damped pendulum `θ'' = -sin θ - 0.1 θ' + u`.
pub struct Pendulum {
    pub space: Arc<dyn Manifold>,
}

impl Ode for Pendulum {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn evaluate(&self, x: &[f64], u: &[f64], d: &mut OdeData) {
        let xd = d.xdot_mut();
        xd[0] = x[1];
        xd[1] = -x[0].sin() - 0.1 * x[1] + u[0];
    }
    fn jacobians(&self, x: &[f64], _u: &[f64], d: &mut OdeData) {
        d.jx.fill(0.0);
        d.jx[(0, 1)] = 1.0;
        d.jx[(1, 0)] = -x[0].cos();
        d.jx[(1, 1)] = -0.1;
        d.ju.fill(0.0);
        d.ju[(1, 0)] = 1.0;
    }
}
