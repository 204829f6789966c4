//! ProxNLP: the primal-dual augmented-Lagrangian method of the ProxDDP paper (Jallet et
//! al. 2023, `../shared/papers/proxddp-jallet-2023.md`, section III) for a generic
//! nonlinear program on a manifold,
//!
//! ```text
//! min f(x)   s.t.   c_k(x) ∈ C_k,  k = 1..K,   x ∈ M,
//! ```
//!
//! with each `C_k` a closed convex set of [`crate::constraints`] (equality, orthant, box,
//! second-order cone, products, ...) and Lagrangian `f + Σ_k ν_kᵀ c_k`.
//!
//! # Algorithm
//!
//! The outer loop is the bound-constrained-Lagrangian schedule of Algorithm 2, as in
//! [`crate::solvers::proxddp`]: inner semi-smooth Newton steps on the proximal subproblem
//! of the current outer multipliers `ν_e` and penalty `mu` run until the inner criterion
//! (19) is below `omega`; then the multipliers are accepted (primal residual (53) below
//! `eta`) or `mu` shrinks, and the tolerances follow. Each Newton step solves the
//! primal-dual system (13)-(14), generalised from the orthant to any set through the
//! normal-cone projection `N(z) = z - proj_C(z)` (the multiplier estimate (39) is
//! `ν⁺ = N(c + mu ν_e) / mu`, its Jacobian `J_N` selects the active rows (12)):
//!
//! ```text
//! [ H + δ I    (J_N J)ᵀ ] [δx]     [ ∇f + Jᵀ (ν⁺ - J_N (ν⁺ - ν)) ]
//! [ J_N J      -mu I    ] [δν] = - [ mu (ν⁺ - ν)                 ]
//! ```
//!
//! densely, by an LDLᵀ factorization with the multiplier rows first, whose pivots give the
//! inertia: it must be `(ndx, nc, 0)` (the reduced Hessian `H + δI + Cᵀ C / mu` positive
//! definite), and the primal regularisation `δ` grows until it is (inertia correction)
//! and until the step is a descent direction of the primal-dual merit function (17).
//! One step of iterative refinement follows. Where `J_N` is not a projector (a cone's
//! boundary) the block's rows are `√J_N J` with the multiplier step recovered from the
//! linearised estimate, which keeps the step the exact semi-smooth Newton step there.
//! The step `x ⊕ α δx`, `ν + α δν` (15)-(16) is accepted by ProxDDP's filter on
//! (merit, infeasibility) or by Armijo backtracking (18), monotone or nonmonotone.
//! `H` is the cost Hessian (Gauss-Newton) or the Lagrangian Hessian at `ν⁺`
//! ([`HessianApprox::Exact`](crate::solvers::HessianApprox::Exact)).
//!
//! The solver stops with [`Status::Converged`](crate::solvers::Status::Converged) when
//! the primal residual (53), the dual residual (52) `|∇f + Jᵀν|_∞` and the
//! complementarity `|c - proj_C(c + ν)|_∞` are below `tol`, and with
//! [`Status::Infeasible`](crate::solvers::Status::Infeasible) when the subproblem at the
//! smallest penalty is solved repeatedly with a primal residual above its target.
//!
//! # Problems
//!
//! An NLP is anything implementing [`Nlp`]; [`NlpProblem`] assembles one from the
//! library's models, and [`OcpNlp`] views an optimal control problem
//! ([`crate::problem::Problem`]) as one NLP over all its states and controls, so that the
//! [`Solver`](crate::solvers::Solver) [`ProxNlpOcp`] (name `proxnlp`) cross-checks
//! ProxDDP's optimum on small problems.

mod kkt;
mod ocp;
mod options;
mod problem;
mod solver;
mod workspace;

pub use kkt::{AUTO_SPARSE_DIM, KktStats, MAX_KKT_DIM};
pub use ocp::{OcpLayout, OcpNlp, ProxNlpOcp};
pub use options::{KktSolver, ProxNlpOptions};
pub use problem::{Columns, ConstraintBlock, Nlp, NlpConstraint, NlpData, NlpProblem, NlpSparsity, num_rows};
pub use solver::{NlpSolution, ProxNlp};
