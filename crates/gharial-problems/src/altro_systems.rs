//! The swing-ups of ALTRO's Table I (Howell et al. 2019, §IV-A) with the authors' models
//! and problem data (TrajectoryOptimization.jl, `problems/pendulum.jl`,
//! `problems/cartpole.jl`, `problems/acrobot.jl`, and the models of its
//! `dynamics/`): pendulum, its time-penalised version, acrobot and cart-pole. Euclidean
//! states (angles as plain coordinates, as the authors write them), RK4 (the authors use
//! RK3), the quadratic objective and goal constraint of [`crate::altro_table`]:
//! `½ Σ dt ((x − x_f)ᵀQ(x − x_f) + uᵀRu) + ½ (x_N − x_f)ᵀQ_f(x_N − x_f)`, `x_N = x_f`,
//! and the guess `u = u₀` rolled out.
//!
//! # Models (angle 0: hanging)
//! - *Pendulum*: `θ̈ = (u − m g l_c sin θ − b θ̇) / J`, `m = 1`, `l_c = 0.5`, `b = 0.1`,
//!   `J = 0.25`.
//! - *Acrobot* (torque at the elbow): `H(q) q̈ + C(q, q̇) q̇ + G(q) = (0, u)`, links of mass
//!   1, length 1, centre 0.5, inertia `m L² / 3` about the joint;
//!   `H = [J₁ + J₂ + m₂L₁² + 2m₂L₁L_c2 cos q₂, J₂ + m₂L₁L_c2 cos q₂; ·, J₂]`,
//!   `C q̇ = (−m₂L₁L_c2 sin q₂ (2 q̇₁ q̇₂ + q̇₂²), m₂L₁L_c2 sin q₂ q̇₁²)`,
//!   `G = ((m₁L_c1 + m₂L₁) g sin q₁ + m₂ g L₂ sin(q₁ + q₂), m₂ g L₂ sin(q₁ + q₂))` (the
//!   authors' gravity term, with the second link's length `L₂` where its centre would be).
//! - *Cart-pole*: `H q̈ + C q̇ + G = (u, 0)`, cart `m_c = 1`, point mass `m_p = 0.2` at
//!   `l = 0.5`: `H = [m_c + m_p, m_p l cos θ; ·, m_p l²]`, `C q̇ = (−m_p l sin θ θ̇², 0)`,
//!   `G = (0, m_p g l sin θ)`.
//!
//! | problem | N, T | Q, R, Q_f | x₀ → x_f | bounds | u₀ |
//! |---|---|---|---|---|---|
//! | `altro-pendulum` | 30, 4.5 s | 1e-3 I, 1e-3, 1e-3 I | (0, 0) → (π, 0) | `|u| ≤ 3` | 1 |
//! | `altro-acrobot` | 100, 5 s | I, 0.01, 100 I | 0 → (π, 0, 0, 0) | `|u| ≤ 15` | 0 |
//! | `altro-cartpole` | 100, 5 s | 1e-2 I, 0.1, 100 I | 0 → (0, π, 0, 0) | `|u| ≤ 3` | 0.01 |
//!
//! (`problems/acrobot.jl` writes the swing-up from `−π/2` to `π/2` for a model whose
//! angle is measured from the horizontal; here from hanging to upright.)
//!
//! ProxDDP's settings (`Example::proxddp`): its defaults (`dyn_al_scale = 1e-3`, the
//! dynamics nearly hard in the merit) crawl on the acrobot and the cart-pole, steps of 1/8
//! and below for thousands of iterations. Measured (release, iterations to 1e-6, local
//! optimum reached): `altro-acrobot` with `mu_init = 0.1`, `dyn_al_scale = 0.5`: 507, cost
//! 35.568, a cheaper local optimum than ALTRO's 42.26 (with `dyn_al_scale = 1`: 813, the
//! same point; with `mu_init` 0.2 or 1: 1024 / 1175 to a third one, 46.61); `altro-cartpole`
//! with the nonmonotone line search on the primal merit and `dyn_al_scale = 0.01`: 521,
//! ALTRO's optimum (1.48619; the defaults at 1e-6: 829). The exact Hessian of the RK4
//! step (hyper-dual numbers through the whole step) was tried and does not help: the
//! cart-pole takes 1265 iterations, the acrobot's line search fails.
//!
//! `altro-pendulum-min-time` (§III-C, [`MinimumTime`]): the pendulum with the step
//! `h = τ²` as a control, `h ∈ [1e-3, 0.2]`, `R_min_time = 1` (the default of the
//! authors' `minimum_time_problem`; `max_dt = 0.2` of their paper scripts), started from
//! the fixed problem's step 0.15.

