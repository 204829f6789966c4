//! # gharial
//!
//! Constrained trajectory optimization and model-predictive control for robots.
//!
//! The library solves optimal control problems
//! ```text
//! minimise    Σ_t ℓ_t(x_t, u_t) + ℓ_N(x_N)
//! subject to  f_t(x_t, u_t, x_{t+1}) = 0,  h_t(x_t, u_t) ∈ C_t,  h_N(x_N) ∈ C_N,
//!             x_0 = x̂ (or a general initial constraint)
//! ```
//! with states on manifolds. The pieces, in the order data flows through them:
//! - [`spaces`]: state manifolds (vector spaces, SO(2), SO(3), SE(2), SE(3), products);
//! - [`functions`], [`costs`], [`dynamics`], [`constraints`]: the modelling layer, with
//!   exact derivatives;
//! - [`autodiff`], [`check`]: above the modelling layer, the dual-number adapters that
//!   turn a model written once generic over the scalar into any model kind, and the
//!   derivative checker of every model kind;
//! - [`lq`]: the linear-quadratic subproblems every solver reduces to, and the proximal
//!   Riccati solver of the ProxDDP paper.

pub mod autodiff;
pub mod check;
pub mod constraints;
pub mod costs;
pub mod dynamics;
pub mod error;
pub mod functions;
pub mod linalg;
pub mod lq;
pub mod mpc;
pub mod nlp;
pub mod param;
pub mod problem;
pub mod solvers;
pub mod spaces;
mod team;

pub use error::{Error, Result};

/// The number of worker threads a pool asked for `requested` threads gets: at most the
/// machine's available parallelism. More threads than cores only add scheduling and
/// wake-up costs to the short stage-wise tasks (1000 threads on 2 cores made a solve
/// 200 times slower), and stage-wise results do not depend on the thread count.
pub fn pool_threads(requested: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    requested.clamp(1, cores.max(1))
}
