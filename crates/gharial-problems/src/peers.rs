//! The LQR family of the peer benchmark harness (`shared/peers/README.md`, "LQR
//! family"): `peers-lqr`, `peers-lqr-box`, `peers-lqr-box-term`, built from the same
//! random numbers as the C++ and Python references so that every library solves the
//! identical problem.
//!
//! Random numbers: [`SplitMix64`] with the given seed, `U(a, b) = a + (b - a) u`, one
//! stream drawn in this order:
//! 1. `A` row-major: `A_ij = (i == j ? 0.95 : 0) + 0.05 w`, `w ~ U(-1, 1)`;
//! 2. `B` row-major: `B_ij ~ U(-1, 1)`;
//! 3. `q_i ~ U(0.5, 1.5)`, `Q = diag(q)`;
//! 4. `r_i ~ U(0.05, 0.15)`, `R = diag(r)`;
//! 5. `x0_i ~ U(-1, 1)`.
//!
//! ```text
//! x_{t+1} = A x_t + B u_t,   ℓ(x, u) = ½ xᵀ Q x + ½ uᵀ R u,   ℓ_N(x) = ½ xᵀ (10 Q) x
//! ```
//! Defaults (the harness's `LQR_NX, LQR_NU, LQR_N, LQR_SEED, LQR_UMAX`): nx = 8, nu = 4,
//! N = 100, seed 42, umax = 0.05. `-box` adds `|u|_∞ ≤ umax`, `-box-term` also
//! `x_N = 0`. Initial guess: `u = 0` and its rollout `x_t = A^t x0`.
//!
//! Reference values (harness README): initial cost `130.19638139597174` (reproduced bit
//! for bit here), optimal costs `lqr` 6.24858177722514, `lqr_box` 6.9221159366,
//! `lqr_box_term` 6.9224174917.
//!
//! Settings: those of the harness for aligator (`mu_init = 1e-5`, linear rollout). At
//! tol `1e-6` the optimal costs below are within 2e-6 (relative) of the references, the
//! accuracy that primal residuals of ~1e-7 allow; at tol `1e-10` they agree to 1e-9
//! (`tests/peers.rs`).

use std::sync::Arc;

use faer::Mat;
use gharial::Result;
use gharial::costs::QuadraticCost;
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::lq::random::SplitMix64;
use gharial::problem::{Problem, StageModel};
use gharial::solvers::proxddp::{ProxDdpOptions, Rollout};
use gharial::spaces::{Manifold, VectorSpace};

use crate::lqr::{control_box, terminal_state};
use crate::{Example, rollout};

/// The harness's knobs (`LQR_NX`, `LQR_NU`, `LQR_N`, `LQR_SEED`, `LQR_UMAX`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeersLqrParams {
    /// State size (default 8).
    pub nx: usize,
    /// Control size (default 4).
    pub nu: usize,
    /// Horizon (default 100).
    pub horizon: usize,
    /// Seed of the SplitMix64 stream (default 42).
    pub seed: u64,
    /// Control bound of the box variants (default 0.05).
    pub umax: f64,
}

impl Default for PeersLqrParams {
    fn default() -> Self {
        Self {
            nx: 8,
            nu: 4,
            horizon: 100,
            seed: 42,
            umax: 0.05,
        }
    }
}

/// The three problems of the family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PeersVariant {
    /// `lqr`: no constraint.
    Lqr,
    /// `lqr_box`: `|u|_∞ ≤ umax`.
    Box,
    /// `lqr_box_term`: the box and `x_N = 0`.
    BoxTerminal,
}

/// The numbers of one instance of the family.
#[derive(Debug, Clone)]
pub struct PeersLqrData {
    /// `A` (`nx x nx`).
    pub a: Mat<f64>,
    /// `B` (`nx x nu`).
    pub b: Mat<f64>,
    /// Diagonal of `Q`.
    pub q: Vec<f64>,
    /// Diagonal of `R`.
    pub r: Vec<f64>,
    /// Initial state.
    pub x0: Vec<f64>,
}