use std::sync::Arc;

use gharial::Result;
use gharial::autodiff::{AutoDiff, AutoOdeFn, ManifoldScalar};
use gharial::dynamics::{Ode, RkMethod};
use gharial::problem::MinimumTime;
use gharial::solvers::proxddp::{Merit, Rollout, StepAcceptance};
use gharial::spaces::VectorSpace;

use crate::Example;
use crate::altro_table::{Spec, control_bounds};

/// The authors' pendulum (module documentation).
struct Pendulum;

impl AutoOdeFn for Pendulum {
    fn nx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let (m, lc, b, j, g) = (1.0, 0.5, 0.1, 0.25, 9.81);
        xdot[0] = x[1];
        xdot[1] = (u[0] - x[0].sin() * (m * g * lc) - x[1] * b) * (1.0 / j);
    }
}

/// The authors' acrobot (module documentation).
struct Acrobot;

impl AutoOdeFn for Acrobot {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let (m1, m2, l1, l2, lc1, lc2, g) = (1.0, 1.0, 1.0, 1.0, 0.5, 0.5, 9.81);
        let (j1, j2) = (m1 * l1 * l1 / 3.0, m2 * l2 * l2 / 3.0);
        let (s2, c2) = (x[1].sin(), x[1].cos());
        let s12 = (x[0] + x[1]).sin();
        let k = m2 * l1 * lc2;
        let h01 = c2 * k + j2;
        let h = [c2 * (2.0 * k) + (j1 + j2 + m2 * l1 * l1), h01, D::from(j2)];
        let cqd = [-(s2 * k) * (x[2] * x[3] * 2.0 + x[3] * x[3]), s2 * k * x[2] * x[2]];
        let gq = [
            x[0].sin() * ((m1 * lc1 + m2 * l1) * g) + s12 * (m2 * g * l2),
            s12 * (m2 * g * l2),
        ];
        let qdd = crate::solve2(&h, &[-cqd[0] - gq[0], u[0] - cqd[1] - gq[1]]);
        xdot[0] = x[2];
        xdot[1] = x[3];
        xdot[2] = qdd[0];
        xdot[3] = qdd[1];
    }
}

/// The authors' cart-pole (module documentation).
struct Cartpole;

impl AutoOdeFn for Cartpole {
    fn nx(&self) -> usize {
        4
    }
    fn nu(&self) -> usize {
        1
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], u: &[D], xdot: &mut [D]) {
        let (mc, mp, l, g) = (1.0, 0.2, 0.5, 9.81);
        let (s, c) = (x[1].sin(), x[1].cos());
        let h01 = c * (mp * l);
        let h = [D::from(mc + mp), h01, D::from(mp * l * l)];
        let b = [u[0] + s * (mp * l) * x[3] * x[3], -(s * (mp * g * l))];
        let qdd = crate::solve2(&h, &b);
        xdot[0] = x[2];
        xdot[1] = x[3];
        xdot[2] = qdd[0];
        xdot[3] = qdd[1];
    }
}

fn ode<F: AutoOdeFn + 'static>(f: F) -> Result<Arc<dyn Ode>> {
    let n = f.nx();
    Ok(Arc::new(AutoDiff::ode(Arc::new(VectorSpace::new(n)), f)?))
}

fn pendulum_spec(name: &'static str, description: &'static str) -> Spec {
    Spec {
        name,
        horizon: 30,
        duration: 4.5,
        weights: [1e-3, 1e-3, 1e-3],
        x0: vec![0.0, 0.0],
        xf: vec![std::f64::consts::PI, 0.0],
        u_guess: 1.0,
        description,
    }
}

