//! `pendulum`: swing-up of a simple pendulum with torque limits and a terminal
//! constraint on the tip position, no terminal cost (ProxDDP paper, Fig. 4).
//!
//! # Model
//! A point mass `m = 1 kg` (a sphere of radius 0.1 m, inertia `2/5 m r²` about its
//! centre) at `l = 1 m` from a joint rotating about the x axis; `θ = 0` is upright,
//! gravity `g = 9.81` along `-z`. State `x = ((cos θ, sin θ), θ̇) ∈ SO(2) × R`, control
//! the joint torque `τ`:
//! ```text
//! I θ̈ = m g l sin θ + τ,     I = m l² + 2/5 m r² = 1.004
//! tip p(θ) = (y, z) = (-l sin θ, l cos θ)
//! ```
//! Semi-implicit Euler, `dt = 10 ms`, N = 200 (T = 2 s).
//!
//! # Problem
//! ```text
//! ℓ(x, u) = ½ dt (1e-3 τ² + |p(θ) - p*|²),   p* = (0, 1)   (the tip upright)
//! ℓ_N = 0,   p(θ_N) = p*,   |τ| ≤ 20
//! ```
//! `x0 = (θ = π, θ̇ = 0)` (hanging). Initial guess: `τ = 0` and the dynamically
//! infeasible states `θ_t = π (1 - t/N)`, `θ̇_t = -π/T` (at rest at both ends): a
//! straight swing to the top.
//! From the rollout of a constant torque the pendulum stays near `θ = π`, where the
//! Jacobian of the terminal constraint's z-row vanishes: the Newton model cannot see how
//! to lift the tip (measured: no convergence in 300 iterations from the rollout of
//! `τ = 0` with `mu_init = 1`, nor from that of `τ = 1 N·m` with `mu_init` from 1 to
//! 1e-3).
//! Settings: the paper's (Fig. 4), `mu_init = 1` and the nonlinear rollout, with the
//! active-set prediction of the step (`active_set_iters = 10`): 6 iterations with either
//! rollout (without the prediction: 19 nonlinear, 18 linear).
//!
//! # Jacobians
//! Hand-written (two nonzero entries); checked against the generic model with dual
//! numbers and against finite differences in the tests.

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoOdeFn, AutoUnaryFn, ManifoldScalar};
use gharial::constraints::EqualityConstraintSet;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticResidualCost};
use gharial::dynamics::{Dynamics, Ode, OdeData, SemiImplicitEuler};
use gharial::functions::{Unary, Workspace};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::{CartesianProduct, Manifold, SO2, VectorSpace};

use crate::lqr::control_box;
use crate::{Example, swing_guess};

/// Time step (s).
pub const DT: f64 = 0.01;
/// Horizon.
pub const HORIZON: usize = 200;
/// Torque limit (N·m).
pub const TAU_MAX: f64 = 20.0;

/// The pendulum ODE `ẋ = (θ̇, (m g l sin θ + τ) / I)` on SO(2) × R.
#[derive(Debug, Clone)]
pub struct PendulumOde {
    space: Arc<dyn Manifold>,
    /// `m g l`.
    mgl: f64,
    /// `1 / I`.
    inv_inertia: f64,
}

impl PendulumOde {
    /// The pendulum of the module documentation.
    pub fn new() -> Self {
        let (m, l, r, g) = (1.0, 1.0, 0.1, 9.81);
        Self {
            space: space(),
            mgl: m * g * l,
            inv_inertia: 1.0 / (m * l * l + 0.4 * m * r * r),
        }
    }
}

impl Default for PendulumOde {
    fn default() -> Self {
        Self::new()
    }
}

/// `SO(2) × R`.
pub fn space() -> Arc<dyn Manifold> {
    Arc::new(CartesianProduct::pair(
        Arc::new(SO2::new()),
        Arc::new(VectorSpace::new(1)),
    ))
}

impl AutoOdeFn for PendulumOde {
    fn nx(&self) -> usize {
        3
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        xdot[0] = x[2];
        xdot[1] = (x[1] * self.mgl + u[0]) * self.inv_inertia;
    }
}

impl Ode for PendulumOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.eval(x, u, data.xdot_mut());
    }
    fn jacobians(&self, x: &[f64], _u: &[f64], data: &mut OdeData) {
        // d sin θ / dθ = cos θ along the SO(2) tangent.
        data.jx[(0, 0)] = 0.0;
        data.jx[(0, 1)] = 1.0;
        data.jx[(1, 0)] = self.mgl * x[0] * self.inv_inertia;
        data.jx[(1, 1)] = 0.0;
        data.ju[(0, 0)] = 0.0;
        data.ju[(1, 0)] = self.inv_inertia;
    }
    fn create_workspace(&self) -> Workspace {
        gharial::functions::no_workspace()
    }
}

/// The tip position error `p(θ) - p*` in the y-z plane (`l = 1`).
#[derive(Debug, Clone, Copy)]
pub struct TipError {
    /// Target `p* = (y, z)`.
    pub target: [f64; 2],
}

impl AutoUnaryFn for TipError {
    fn nx(&self) -> usize {
        3
    }
    fn nr(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = -x[1] - self.target[0];
        out[1] = x[0] - self.target[1];
    }
}

/// Builds `pendulum` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn build() -> Result<Example> {
    let space = space();
    let nu = 1;
    let ode = Arc::new(PendulumOde::new());
    let dynamics = Dynamics::Explicit(Arc::new(SemiImplicitEuler::new(ode, Arc::new(SO2::new()), DT)?));
    let tip = Arc::new(AutoDiff::unary(space.clone(), TipError { target: [0.0, 1.0] })?);
    let cost = CostStack::new(space.as_ref(), nu)
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[1e-3 * DT])?),
            1.0,
        )?
        .with(
            "tip",
            Arc::new(QuadraticResidualCost::diagonal(
                Arc::new(Unary::new(tip.clone(), nu)),
                &[DT, DT],
            )?),
            1.0,
        )?;
    let stage =
        StageModel::new(Arc::new(cost), dynamics)?.with_constraint(control_box(space.as_ref(), nu, TAU_MAX, 1.0)?)?;
    let term_cost = Arc::new(gharial::costs::ConstantCost::zero(space.as_ref(), 0));
    let x0 = [-1.0, std::f64::consts::PI.sin(), 0.0];
    let problem = Problem::new(&x0, vec![stage; HORIZON], term_cost)?.with_terminal_constraint(
        StageConstraint::new("tip", Arc::new(Unary::new(tip, 0)), Arc::new(EqualityConstraintSet)),
    )?;
    let us0 = vec![vec![0.0]; HORIZON];
    let xs0 = swing_guess(HORIZON, DT, |theta, omega| vec![theta.cos(), theta.sin(), omega]);
    Ok(Example {
        name: "pendulum",
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1.0;
            o.rollout = Rollout::Nonlinear;
            o.max_iters = 300;
            o.active_set_iters = 10;
        }),
        description: "Pendulum swing-up on SO(2) x R (ProxDDP paper Fig. 4): semi-implicit Euler, dt = 10 ms, \
                      N = 200, |tau| <= 20, terminal tip position (0, 1), no terminal cost.",
    })
}
