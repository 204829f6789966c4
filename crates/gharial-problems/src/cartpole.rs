//! `cartpole`: swing-up of a pole on a cart with force limits and a terminal
//! constraint on the tip position (ProxDDP paper, Fig. 5).
//!
//! # Model
//! A cart of mass `m_c = 1 kg` sliding along y, carrying a pole that rotates about the
//! x axis with a point mass `m = 0.1 kg` (a sphere of radius 0.1 m, inertia
//! `I_c = 2/5 m r²`) at `l = 1 m`; `θ = 0` is upright, gravity `g = 9.81` along `-z`.
//! State `x = (y, θ, ẏ, θ̇) ∈ R² × R²`, control the force `F` on the cart:
//! ```text
//! M(θ) (ÿ, θ̈) = (F - m l sin θ θ̇²,  m g l sin θ),
//! M(θ) = [m_c + m, -m l cos θ; -m l cos θ, m l² + I_c]
//! tip p(x) = (y - l sin θ, l cos θ)  in the y-z plane
//! ```
//! Semi-implicit Euler, `dt = 10 ms`, N = 500 (T = 5 s).
//!
//! # Problem
//! ```text
//! ℓ(x, u) = ½ dt (1e-3 |x|² + 1e-3 F²),   ℓ_N = 0,   p(x_N) = (0, 1),   |F| ≤ 6
//! ```
//! `x0 = (0, π, 0, 0)` (pole hanging). Initial guess: `F = 0` and the dynamically
//! infeasible states `θ_t = π (1 - t/N)`, `θ̇_t = -π/T` (at rest at both ends), cart
//! at rest at `y = 0` (from the rollout of `F = 0` the pole hangs at `θ = π`, where the
//! Jacobian of the terminal constraint's z-row vanishes).
//! Settings: `mu_init = 1e-5` (Fig. 5), nonlinear rollout, at most 3000 iterations, and
//! aligator's step acceptance: the nonmonotone Armijo line search on the primal
//! augmented Lagrangian (35). With the force limits active, the Newton steps cross the
//! kinks of the penalty and the monotone rules accept only short steps for hundreds of
//! iterations; the nonmonotone reference lets the merit rise for a few steps (measured:
//! 242 iterations nonlinear and 186 linear, instead of 492 and 1780 with the default
//! filter on the primal-dual merit; from `mu_init` 1e-3 and 1e-1: 346 and 791, the
//! filter from 1e-1 not in 800). Without the force limits (`F_MAX = 100`) the
//! default filter converges in 161 iterations (crate README, "Solver issues found").
//! The dynamics keep the full penalty (`dyn_al_scale = 1`): with the solver's default
//! `1e-3` the swing-up takes 264 iterations nonlinear and 229 linear (measured).
//!
//! # Jacobians
//! Hand-written: with `a = M⁻¹ b`, `da/dz = M⁻¹ (db/dz - (dM/dz) a)`, where only `θ`
//! enters `M`. Checked against the generic model with dual numbers and against finite
//! differences in the tests.

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoOdeFn, AutoUnaryFn, ManifoldScalar};
use gharial::constraints::EqualityConstraintSet;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, Ode, OdeData, SemiImplicitEuler};
use gharial::functions::Unary;
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{Merit, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::spaces::{Manifold, VectorSpace};

use crate::lqr::control_box;
use crate::{Example, solve2, swing_guess};

/// Time step (s).
pub const DT: f64 = 0.01;
/// Horizon (T = 5 s).
pub const HORIZON: usize = 500;
/// Force limit (N).
pub const F_MAX: f64 = 6.0;

/// The cart-pole ODE of the module documentation on `R² × R²`.
#[derive(Debug, Clone)]
pub struct CartpoleOde {
    space: Arc<dyn Manifold>,
    cart_mass: f64,
    pole_mass: f64,
    length: f64,
    /// Pole inertia about the joint, `m l² + I_c`.
    pole_inertia: f64,
    gravity: f64,
}

impl CartpoleOde {
    /// The cart-pole of the module documentation.
    pub fn new() -> Self {
        Self::with_pole(1.0, 0.1, 1.0, 0.1)
    }

    /// A cart of mass `cart_mass` carrying at `length` a sphere of mass `pole_mass` and
    /// radius `radius` (0: a point mass), `g = 9.81`.
    pub fn with_pole(cart_mass: f64, pole_mass: f64, length: f64, radius: f64) -> Self {
        let (m, l, r) = (pole_mass, length, radius);
        Self {
            space: Arc::new(VectorSpace::new(4)),
            cart_mass,
            pole_mass: m,
            length: l,
            pole_inertia: m * l * l + 0.4 * m * r * r,
            gravity: 9.81,
        }
    }

    /// `M(θ)` entries `(m11, m12, m22)` and the right-hand side `b` at `(θ, θ̇, F)`.
    fn terms<D: ManifoldScalar>(&self, theta: D, omega: D, f: D) -> ([D; 3], [D; 2]) {
        let (s, c) = (theta.sin(), theta.cos());
        let ml = self.pole_mass * self.length;
        let m = [
            D::from(self.cart_mass + self.pole_mass),
            -c * ml,
            D::from(self.pole_inertia),
        ];
        let b = [f - s * omega * omega * ml, s * (ml * self.gravity)];
        (m, b)
    }
}

impl Default for CartpoleOde {
    fn default() -> Self {
        Self::new()
    }
}

impl AutoOdeFn for CartpoleOde {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let (m, b) = self.terms(x[1], x[3], u[0]);
        let a = solve2(&m, &b);
        xdot[0] = x[2];
        xdot[1] = x[3];
        xdot[2] = a[0];
        xdot[3] = a[1];
    }
}