/// `altro-pendulum` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn pendulum() -> Result<Example> {
    let spec = pendulum_spec(
        "altro-pendulum",
        "ALTRO Table I pendulum: swing-up from hanging in 4.5 s, |u| <= 3, goal constraint, N = 30",
    );
    let problem = spec.problem(ode(Pendulum)?, &[control_bounds(2, &[-3.0], &[3.0])?], &[])?;
    let mut ex = spec.example(problem, None)?;
    nonmonotone(&mut ex, 1e-1, Rollout::Nonlinear);
    Ok(ex)
}

/// ProxDDP's settings where its defaults stall: the nonmonotone line search on the primal
/// merit (as on `cartpole`), `mu_init` and the rollout measured best (module
/// documentation).
pub(crate) fn nonmonotone(ex: &mut Example, mu_init: f64, rollout: Rollout) {
    ex.proxddp.mu_init = mu_init;
    ex.proxddp.rollout = rollout;
    ex.proxddp.step_acceptance = StepAcceptance::NonmonotoneLinesearch;
    ex.proxddp.merit = Merit::Primal;
    ex.proxddp.max_iters = 1000;
}

/// Step bounds and time weight of `altro-pendulum-min-time` (module documentation).
pub const PENDULUM_MIN_TIME: [f64; 3] = [1e-3, 0.2, 1.0];

/// `altro-pendulum-min-time` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn pendulum_min_time() -> Result<Example> {
    let spec = pendulum_spec(
        "altro-pendulum-min-time",
        "ALTRO Table I pendulum time-penalised: the step h = tau^2 a control in [1e-3, 0.2], R_min_time = 1, \
         equal steps, |u| <= 3, goal constraint, N = 30; started from h = 0.15",
    );
    let [h_min, h_max, r] = PENDULUM_MIN_TIME;
    let mt = MinimumTime::new(h_min, h_max, r, RkMethod::Rk4)?;
    let problem = spec.min_time_problem(ode(Pendulum)?, &[control_bounds(2, &[-3.0], &[3.0])?], &[], &mt)?;
    let mut ex = spec.min_time_example(problem)?;
    ex.proxddp.tol = 1e-6;
    nonmonotone(&mut ex, 1e-2, Rollout::Nonlinear);
    Ok(ex)
}

/// `altro-acrobot` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn acrobot() -> Result<Example> {
    let spec = Spec {
        name: "altro-acrobot",
        horizon: 100,
        duration: 5.0,
        weights: [1.0, 0.01, 100.0],
        x0: vec![0.0; 4],
        xf: vec![std::f64::consts::PI, 0.0, 0.0, 0.0],
        u_guess: 0.0,
        description: "ALTRO Table I acrobot: swing-up from hanging in 5 s by the elbow torque, |u| <= 15, \
                      goal constraint, N = 100",
    };
    let problem = spec.problem(ode(Acrobot)?, &[control_bounds(4, &[-15.0], &[15.0])?], &[])?;
    let mut ex = spec.example(problem, None)?;
    ex.proxddp.mu_init = 0.1;
    ex.proxddp.dyn_al_scale = 0.5;
    ex.proxddp.tol = 1e-6;
    ex.proxddp.max_iters = 1000;
    Ok(ex)
}

/// `altro-cartpole` (module documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn cartpole() -> Result<Example> {
    let spec = Spec {
        name: "altro-cartpole",
        horizon: 100,
        duration: 5.0,
        weights: [1e-2, 0.1, 100.0],
        x0: vec![0.0; 4],
        xf: vec![0.0, std::f64::consts::PI, 0.0, 0.0],
        u_guess: 0.01,
        description: "ALTRO Table I cart-pole: swing-up from hanging in 5 s, |u| <= 3, goal constraint, N = 100",
    };
    let problem = spec.problem(ode(Cartpole)?, &[control_bounds(4, &[-3.0], &[3.0])?], &[])?;
    let mut ex = spec.example(problem, None)?;
    nonmonotone(&mut ex, 1e-2, Rollout::Linear);
    ex.proxddp.dyn_al_scale = 0.01;
    ex.proxddp.tol = 1e-6;
    Ok(ex)
}
