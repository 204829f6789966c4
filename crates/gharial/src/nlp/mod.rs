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
//! by an LDLᵀ factorization without pivoting, every multiplier row eliminated before the
//! primal rows, whose pivots give the inertia: it must be `(ndx, nc, 0)` (the reduced
//! Hessian `H + δI + Cᵀ C / mu` positive definite), and the primal regularisation `δ`
//! grows until it is (inertia correction) and until the step is a descent direction of
//! the primal-dual merit function (17).
//!
//! The factorization is dense or sparse ([`ProxNlpOptions::kkt`], [`KktSolver`]). The
//! sparse one assembles the system's upper triangle in compressed columns from the
//! derivative blocks of the problem ([`NlpSparsity`]: each constraint block's Jacobian
//! on a set of columns, the Hessian as a sum of terms on sets of columns), with the
//! primal variables in the approximate-minimum-degree order of the pattern of
//! `H + Cᵀ C`, and factors it with faer's sparse LDLᵀ: the ordering, the symbolic
//! factorization and the positions of every block's entries are computed once in
//! `setup`, each iteration writes the values and runs the numeric factorization in
//! preallocated memory. Both take the same iterates (to round-off); the default
//! ([`KktSolver::Auto`]) is sparse above [`AUTO_SPARSE_DIM`] rows when the blocks fill at
//! most a tenth of the system, which is the case of every optimal control problem of
//! more than a few stages (its system is block-banded by stage), and dense otherwise.
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
//! An NLP is anything implementing [`Nlp`]; its data ([`NlpData`]) holds the derivatives
//! as dense blocks on the column sets of an [`NlpSparsity`] ([`NlpSparsity::dense`]: all
//! columns). [`NlpProblem`] assembles a (dense) NLP from the library's models, and
//! [`OcpNlp`] views an optimal control problem ([`crate::problem::Problem`]) as one NLP
//! over all its states and controls, its blocks on the states and controls of one stage,
//! so that the [`Solver`](crate::solvers::Solver) [`ProxNlpOcp`] (name `proxnlp`)
//! cross-checks ProxDDP's optimum, through the sparse KKT solve on long horizons.

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
