//! Linear-quadratic problems: the constrained LQR of the ProxDDP paper (Fig. 3) and
//! a random seeded LQR with control bounds.
//!
//! # `lqr`, `lqr-bounds`, `lqr-term`, `lqr-bounds-term`
//!
//! ```text
//! x_{t+1} = A x_t + B u_t + c,   A = [1 -0.2 0; 0.2 1 0; 0 0 1],
//!                                B = [1 0 0; 0 1 0; 0.4 0.4 0.4],  c = (0, 0, 0.1)
//! ℓ(x, u) = ½ 0.01 |x|² + ½ 0.01 |u|²,   ℓ_N(x) = ½ |x|²  (0 with the terminal constraint)
//! ```
//! nx = nu = 3, N = 20, x0 = (0.2, 0.3, -0.1). Variants: control bounds
//! `|u|_∞ ≤ 0.15` (`-bounds`), terminal equality `x_N = (0.1, 0.1, 0.1)` (`-term`),
//! both (`-bounds-term`, the paper's Fig. 3). Initial guess: `u = 0` and its rollout.
//! Settings: `mu_init = 1e-6` (Fig. 3), nonlinear rollout (the paper's choice for
//! explicit dynamics; on a linear system both rollouts coincide), tol `1e-6`, and with
//! the bounds the active-set prediction of the step (`active_set_iters = 10`): the
//! first step lands on the active set of the solution (`lqr-bounds` 1 iteration,
//! `lqr-bounds-term` 2; without the prediction 4 and 4).
//!
//! # `clqr`
//!
//! A random system drawn from [`SplitMix64`] with seed [`CLQR_SEED`] = 3 (standard normals by
//! Box-Muller, in this order): the lower-right 2x2 block of `A = I₄`, `B` (4x2), `x0`,
//! `M` (4x4) with `Q = Mᵀ M`, `N` (2x2) with `R = Nᵀ N`, row-major. No drift, no linear
//! terms, terminal cost `½ xᵀ (10 Q) x`, N = 100, `|u|_∞ ≤ 0.3`. Initial guess: the
//! constant state `x0` (dynamically infeasible) and `u = 0`. Settings: `mu_init = 1e-6`,
//! linear rollout.

use std::sync::Arc;

use faer::Mat;
use gharial::Result;
use gharial::constraints::{BoxConstraint, EqualityConstraintSet};
use gharial::costs::QuadraticCost;
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::functions::{ControlError, StateError, Unary};
use gharial::lq::random::SplitMix64;
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::{Manifold, VectorSpace};

use crate::{Example, rollout};

/// The variants of the paper's LQR.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LqrVariant {
    /// No constraint.
    Plain,
    /// Control bounds `|u|_∞ ≤ 0.15`.
    Bounds,
    /// Terminal equality `x_N = (0.1, 0.1, 0.1)`, no terminal cost.
    Terminal,
    /// Both (the paper's Fig. 3).
    BoundsTerminal,
}

/// Adds `lo ≤ u ≤ hi` (componentwise, all controls) to a stage.
pub(crate) fn control_box(space: &dyn Manifold, nu: usize, umax: f64, scale: f64) -> Result<StageConstraint> {
    let f = Arc::new(ControlError::new(space, &vec![0.0; nu])?);
    let set = Arc::new(BoxConstraint::new(&vec![-umax; nu], &vec![umax; nu])?);
    Ok(StageConstraint::new("u_box", f, set).with_scale(scale))
}

/// The terminal equality `x_N ⊖ target = 0`.
pub(crate) fn terminal_state(space: Arc<dyn Manifold>, target: &[f64]) -> Result<StageConstraint> {
    let f = Arc::new(Unary::new(Arc::new(StateError::new(space, target)?), 0));
    Ok(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))
}