impl Ode for CartpoleOde {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn evaluate(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        self.eval(x, u, data.xdot_mut());
    }
    fn jacobians(&self, x: &[f64], u: &[f64], data: &mut OdeData) {
        let (theta, omega) = (x[1], x[3]);
        let (m, b) = self.terms(theta, omega, u[0]);
        let a = solve2(&m, &b);
        let (s, c) = (theta.sin(), theta.cos());
        let ml = self.pole_mass * self.length;
        // dM/dθ = [0 m l sin θ; m l sin θ 0].
        let dm12 = s * ml;
        let db_dtheta = [
            -c * omega * omega * ml - dm12 * a[1],
            c * ml * self.gravity - dm12 * a[0],
        ];
        let da_dtheta = solve2(&m, &db_dtheta);
        let da_domega = solve2(&m, &[-2.0 * s * omega * ml, 0.0]);
        let da_df = solve2(&m, &[1.0, 0.0]);
        data.jx.fill(0.0);
        data.jx[(0, 2)] = 1.0;
        data.jx[(1, 3)] = 1.0;
        for i in 0..2 {
            data.jx[(2 + i, 1)] = da_dtheta[i];
            data.jx[(2 + i, 3)] = da_domega[i];
            data.ju[(i, 0)] = 0.0;
            data.ju[(2 + i, 0)] = da_df[i];
        }
    }
}

/// The tip position error `p(x) - p*` in the y-z plane.
#[derive(Debug, Clone, Copy)]
pub struct CartpoleTipError {
    /// Pole length.
    pub length: f64,
    /// Target `p* = (y, z)`.
    pub target: [f64; 2],
}

impl AutoUnaryFn for CartpoleTipError {
    fn nx(&self) -> usize {
        4
    }
    fn nr(&self) -> usize {
        2
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], out: &mut [D]) {
        out[0] = x[0] - x[1].sin() * self.length - self.target[0];
        out[1] = x[1].cos() * self.length - self.target[1];
    }
}

