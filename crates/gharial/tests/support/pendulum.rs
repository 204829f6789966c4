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

/// A pendulum `(θ, ω)` on `R²` by semi-implicit Euler with a saturating actuator,
/// `ω⁺ = ω + dt (u - 0.1 u³ - g sin θ)`,
/// `θ⁺ = θ + dt ω⁺`, through the dual-number adapter (which gives the vector-Hessian
/// products of the exact Hessian).
pub struct EulerPendulum {
    pub dt: f64,
}

impl gharial::autodiff::AutoDynamicsFn for EulerPendulum {
    fn nx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: gharial::autodiff::ManifoldScalar>(&self, x: &[D], u: &[D], y: &mut [D]) {
        y[1] = x[1] + (u[0] - u[0].powi(3) * 0.1 - x[0].sin() * 9.81) * self.dt;
        y[0] = x[0] + y[1] * self.dt;
    }
}

/// Swing-up of [`EulerPendulum`] towards `θ = π` in `n` steps of 0.05 s: quadratic
/// state and control costs, terminal weight 10.
pub fn euler_swing_up(n: usize, x0: [f64; 2]) -> gharial::problem::Problem {
    use gharial::autodiff::AutoDiff;
    use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
    use gharial::dynamics::Dynamics;
    use gharial::spaces::{Manifold, VectorSpace};
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let phi = AutoDiff::explicit_dynamics(space.clone(), space.clone(), EulerPendulum { dt: 0.05 }).unwrap();
    let target = [std::f64::consts::PI, 0.0];
    let state = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[0.05, 0.01], 1).unwrap());
    let control = Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[0.02]).unwrap());
    let stack = CostStack::new(space.as_ref(), 1)
        .with("x", state, 1.0)
        .unwrap()
        .with("u", control, 1.0)
        .unwrap();
    let stage = gharial::problem::StageModel::new(Arc::new(stack), Dynamics::Explicit(Arc::new(phi))).unwrap();
    let term = Arc::new(QuadraticStateCost::diagonal(space, &target, &[10.0, 10.0], 0).unwrap());
    gharial::problem::Problem::new(&x0, vec![stage; n], term).unwrap()
}

/// A guess that interpolates the swing-up from 0 to π (it violates the dynamics), with
/// zero controls.
pub fn interpolated_guess(p: &gharial::problem::Problem) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = p.horizon();
    let xs = (0..=n)
        .map(|t| vec![std::f64::consts::PI * t as f64 / n as f64, 0.0])
        .collect();
    (xs, vec![vec![0.0]; n])
}