/// The paper's 3-state LQR (module documentation).
///
/// # Errors
/// Never for these fixed numbers (model constructors are fallible in general).
pub fn paper(variant: LqrVariant) -> Result<Example> {
    let (nx, nu, n) = (3, 3, 20);
    let mut a = Mat::<f64>::identity(nx, nx);
    a[(0, 1)] = -0.2;
    a[(1, 0)] = 0.2;
    let mut b = Mat::<f64>::identity(nx, nu);
    for j in 0..nu {
        b[(2, j)] = 0.4;
    }
    let c = [0.0, 0.0, 0.1];
    let bounds = matches!(variant, LqrVariant::Bounds | LqrVariant::BoundsTerminal);
    let term = matches!(variant, LqrVariant::Terminal | LqrVariant::BoundsTerminal);
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx));
    let dynamics = Dynamics::Explicit(Arc::new(LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &c)?));
    let q = Mat::<f64>::identity(nx, nx) * 1e-2;
    let r = Mat::<f64>::identity(nu, nu) * 1e-2;
    let cost = Arc::new(QuadraticCost::new(
        q.as_ref(),
        Mat::zeros(nx, nu).as_ref(),
        r.as_ref(),
        &[0.0; 3],
        &[0.0; 3],
    )?);
    let mut stage = StageModel::new(cost, dynamics)?;
    if bounds {
        stage.add_constraint(control_box(space.as_ref(), nu, 0.15, 1.0)?)?;
    }
    let qf = if term {
        Mat::zeros(nx, nx)
    } else {
        Mat::<f64>::identity(nx, nx)
    };
    let term_cost = Arc::new(QuadraticCost::terminal(qf.as_ref(), &[0.0; 3])?);
    let mut problem = Problem::new(&[0.2, 0.3, -0.1], vec![stage; n], term_cost)?;
    if term {
        problem.add_terminal_constraint(terminal_state(space, &[0.1; 3])?)?;
    }
    let us0 = vec![vec![0.0; nu]; n];
    let xs0 = rollout(&problem, &us0)?;
    let (name, description) = match variant {
        LqrVariant::Plain => ("lqr", "The ProxDDP paper's 3-state LQR, unconstrained."),
        LqrVariant::Bounds => ("lqr-bounds", "The ProxDDP paper's 3-state LQR with |u|_inf <= 0.15."),
        LqrVariant::Terminal => (
            "lqr-term",
            "The ProxDDP paper's 3-state LQR with x_N = (0.1, 0.1, 0.1) and no terminal cost.",
        ),
        LqrVariant::BoundsTerminal => (
            "lqr-bounds-term",
            "The ProxDDP paper's 3-state LQR (Fig. 3): |u|_inf <= 0.15 and x_N = (0.1, 0.1, 0.1).",
        ),
    };
    Ok(Example {
        name,
        problem,
        xs0,
        us0,
        dt: None,
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-6;
            o.rollout = Rollout::Nonlinear;
            o.max_iters = 100;
            o.active_set_iters = if bounds { 10 } else { 0 };
        }),
        description,
    })
}

/// A standard normal draw by Box-Muller from two uniforms of `rng`.
fn normal(rng: &mut SplitMix64) -> f64 {
    let u1 = 1.0 - rng.uniform(0.0, 1.0);
    let u2 = rng.uniform(0.0, 1.0);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// `Mᵀ M` for a row-major `n x n` matrix of standard normals.
fn gram(rng: &mut SplitMix64, n: usize) -> Mat<f64> {
    let mut m = Mat::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = normal(rng);
        }
    }
    Mat::from_fn(n, n, |i, j| (0..n).map(|k| m[(k, i)] * m[(k, j)]).sum())
}

/// Seed of `clqr`.
pub const CLQR_SEED: u64 = 3;

/// The random seeded 4-state / 2-control LQR with `|u|_∞ ≤ 0.3` (module
/// documentation).
///
/// # Errors
/// Never for these fixed numbers.
pub fn clqr() -> Result<Example> {
    clqr_seeded(CLQR_SEED)
}

/// `clqr` drawn from another seed.
///
/// # Errors
/// Never (the draws are finite).
pub fn clqr_seeded(seed: u64) -> Result<Example> {
    let (nx, nu, n, umax) = (4, 2, 100, 0.3);
    let mut rng = SplitMix64::new(seed);
    let mut a = Mat::<f64>::identity(nx, nx);
    for i in 2..4 {
        for j in 2..4 {
            a[(i, j)] = normal(&mut rng);
        }
    }
    let mut b = Mat::<f64>::zeros(nx, nu);
    for i in 0..nx {
        for j in 0..nu {
            b[(i, j)] = normal(&mut rng);
        }
    }
    let x0: Vec<f64> = (0..nx).map(|_| normal(&mut rng)).collect();
    let q = gram(&mut rng, nx);
    let r = gram(&mut rng, nu);
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx));
    let dynamics = Dynamics::Explicit(Arc::new(LinearDiscreteDynamics::new(
        a.as_ref(),
        b.as_ref(),
        &[0.0; 4],
    )?));
    let cost = Arc::new(QuadraticCost::new(
        q.as_ref(),
        Mat::zeros(nx, nu).as_ref(),
        r.as_ref(),
        &[0.0; 4],
        &[0.0; 2],
    )?);
    let stage = StageModel::new(cost, dynamics)?.with_constraint(control_box(space.as_ref(), nu, umax, 1.0)?)?;
    let qf = &q * 10.0;
    let term_cost = Arc::new(QuadraticCost::terminal(qf.as_ref(), &[0.0; 4])?);
    let problem = Problem::new(&x0, vec![stage; n], term_cost)?;
    Ok(Example {
        name: "clqr",
        problem,
        xs0: vec![x0; n + 1],
        us0: vec![vec![0.0; nu]; n],
        dt: None,
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-6;
            o.rollout = Rollout::Linear;
            o.max_iters = 200;
        }),
        description: "Random seeded 4-state / 2-control LQR (SplitMix64 seed 3, Box-Muller normals), N = 100, \
                      |u|_inf <= 0.3, terminal cost 10 Q; initial guess x = x0 (infeasible), u = 0.",
    })
}