/// The stage of both variants: semi-implicit Euler, quadratic regularisation, `|F| ≤ F_MAX`.
fn stage() -> Result<(StageModel, Arc<dyn Manifold>)> {
    let ode = Arc::new(CartpoleOde::new());
    let space = ode.space.clone();
    let nu = 1;
    let dynamics = Dynamics::Explicit(Arc::new(SemiImplicitEuler::new(
        ode,
        Arc::new(VectorSpace::new(2)),
        DT,
    )?));
    let cost = CostStack::new(space.as_ref(), nu)
        .with(
            "u_reg",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[1e-3 * DT])?),
            1.0,
        )?
        .with(
            "x_reg",
            Arc::new(QuadraticStateCost::diagonal(
                space.clone(),
                &[0.0; 4],
                &[1e-3 * DT; 4],
                nu,
            )?),
            1.0,
        )?;
    let stage =
        StageModel::new(Arc::new(cost), dynamics)?.with_constraint(control_box(space.as_ref(), nu, F_MAX, 1.0)?)?;
    Ok((stage, space))
}

/// The cart-pole of the ALTRO paper (Howell et al. 2019, Fig. 1): the same model, costs
/// and force limits as [`build`], with the terminal *state* constraint `x_N = 0` (upright,
/// cart at the origin, at rest) instead of the tip position, and the zero-force guess
/// with its rollout (the pole hanging) as initial trajectory (the paper's Algorithm 4,
/// line 6).
///
/// # Errors
/// Never for these fixed numbers.
pub fn build_state_target() -> Result<Example> {
    let (stage, space) = stage()?;
    let target = Arc::new(gharial::functions::StateError::new(space.clone(), &[0.0; 4])?);
    let term_cost = Arc::new(gharial::costs::ConstantCost::zero(space.as_ref(), 0));
    let x0 = [0.0, std::f64::consts::PI, 0.0, 0.0];
    let problem = Problem::new(&x0, vec![stage; HORIZON], term_cost)?.with_terminal_constraint(
        StageConstraint::new("x_N", Arc::new(Unary::new(target, 0)), Arc::new(EqualityConstraintSet)),
    )?;
    let us0 = vec![vec![0.0]; HORIZON];
    let xs0 = vec![x0.to_vec(); HORIZON + 1];
    Ok(Example {
        name: "cartpole-state",
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default(),
        description: "Cart-pole swing-up with a terminal state constraint (ALTRO paper, Fig. 1): semi-implicit \
                      Euler, dt = 10 ms, T = 5 s, |F| <= 6, x_N = 0 (upright, at rest).",
    })
}

/// Builds `cartpole` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn build() -> Result<Example> {
    let (stage, space) = stage()?;
    let tip = AutoDiff::unary(
        space.clone(),
        CartpoleTipError {
            length: 1.0,
            target: [0.0, 1.0],
        },
    )?;
    let term_cost = Arc::new(gharial::costs::ConstantCost::zero(space.as_ref(), 0));
    let x0 = [0.0, std::f64::consts::PI, 0.0, 0.0];
    let problem =
        Problem::new(&x0, vec![stage; HORIZON], term_cost)?.with_terminal_constraint(StageConstraint::new(
            "tip",
            Arc::new(Unary::new(Arc::new(tip), 0)),
            Arc::new(EqualityConstraintSet),
        ))?;
    let us0 = vec![vec![0.0]; HORIZON];
    let xs0 = swing_guess(HORIZON, DT, |theta, omega| vec![0.0, theta, 0.0, omega]);
    Ok(Example {
        name: "cartpole",
        problem,
        xs0,
        us0,
        dt: Some(DT),
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-5;
            o.dyn_al_scale = 1.0;
            o.rollout = Rollout::Nonlinear;
            o.step_acceptance = StepAcceptance::NonmonotoneLinesearch;
            o.merit = Merit::Primal;
            o.max_iters = 3000;
        }),
        description: "Cart-pole swing-up (ProxDDP paper Fig. 5): semi-implicit Euler, dt = 10 ms, T = 5 s, \
                      |F| <= 6, terminal tip position (0, 1) in the y-z plane.",
    })
}
