//! `se2-car`: a kinematic car on SE(2) parking at the origin (the `se2-car` example of
//! the ProxDDP authors' library).
//!
//! # Model
//! State `x = (p_x, p_y, cos θ, sin θ) ∈ SE(2)`, control `u = (v, ω)` (forward speed and
//! turning rate). The car moves along its own heading: its body velocity is
//! `(v, 0, ω)`, which is the ODE's tangent vector at `x` in the local (right) convention
//! of [`SE2`]:
//! ```text
//! ẋ = f(x, u) = (v, 0, ω),     x_{t+1} = x_t ⊕ dt f(x_t, u_t) = x_t · exp(dt (v, 0, ω))
//! ```
//! (explicit Euler, exact for piecewise-constant controls). `f` is linear in `u` and
//! does not depend on `x`: its Jacobians are constant and hand-written.
//!
//! # Problem
//! ```text
//! ℓ(x, u) = ½ dt (0.01 |x ⊖ x*|² + |u|²),   ℓ_N(x) = ½ 0.1 |x ⊖ x*|²,   x* = identity
//! ```
//! N = 40, `dt = 0.05`, `x0 = (0.7, -0.1, θ = 0.15355)`. No constraint. Initial guess
//! `u = 0` and its rollout (the car stays at `x0`). Settings: `mu_init = 1e-2`, linear
//! rollout (as in the original example); both rollouts converge.

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoOdeFn, ManifoldScalar};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta, Ode, OdeData};
use gharial::problem::{Problem, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::{Manifold, SE2};

use crate::{Example, rollout};

/// Time step (s).
pub const DT: f64 = 0.05;
/// Horizon.
pub const HORIZON: usize = 40;

/// The kinematic car `ẋ = (v, 0, ω)` on SE(2).
#[derive(Debug, Clone)]
pub struct CarOde {
    space: Arc<dyn Manifold>,
}

impl CarOde {
    /// The car on SE(2).
    pub fn new() -> Self {
        Self {
            space: Arc::new(SE2::new()),
        }
    }
}

impl Default for CarOde {
    fn default() -> Self {
        Self::new()
    }
}

impl AutoOdeFn for CarOde {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, _x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = u[0];
        xdot[1] = D::from(0.0);
        xdot[2] = u[1];
    }
}

impl Ode for CarOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        2
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.eval(x, u, data.xdot_mut());
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], data: &mut OdeData) {
        data.jx.fill(0.0);
        data.ju.fill(0.0);
        data.ju[(0, 0)] = 1.0;
        data.ju[(2, 1)] = 1.0;
    }
}

/// Builds `se2-car` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn build() -> Result<Example> {
    let ode = Arc::new(CarOde::new());
    let space = ode.space.clone();
    let nu = 2;
    let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::euler(ode, DT)?));
    let target = SE2::from_pose(0.0, 0.0, 0.0);
    let cost = CostStack::new(space.as_ref(), nu)
        .with(
            "x_reg",
            Arc::new(QuadraticStateCost::diagonal(
                space.clone(),
                &target,
                &[0.01 * DT; 3],
                nu,
            )?),
            1.0,
        )?
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0; 2], &[DT; 2])?),
            1.0,
        )?;
    let stage = StageModel::new(Arc::new(cost), dynamics)?;
    let term_cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[0.1; 3], 0)?);
    let x0 = SE2::from_pose(0.7, -0.1, 0.15355);
    let problem = Problem::new(&x0, vec![stage; HORIZON], term_cost)?;
    let us0 = vec![vec![0.0; nu]; HORIZON];
    let xs0 = rollout(&problem, &us0)?;
    Ok(Example {
        name: "se2-car",
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-2;
            o.rollout = Rollout::Linear;
            o.max_iters = 100;
        }),
        description: "Kinematic car on SE(2) (body velocity (v, 0, omega)), explicit Euler, N = 40, dt = 0.05, \
                      quadratic costs towards the identity pose; unconstrained.",
    })
}