/// Draws the numbers of the instance `params` in the harness's order.
pub fn data(params: &PeersLqrParams) -> PeersLqrData {
    let (nx, nu) = (params.nx, params.nu);
    let mut rng = SplitMix64::new(params.seed);
    let mut a = Mat::<f64>::zeros(nx, nx);
    for i in 0..nx {
        for j in 0..nx {
            let w = rng.uniform(-1.0, 1.0);
            a[(i, j)] = if i == j { 0.95 } else { 0.0 } + 0.05 * w;
        }
    }
    let mut b = Mat::<f64>::zeros(nx, nu);
    for i in 0..nx {
        for j in 0..nu {
            b[(i, j)] = rng.uniform(-1.0, 1.0);
        }
    }
    let q = (0..nx).map(|_| rng.uniform(0.5, 1.5)).collect();
    let r = (0..nu).map(|_| rng.uniform(0.05, 0.15)).collect();
    let x0 = (0..nx).map(|_| rng.uniform(-1.0, 1.0)).collect();
    PeersLqrData { a, b, q, r, x0 }
}

/// Builds the instance `params` of the family in its `variant`.
///
/// # Errors
/// If a size is zero or `umax` is not positive and finite.
pub fn build(params: &PeersLqrParams, variant: PeersVariant) -> Result<Example> {
    let (nx, nu, n) = (params.nx, params.nu, params.horizon);
    if nx == 0 || nu == 0 || n == 0 {
        return Err(gharial::Error::InvalidModel(format!(
            "peers LQR: nx, nu and N must be positive, got {nx}, {nu}, {n}"
        )));
    }
    if !(params.umax.is_finite() && params.umax > 0.0) {
        return Err(gharial::Error::InvalidModel(format!(
            "peers LQR: umax must be positive and finite, got {}",
            gharial::error::Num(params.umax)
        )));
    }
    let d = data(params);
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx));
    let dynamics = Dynamics::Explicit(Arc::new(LinearDiscreteDynamics::new(
        d.a.as_ref(),
        d.b.as_ref(),
        &vec![0.0; nx],
    )?));
    let qm = Mat::from_fn(nx, nx, |i, j| if i == j { d.q[i] } else { 0.0 });
    let rm = Mat::from_fn(nu, nu, |i, j| if i == j { d.r[i] } else { 0.0 });
    let cost = Arc::new(QuadraticCost::new(
        qm.as_ref(),
        Mat::zeros(nx, nu).as_ref(),
        rm.as_ref(),
        &vec![0.0; nx],
        &vec![0.0; nu],
    )?);
    let mut stage = StageModel::new(cost, dynamics)?;
    if variant != PeersVariant::Lqr {
        stage.add_constraint(control_box(space.as_ref(), nu, params.umax, 1.0)?)?;
    }
    let qf = Mat::from_fn(nx, nx, |i, j| if i == j { 10.0 * d.q[i] } else { 0.0 });
    let term_cost = Arc::new(QuadraticCost::terminal(qf.as_ref(), &vec![0.0; nx])?);
    let mut problem = Problem::new(&d.x0, vec![stage; n], term_cost)?;
    if variant == PeersVariant::BoxTerminal {
        problem.add_terminal_constraint(terminal_state(space, &vec![0.0; nx])?)?;
    }
    let us0 = vec![vec![0.0; nu]; n];
    let xs0 = rollout(&problem, &us0)?;
    let (name, description) = match variant {
        PeersVariant::Lqr => (
            "peers-lqr",
            "Peer-harness LQR family (SplitMix64), unconstrained; reference optimal cost 6.24858177722514.",
        ),
        PeersVariant::Box => (
            "peers-lqr-box",
            "Peer-harness LQR family with |u|_inf <= umax; reference optimal cost 6.9221159366.",
        ),
        PeersVariant::BoxTerminal => (
            "peers-lqr-box-term",
            "Peer-harness LQR family with |u|_inf <= umax and x_N = 0; reference optimal cost 6.9224174917.",
        ),
    };
    Ok(Example {
        name,
        problem,
        xs0,
        us0,
        dt: None,
        proxddp: ProxDdpOptions::default().with(|o| {
            o.mu_init = 1e-5;
            o.rollout = Rollout::Linear;
            o.max_iters = 500;
        }),
        description,
    })
}
