//! Linear-quadratic (LQ) subproblems and their solvers.
//!
//! # The problem
//!
//! An [`LqProblem`] is a chain of knots `t = 0..=N`; knot `t` holds
//! ```text
//! cost         ½ [x; u]ᵀ [Q S; Sᵀ R] [x; u] + qᵀ x + rᵀ u
//! dynamics     A x_t + B u_t + E x_{t+1} + f - mu_dyn λ_{t+1} = 0      (t < N)
//! constraints  C x_t + D u_t + d - diag(mu_c) ν_t = 0
//! ```
//! and the problem an initial constraint `G0 x_0 + g0 - mu0 λ_0 = 0` (possibly with no
//! rows: then `x_0` is free). The last knot has no dynamics (`nx_next = 0`); dimensions
//! may change from knot to knot. The `mu` terms are the proximal (dual) regularisation of
//! the ProxDDP subproblem; with `mu_dyn = 0`, `E = -I` and no constraints this is the
//! classical LQR of DDP, FDDP and SQP. The Lagrangian is
//! ```text
//! Σ_t cost_t + λ_0ᵀ(G0 x_0 + g0) + Σ_t λ_{t+1}ᵀ(A x + B u + E x' + f) + ν_tᵀ(C x + D u + d)
//!   - ½ mu0 |λ_0|² - ½ Σ mu_dyn |λ_{t+1}|² - ½ Σ ν_tᵀ diag(mu_c) ν_t
//! ```
//! and its stationary point (the solution of the KKT system assembled by [`dense`]) is
//! what every solver of this module returns, as an [`LqSolution`].
//!
//! # The proximal Riccati recursion ([`RiccatiSolver`])
//!
//! The backward pass eliminates, knot by knot from `N` down to `0`, the variables
//! `(u_t, ν_t, x_{t+1}, λ_{t+1})` of the stage KKT system (43) of the ProxDDP paper,
//! leaving a quadratic value function `V_t(x) = ½ xᵀ P_t x + p_tᵀ x` (`P = V_xx`,
//! `p = V_x`). With `P' = P_{t+1}`, `p' = p_{t+1}`:
//!
//! 1. *Dynamics in explicit form.* `x_{t+1} = Ã x + B̃ u + f̃ - G λ̃` with
//!    `Ã = -E⁻¹A`, `B̃ = -E⁻¹B`, `f̃ = -E⁻¹f`, `G = mu_dyn E⁻¹E⁻ᵀ` and `λ̃ = -Eᵀλ_{t+1}`
//!    (for `E = -I`: `Ã = A`, `B̃ = B`, `f̃ = f`, `G = mu_dyn I`, `λ̃ = λ_{t+1}`; no
//!    solve with `E` is made).
//! 2. *Proximal value.* Eliminating `x_{t+1}` and `λ̃` from `P' x_{t+1} + p' = λ̃` gives
//!    `λ̃ = P̃ z + p̃` for `z = Ã x + B̃ u + f̃`, with `P̃ = (I + P'G)⁻¹P'` (symmetric) and
//!    `p̃ = (I + P'G)⁻¹p'`; with `mu_dyn = 0`, `P̃ = P'` and `p̃ = p'`. This is the
//!    dynamics block of (43)-(44) solved exactly, without dividing by `mu_dyn`.
//! 3. *Q-function* (37): `Q_xx = Q + ÃᵀP̃Ã`, `Q_xu = S + ÃᵀP̃B̃`, `Q_uu = R + B̃ᵀP̃B̃`,
//!    `Q_x = q + Ãᵀ(P̃f̃ + p̃)`, `Q_u = r + B̃ᵀ(P̃f̃ + p̃)`.
//! 4. *Stage KKT* (45)-(46), not condensed (no division by `mu_c`): with the primal
//!    regularisation `ρ`,
//!    ```text
//!    [Q_uu + ρI   Dᵀ         ] [k  K]     [Q_u  Q_ux]
//!    [D          -diag(mu_c) ] [ζ  Z] = - [d    C   ]
//!    ```
//!    factored by LDLᵀ (Bunch-Kaufman if some `mu_c` is 0); its inertia must be
//!    `(nu, nc, 0)`, otherwise [`LqError::Inertia`] asks the caller for a larger `ρ`.
//! 5. *Value* (47): `P = Q_xx + [Q_xu Cᵀ][K; Z]`, `p = Q_x + [Q_xu Cᵀ][k; ζ]`.
//!
//! The initial stage (49)/(65) solves `[[P_0, G0ᵀ], [G0, -mu0 I]] [x_0; λ_0] = -[p_0; g0]`
//! with Bunch-Kaufman. The forward pass (50) then reads, for `t = 0..N-1`,
//! `u = k + K x`, `ν = ζ + Z x`, `z = Ã x + B̃ u + f̃`, `λ̃ = P̃ z + p̃`,
//! `x_{t+1} = z - G λ̃`, `λ_{t+1} = -E⁻ᵀ λ̃`. The optional rollout gains of (44)/(50),
//! `x_{t+1} = c + C x_t` and `λ_{t+1} = ξ + Ξ x_t`, are `C = (I - GP̃)(Ã + B̃K)`,
//! `c = (I - GP̃)(B̃k + f̃) - Gp̃`, `Ξ = -E⁻ᵀP̃(Ã + B̃K)`, `ξ = -E⁻ᵀ(P̃(B̃k + f̃) + p̃)`.
//!
//! Everything that depends only on `Q, S, R, A, B, E, C, D` and the `mu`s (factorizations,
//! feedback gains, `P`) is the *matrix part* of the backward pass; the rest (`k`, `ζ`, `p`,
//! the feedforward terms) the *vector part*, which [`RiccatiSolver::backward_vectors`]
//! redoes alone when only `q, r, f, d, g0` changed (the ADMM iterations of CSQP).
//!
//! The per-knot pieces live in [`RiccatiStage`]: the Q-function (`Q_xx`, `Q_xu`, `Q_uu`,
//! `Q_x`, `Q_u`, as FDDP's expected decrease needs), the gains, the value function, the
//! stage KKT solve and a value update from arbitrary gains
//! ([`RiccatiStage::value_from_gains`]: `P = Q_xx + KᵀQ_uu K + Q_xu K + KᵀQ_ux`,
//! `p = Q_x + KᵀQ_uu k + Q_xu k + KᵀQ_u`), so that solvers with their own control law
//! (box-DDP's projected Newton step) reuse the same sweep through
//! [`RiccatiSolver::backward_with`].
//!
//! # Accuracy
//!
//! With small regularisations the value function grows like `1/mu` in the directions the
//! constraints pin down, and the recursion computes the co-states `P x + p` and the
//! multipliers `ζ + Z x` with errors of about `ε/mu` relative (`ε` the machine epsilon):
//! about `1e-6` at `mu = 1e-10`. Every Riccati-based proximal solver shares this
//! (aligator's `gar` reports KKT dual residuals of `≈ 5e-15/mu`). Iterative refinement
//! ([`RiccatiOptions::refinement_steps`]) removes it: each step computes the KKT
//! residual ([`LqVectors::set_kkt_residual`]) and solves for the correction with the
//! factorizations already computed (one vector pass and one rollout). One or two steps give
//! KKT residuals of about `ε` (the dense LU solve's) down to `mu = 1e-10`. When the
//! constraint rows of the whole problem are linearly dependent (more rows than controls,
//! rows on the last state, rank-deficient blocks), the multipliers are themselves
//! ill-conditioned (the KKT matrix has singular values of the order of `mu`): no
//! algorithm determines them better than `ε/mu`; refinement still gives residuals of `ε`.
//!
//! # Other solvers
//!
//! - The square-root pass of ALTRO ([`RiccatiSolver::with_square_root`],
//!   [`RiccatiSolver::backward_square_root`]): the same recursion on Cholesky factors of
//!   the value Hessians, propagated by QR, for knots with `E = -I`, `mu_dyn = 0` and
//!   constraint rows as penalties (`mu_c > 0`); robust where the penalties make `P`
//!   ill-conditioned (module `sqrt`).
//! - [`ParallelRiccatiSolver`]: the horizon split into legs solved on threads, each leg
//!   parameterised by its boundary co-state, then a condensed system over the legs'
//!   boundaries; the same solution as the serial solver.
//! - [`LqSolver`]: the interface the nonlinear solvers use, serial or parallel by the
//!   number of threads.
//! - [`dense`]: the KKT system assembled densely and solved by LU, the reference of the
//!   tests, and the KKT residuals of any solution.
//! - [`random`]: random problems (the generator of the peer benchmarks, and a more varied
//!   one for tests).
#![allow(non_snake_case)]

use faer::{Col, Mat, MatRef};

use crate::linalg::{self, Inertia};

pub mod dense;
mod e_factor;
pub(crate) mod offsets;
mod parallel;
pub mod random;
mod riccati;
mod solver;
mod sqrt;
mod stage;

pub use parallel::ParallelRiccatiSolver;
pub(crate) use riccati::Outputs;
pub use riccati::{RiccatiOptions, RiccatiSolver};
pub use solver::LqSolver;
pub use stage::RiccatiStage;

/// One knot of an LQ problem. Matrix names follow the ProxDDP paper and the LQ literature.
#[derive(Debug, Clone)]
pub struct LqKnot {
    /// State (tangent) dimension at this knot.
    pub nx: usize,
    /// Control dimension (0 at the last knot).
    pub nu: usize,
    /// Number of constraint rows.
    pub nc: usize,
    /// State dimension of the next knot (0 at the last knot).
    pub nx_next: usize,
    /// Cost Hessian block `Q` (`nx x nx`).
    pub Q: Mat<f64>,
    /// Cost cross term `S` (`nx x nu`).
    pub S: Mat<f64>,
    /// Cost Hessian block `R` (`nu x nu`).
    pub R: Mat<f64>,
    /// Cost gradient `q` (`nx`).
    pub q: Col<f64>,
    /// Cost gradient `r` (`nu`).
    pub r: Col<f64>,
    /// Dynamics `A` (`nx_next x nx`).
    pub A: Mat<f64>,
    /// Dynamics `B` (`nx_next x nu`).
    pub B: Mat<f64>,
    /// Dynamics `E` (`nx_next x nx_next`), `-I` for explicit dynamics on vector spaces.
    pub E: Mat<f64>,
    /// Dynamics offset `f` (`nx_next`): the gap (defect) of the linearised dynamics.
    pub f: Col<f64>,
    /// Constraint Jacobian `C` (`nc x nx`).
    pub C: Mat<f64>,
    /// Constraint Jacobian `D` (`nc x nu`).
    pub D: Mat<f64>,
    /// Constraint offset `d` (`nc`).
    pub d: Col<f64>,
    /// Dual regularisation of the dynamics rows (`mu_dyn ≥ 0`).
    pub mu_dyn: f64,
    /// Dual regularisation of each constraint row (`mu_c ≥ 0`, `nc`).
    pub mu_c: Col<f64>,
}

impl LqKnot {
    /// A zero knot of the given dimensions with `E = -I`, `mu_dyn = 0` and `mu_c = 0`.
    pub fn new(nx: usize, nu: usize, nc: usize, nx_next: usize) -> Self {
        let mut E = Mat::zeros(nx_next, nx_next);
        for i in 0..nx_next {
            E[(i, i)] = -1.0;
        }
        Self {
            nx,
            nu,
            nc,
            nx_next,
            Q: Mat::zeros(nx, nx),
            S: Mat::zeros(nx, nu),
            R: Mat::zeros(nu, nu),
            q: Col::zeros(nx),
            r: Col::zeros(nu),
            A: Mat::zeros(nx_next, nx),
            B: Mat::zeros(nx_next, nu),
            E,
            f: Col::zeros(nx_next),
            C: Mat::zeros(nc, nx),
            D: Mat::zeros(nc, nu),
            d: Col::zeros(nc),
            mu_dyn: 0.0,
            mu_c: Col::zeros(nc),
        }
    }

    /// Checks that every field has the shape the knot's dimensions announce.
    pub fn check_shapes(&self, knot: usize) -> Result<(), LqError> {
        let (nx, nu, nc, ny) = (self.nx, self.nu, self.nc, self.nx_next);
        let dims = |m: &Mat<f64>, rows: usize, cols: usize| m.nrows() == rows && m.ncols() == cols;
        // The common case in one pass of comparisons (this runs at every Riccati solve);
        // the named error is built only when a shape is wrong.
        if dims(&self.Q, nx, nx)
            && dims(&self.S, nx, nu)
            && dims(&self.R, nu, nu)
            && dims(&self.A, ny, nx)
            && dims(&self.B, ny, nu)
            && dims(&self.E, ny, ny)
            && dims(&self.C, nc, nx)
            && dims(&self.D, nc, nu)
            && self.q.nrows() == nx
            && self.r.nrows() == nu
            && self.f.nrows() == ny
            && self.d.nrows() == nc
            && self.mu_c.nrows() == nc
        {
            return Ok(());
        }
        let mats: [(&'static str, &Mat<f64>, usize, usize); 8] = [
            ("Q", &self.Q, nx, nx),
            ("S", &self.S, nx, nu),
            ("R", &self.R, nu, nu),
            ("A", &self.A, ny, nx),
            ("B", &self.B, ny, nu),
            ("E", &self.E, ny, ny),
            ("C", &self.C, nc, nx),
            ("D", &self.D, nc, nu),
        ];
        for (field, m, rows, cols) in mats {
            if (m.nrows(), m.ncols()) != (rows, cols) {
                return Err(LqError::Dimension {
                    knot,
                    field,
                    expected: (rows, cols),
                    got: (m.nrows(), m.ncols()),
                });
            }
        }
        let cols: [(&'static str, &Col<f64>, usize); 5] = [
            ("q", &self.q, nx),
            ("r", &self.r, nu),
            ("f", &self.f, ny),
            ("d", &self.d, nc),
            ("mu_c", &self.mu_c, nc),
        ];
        for (field, c, rows) in cols {
            if c.nrows() != rows {
                return Err(LqError::Dimension {
                    knot,
                    field,
                    expected: (rows, 1),
                    got: (c.nrows(), 1),
                });
            }
        }
        Ok(())
    }

    /// Finds the first field holding a NaN or an infinity, or a negative regularisation.
    pub fn check_values(&self, knot: usize) -> Result<(), LqError> {
        let mats: [(&'static str, &Mat<f64>); 8] = [
            ("Q", &self.Q),
            ("S", &self.S),
            ("R", &self.R),
            ("A", &self.A),
            ("B", &self.B),
            ("E", &self.E),
            ("C", &self.C),
            ("D", &self.D),
        ];
        for (field, m) in mats {
            if !linalg::all_finite(m.as_ref()) {
                return Err(LqError::NonFinite { knot, field });
            }
        }
        let cols: [(&'static str, &Col<f64>); 5] = [
            ("q", &self.q),
            ("r", &self.r),
            ("f", &self.f),
            ("d", &self.d),
            ("mu_c", &self.mu_c),
        ];
        for (field, c) in cols {
            if !linalg::all_finite(c.as_mat()) {
                return Err(LqError::NonFinite { knot, field });
            }
        }
        if !self.mu_dyn.is_finite() {
            return Err(LqError::NonFinite { knot, field: "mu_dyn" });
        }
        if self.mu_dyn < 0.0 {
            return Err(LqError::Negative { knot, field: "mu_dyn" });
        }
        if (0..self.nc).any(|i| self.mu_c[i] < 0.0) {
            return Err(LqError::Negative { knot, field: "mu_c" });
        }
        Ok(())
    }
}

/// A chain of LQ knots with an initial constraint.
#[derive(Debug, Clone)]
pub struct LqProblem {
    /// Knots `0..=N`; the last one has `nx_next = 0`.
    pub knots: Vec<LqKnot>,
    /// Initial constraint matrix `G0` (`nc0 x nx_0`).
    pub G0: Mat<f64>,
    /// Initial constraint offset `g0` (`nc0`).
    pub g0: Col<f64>,
    /// Dual regularisation of the initial constraint (`mu0 ≥ 0`).
    pub mu0: f64,
}

impl LqProblem {
    /// Horizon `N` (number of knots minus one).
    pub fn horizon(&self) -> usize {
        self.knots.len().saturating_sub(1)
    }

    /// Number of rows of the initial constraint.
    pub fn nc0(&self) -> usize {
        self.G0.nrows()
    }

    /// Checks the shapes of every field and the chaining of the knots' dimensions
    /// (`nx_next` of knot `t` equals `nx` of knot `t + 1`, the last knot has no dynamics).
    pub fn check_shapes(&self) -> Result<(), LqError> {
        let n = self.knots.len();
        if n == 0 {
            return Err(LqError::Empty);
        }
        for (t, k) in self.knots.iter().enumerate() {
            k.check_shapes(t)?;
            let ny = if t + 1 < n { self.knots[t + 1].nx } else { 0 };
            if k.nx_next != ny {
                return Err(LqError::Dimension {
                    knot: t,
                    field: "nx_next",
                    expected: (ny, 1),
                    got: (k.nx_next, 1),
                });
            }
        }
        let nx0 = self.knots[0].nx;
        if self.G0.ncols() != nx0 {
            return Err(LqError::Dimension {
                knot: 0,
                field: "G0",
                expected: (self.G0.nrows(), nx0),
                got: (self.G0.nrows(), self.G0.ncols()),
            });
        }
        if self.g0.nrows() != self.G0.nrows() {
            return Err(LqError::Dimension {
                knot: 0,
                field: "g0",
                expected: (self.G0.nrows(), 1),
                got: (self.g0.nrows(), 1),
            });
        }
        Ok(())
    }

    /// Finds a non-finite value or a negative regularisation in the initial constraint.
    pub fn check_initial_values(&self) -> Result<(), LqError> {
        if !linalg::all_finite(self.G0.as_ref()) {
            return Err(LqError::NonFinite { knot: 0, field: "G0" });
        }
        if !linalg::all_finite(self.g0.as_mat()) {
            return Err(LqError::NonFinite { knot: 0, field: "g0" });
        }
        if !self.mu0.is_finite() {
            return Err(LqError::NonFinite { knot: 0, field: "mu0" });
        }
        if self.mu0 < 0.0 {
            return Err(LqError::Negative { knot: 0, field: "mu0" });
        }
        Ok(())
    }

    /// Finds the first non-finite value or negative regularisation of the problem.
    pub fn check_values(&self) -> Result<(), LqError> {
        self.check_initial_values()?;
        for (t, k) in self.knots.iter().enumerate() {
            k.check_values(t)?;
        }
        Ok(())
    }

    /// [`check_shapes`](Self::check_shapes) then [`check_values`](Self::check_values).
    pub fn validate(&self) -> Result<(), LqError> {
        self.check_shapes()?;
        self.check_values()
    }

    /// The dimensions `(nx, nu, nc, nx_next)` of every knot.
    pub fn dims(&self) -> Vec<KnotDims> {
        self.knots
            .iter()
            .map(|k| KnotDims {
                nx: k.nx,
                nu: k.nu,
                nc: k.nc,
                nx_next: k.nx_next,
            })
            .collect()
    }
}

/// Dimensions of one knot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KnotDims {
    /// State dimension.
    pub nx: usize,
    /// Control dimension.
    pub nu: usize,
    /// Number of constraint rows.
    pub nc: usize,
    /// State dimension of the next knot (0 at the last knot).
    pub nx_next: usize,
}

/// Checks that every regularisation parameter is finite and nonnegative (cheap: the
/// solvers call it at every backward pass; the matrices are checked through their results).
pub(crate) fn check_regularisation(problem: &LqProblem) -> Result<(), LqError> {
    let check = |knot: usize, field: &'static str, v: f64| {
        if !v.is_finite() {
            Err(LqError::NonFinite { knot, field })
        } else if v < 0.0 {
            Err(LqError::Negative { knot, field })
        } else {
            Ok(())
        }
    };
    check(0, "mu0", problem.mu0)?;
    for (t, k) in problem.knots.iter().enumerate() {
        check(t, "mu_dyn", k.mu_dyn)?;
        for i in 0..k.nc {
            check(t, "mu_c", k.mu_c[i])?;
        }
    }
    Ok(())
}

/// Checks that a problem has the dimensions a solver was built for.
pub(crate) fn check_same_dims(problem: &LqProblem, dims: &[KnotDims], nc0: usize) -> Result<(), LqError> {
    if problem.knots.len() != dims.len() {
        return Err(LqError::Dimension {
            knot: problem.knots.len().min(dims.len()),
            field: "number of knots",
            expected: (dims.len(), 1),
            got: (problem.knots.len(), 1),
        });
    }
    problem.check_shapes()?;
    for (t, (k, d)) in problem.knots.iter().zip(dims).enumerate() {
        let got = [k.nx, k.nu, k.nc, k.nx_next];
        let expected = [d.nx, d.nu, d.nc, d.nx_next];
        let names = ["nx", "nu", "nc", "nx_next"];
        for i in 0..4 {
            if got[i] != expected[i] {
                return Err(LqError::Dimension {
                    knot: t,
                    field: names[i],
                    expected: (expected[i], 1),
                    got: (got[i], 1),
                });
            }
        }
    }
    if problem.nc0() != nc0 {
        return Err(LqError::Dimension {
            knot: 0,
            field: "G0 rows",
            expected: (nc0, 1),
            got: (problem.nc0(), 1),
        });
    }
    Ok(())
}

/// The primal-dual solution of an LQ problem, allocated once for a problem's dimensions.
#[derive(Debug, Clone)]
pub struct LqSolution {
    /// States `x_t`, one per knot (`nx_t`).
    pub xs: Vec<Col<f64>>,
    /// Controls `u_t`, one per knot (`nu_t`; empty at a knot without control).
    pub us: Vec<Col<f64>>,
    /// Co-states: `λ_0` of the initial constraint (`nc0`), then `λ_{t+1}` of the
    /// dynamics of knot `t` (`nx_{t+1}`), `N + 1` vectors in all.
    pub lambdas: Vec<Col<f64>>,
    /// Constraint multipliers `ν_t`, one per knot (`nc_t`).
    pub nus: Vec<Col<f64>>,
}

impl LqSolution {
    /// A zero solution with the dimensions of `problem`.
    pub fn new(problem: &LqProblem) -> Self {
        let ks = &problem.knots;
        let mut lambdas = Vec::with_capacity(ks.len());
        lambdas.push(Col::zeros(problem.nc0()));
        lambdas.extend(
            ks.iter()
                .take(ks.len().saturating_sub(1))
                .map(|k| Col::zeros(k.nx_next)),
        );
        Self {
            xs: ks.iter().map(|k| Col::zeros(k.nx)).collect(),
            us: ks.iter().map(|k| Col::zeros(k.nu)).collect(),
            lambdas,
            nus: ks.iter().map(|k| Col::zeros(k.nc)).collect(),
        }
    }

    /// Checks that the solution has the dimensions of `problem`.
    pub fn check_dims(&self, problem: &LqProblem) -> Result<(), LqError> {
        let n = problem.knots.len();
        let lens = [
            ("solution xs", self.xs.len()),
            ("solution us", self.us.len()),
            ("solution lambdas", self.lambdas.len()),
            ("solution nus", self.nus.len()),
        ];
        for (field, len) in lens {
            if len != n {
                return Err(LqError::Dimension {
                    knot: 0,
                    field,
                    expected: (n, 1),
                    got: (len, 1),
                });
            }
        }
        let check = |knot: usize, field: &'static str, c: &Col<f64>, rows: usize| {
            if c.nrows() == rows {
                Ok(())
            } else {
                Err(LqError::Dimension {
                    knot,
                    field,
                    expected: (rows, 1),
                    got: (c.nrows(), 1),
                })
            }
        };
        check(0, "solution lambdas[0]", &self.lambdas[0], problem.nc0())?;
        for (t, k) in problem.knots.iter().enumerate() {
            check(t, "solution xs", &self.xs[t], k.nx)?;
            check(t, "solution us", &self.us[t], k.nu)?;
            check(t, "solution nus", &self.nus[t], k.nc)?;
            if t + 1 < n {
                check(t, "solution lambdas", &self.lambdas[t + 1], k.nx_next)?;
            }
        }
        Ok(())
    }
}

/// The vector data `q, r, f, d` of one knot, borrowed.
#[derive(Debug, Clone, Copy)]
pub struct KnotVectors<'a> {
    /// Cost gradient in `x`.
    pub q: &'a [f64],
    /// Cost gradient in `u`.
    pub r: &'a [f64],
    /// Dynamics offset.
    pub f: &'a [f64],
    /// Constraint offset.
    pub d: &'a [f64],
}

impl<'a> KnotVectors<'a> {
    /// The vectors of `knot`.
    pub fn of(knot: &'a LqKnot) -> Self {
        Self {
            q: linalg::slice(&knot.q),
            r: linalg::slice(&knot.r),
            f: linalg::slice(&knot.f),
            d: linalg::slice(&knot.d),
        }
    }
}

/// The vector data of a whole problem (`q, r, f, d` per knot and `g0`): the right-hand
/// side of the KKT system, or a KKT residual.
#[derive(Debug, Clone)]
pub struct LqVectors {
    /// `q_t`.
    pub q: Vec<Col<f64>>,
    /// `r_t`.
    pub r: Vec<Col<f64>>,
    /// `f_t` (empty at the last knot).
    pub f: Vec<Col<f64>>,
    /// `d_t`.
    pub d: Vec<Col<f64>>,
    /// `g0`.
    pub g0: Col<f64>,
}

impl LqVectors {
    /// Zero vectors with the dimensions of `problem`.
    pub fn new(problem: &LqProblem) -> Self {
        let ks = &problem.knots;
        Self {
            q: ks.iter().map(|k| Col::zeros(k.nx)).collect(),
            r: ks.iter().map(|k| Col::zeros(k.nu)).collect(),
            f: ks.iter().map(|k| Col::zeros(k.nx_next)).collect(),
            d: ks.iter().map(|k| Col::zeros(k.nc)).collect(),
            g0: Col::zeros(problem.nc0()),
        }
    }

    /// Checks that the vectors have the dimensions of `problem`.
    pub fn check_dims(&self, problem: &LqProblem) -> Result<(), LqError> {
        let n = problem.knots.len();
        type Dim = fn(&LqKnot) -> usize;
        let groups: [(&'static str, &Vec<Col<f64>>, Dim); 4] = [
            ("vectors q", &self.q, |k| k.nx),
            ("vectors r", &self.r, |k| k.nu),
            ("vectors f", &self.f, |k| k.nx_next),
            ("vectors d", &self.d, |k| k.nc),
        ];
        for (field, v, dim) in groups {
            if v.len() != n {
                return Err(LqError::Dimension {
                    knot: 0,
                    field,
                    expected: (n, 1),
                    got: (v.len(), 1),
                });
            }
            for (t, (c, k)) in v.iter().zip(&problem.knots).enumerate() {
                if c.nrows() != dim(k) {
                    return Err(LqError::Dimension {
                        knot: t,
                        field,
                        expected: (dim(k), 1),
                        got: (c.nrows(), 1),
                    });
                }
            }
        }
        if self.g0.nrows() != problem.nc0() {
            return Err(LqError::Dimension {
                knot: 0,
                field: "vectors g0",
                expected: (problem.nc0(), 1),
                got: (self.g0.nrows(), 1),
            });
        }
        Ok(())
    }

    /// The vectors of knot `t`.
    pub fn knot(&self, t: usize) -> KnotVectors<'_> {
        KnotVectors {
            q: linalg::slice(&self.q[t]),
            r: linalg::slice(&self.r[t]),
            f: linalg::slice(&self.f[t]),
            d: linalg::slice(&self.d[t]),
        }
    }

    /// Sets `self` to the signed KKT residual of `sol` (the Lagrangian's gradient, see
    /// [`dense`]): `q ← Q x + S u + q + Cᵀν + Aᵀλ_{t+1} + E_{t-1}ᵀλ_t` (`G0ᵀλ_0` at
    /// `t = 0`), `r ← Sᵀx + R u + r + Dᵀν + Bᵀλ_{t+1}`, `d ← C x + D u + d - diag(mu_c) ν`,
    /// `f ← A x + B u + E x' + f - mu_dyn λ'`, `g0 ← G0 x_0 + g0 - mu0 λ_0`. Solving the
    /// problem with these vectors gives minus the error of `sol`.
    pub fn set_kkt_residual(&mut self, problem: &LqProblem, sol: &LqSolution) -> Result<(), LqError> {
        use faer::Accum::Add;
        use linalg::{matvec, matvec_t, slice, slice_mut};
        problem.check_shapes()?;
        sol.check_dims(problem)?;
        self.check_dims(problem)?;
        let n = problem.knots.len();
        let g0 = slice_mut(&mut self.g0);
        g0.copy_from_slice(slice(&problem.g0));
        matvec(g0, Add, problem.G0.as_ref(), slice(&sol.xs[0]), 1.0);
        for (g, l) in g0.iter_mut().zip(slice(&sol.lambdas[0])) {
            *g -= problem.mu0 * l;
        }
        for (t, k) in problem.knots.iter().enumerate() {
            let (x, u, nu) = (slice(&sol.xs[t]), slice(&sol.us[t]), slice(&sol.nus[t]));
            let has_dyn = t + 1 < n;
            let rq = slice_mut(&mut self.q[t]);
            rq.copy_from_slice(slice(&k.q));
            matvec(rq, Add, k.Q.as_ref(), x, 1.0);
            matvec(rq, Add, k.S.as_ref(), u, 1.0);
            matvec_t(rq, Add, k.C.as_ref(), nu, 1.0);
            if has_dyn {
                matvec_t(rq, Add, k.A.as_ref(), slice(&sol.lambdas[t + 1]), 1.0);
            }
            if t == 0 {
                matvec_t(rq, Add, problem.G0.as_ref(), slice(&sol.lambdas[0]), 1.0);
            } else {
                matvec_t(rq, Add, problem.knots[t - 1].E.as_ref(), slice(&sol.lambdas[t]), 1.0);
            }
            let rr = slice_mut(&mut self.r[t]);
            rr.copy_from_slice(slice(&k.r));
            matvec_t(rr, Add, k.S.as_ref(), x, 1.0);
            matvec(rr, Add, k.R.as_ref(), u, 1.0);
            matvec_t(rr, Add, k.D.as_ref(), nu, 1.0);
            if has_dyn {
                matvec_t(rr, Add, k.B.as_ref(), slice(&sol.lambdas[t + 1]), 1.0);
            }
            let rd = slice_mut(&mut self.d[t]);
            rd.copy_from_slice(slice(&k.d));
            matvec(rd, Add, k.C.as_ref(), x, 1.0);
            matvec(rd, Add, k.D.as_ref(), u, 1.0);
            for (i, v) in rd.iter_mut().enumerate() {
                *v -= k.mu_c[i] * nu[i];
            }
            if has_dyn {
                let rf = slice_mut(&mut self.f[t]);
                let lam = slice(&sol.lambdas[t + 1]);
                rf.copy_from_slice(slice(&k.f));
                matvec(rf, Add, k.A.as_ref(), x, 1.0);
                matvec(rf, Add, k.B.as_ref(), u, 1.0);
                matvec(rf, Add, k.E.as_ref(), slice(&sol.xs[t + 1]), 1.0);
                for (v, l) in rf.iter_mut().zip(lam) {
                    *v -= k.mu_dyn * l;
                }
            }
        }
        Ok(())
    }
}

impl LqSolution {
    /// `self += other` (same dimensions).
    pub(crate) fn add(&mut self, other: &LqSolution) {
        let groups = [
            (&mut self.xs, &other.xs),
            (&mut self.us, &other.us),
            (&mut self.lambdas, &other.lambdas),
            (&mut self.nus, &other.nus),
        ];
        for (a, b) in groups {
            for (ca, cb) in a.iter_mut().zip(b) {
                for (x, y) in linalg::slice_mut(ca).iter_mut().zip(linalg::slice(cb)) {
                    *x += y;
                }
            }
        }
    }
}

/// Errors of the LQ solvers. Each names the knot and the field or system concerned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LqError {
    /// The problem has no knot.
    #[error("the LQ problem has no knots")]
    Empty,
    /// A field does not have the shape the knot's dimensions (or the solver) expect.
    #[error("LQ knot {knot}: {field} has shape {got:?}, expected {expected:?}")]
    Dimension {
        /// Knot index (0 for the initial constraint).
        knot: usize,
        /// Field name, e.g. `"B"`.
        field: &'static str,
        /// Expected `(rows, cols)`.
        expected: (usize, usize),
        /// Shape found.
        got: (usize, usize),
    },
    /// A field holds a NaN or an infinity.
    #[error("LQ knot {knot}: non-finite value in {field}")]
    NonFinite {
        /// Knot index (0 for the initial constraint).
        knot: usize,
        /// Field name, or the computed quantity that overflowed.
        field: &'static str,
    },
    /// A regularisation parameter is negative.
    #[error("LQ knot {knot}: {field} must be nonnegative")]
    Negative {
        /// Knot index.
        knot: usize,
        /// Field name.
        field: &'static str,
    },
    /// A symmetric system has the wrong inertia: for a stage KKT block, `Q_uu` is not
    /// positive definite on the constraints' null space; a larger primal regularisation
    /// fixes it.
    #[error("LQ knot {knot}: {system} has inertia {got:?}, expected {expected:?}")]
    Inertia {
        /// Knot index.
        knot: usize,
        /// Which system: `"stage KKT"` or `"initial KKT"`.
        system: &'static str,
        /// Expected inertia.
        expected: Inertia,
        /// Inertia found.
        got: Inertia,
    },
    /// A linear system is singular.
    #[error("LQ knot {knot}: singular {system}")]
    Singular {
        /// Knot index (or leg boundary index for the condensed system).
        knot: usize,
        /// Which system, e.g. `"E"`.
        system: &'static str,
    },
    /// The square-root pass does not handle this knot (it needs `E = -I`, `mu_dyn = 0`
    /// and penalty rows, `mu_c > 0`).
    #[error("LQ knot {knot}: {what}")]
    Unsupported {
        /// Knot index.
        knot: usize,
        /// What is not handled.
        what: &'static str,
    },
    /// `backward_vectors` or `forward` was called without a successful full backward pass.
    #[error("the LQ solver has no factorization: call backward first (or after an error)")]
    NotFactored,
    /// An option of a solver is invalid.
    #[error("invalid LQ solver option `{name}`: {reason}")]
    Option {
        /// Option name.
        name: &'static str,
        /// Why it is invalid.
        reason: &'static str,
    },
}

impl From<LqError> for crate::Error {
    fn from(e: LqError) -> Self {
        match &e {
            LqError::Dimension { expected, got, .. } => {
                crate::Error::dim(e.to_string(), expected.0 * expected.1, got.0 * got.1)
            }
            LqError::NonFinite { .. } => crate::Error::non_finite(e.to_string()),
            LqError::Inertia { .. } | LqError::Singular { .. } => crate::Error::singular(e.to_string()),
            LqError::Option { name, reason } => crate::Error::option(name, reason),
            LqError::Empty | LqError::Negative { .. } | LqError::NotFactored | LqError::Unsupported { .. } => {
                crate::Error::InvalidModel(e.to_string())
            }
        }
    }
}

/// On a numerical failure at `knot`, names the offending input if there is one, else
/// returns `fallback`. Only called on the error path.
pub(crate) fn blame(problem: &LqProblem, knot: usize, fallback: LqError) -> LqError {
    if knot == 0
        && let Err(e) = problem.check_initial_values()
    {
        return e;
    }
    match problem.knots.get(knot).map(|k| k.check_values(knot)) {
        Some(Err(e)) => e,
        _ => fallback,
    }
}

/// `true` if `m` is exactly `-I`. Sums of absolute values (no early exit), which
/// vectorise: this runs on every knot at every backward pass.
pub(crate) fn is_minus_identity(m: MatRef<'_, f64>) -> bool {
    // Off-diagonal entries: one vectorised test per column (`-0.0` counts as zero, NaN
    // does not).
    use crate::linalg::any_nonzero;
    (0..m.ncols()).all(|j| match m.col(j).try_as_col_major() {
        Some(c) => {
            let c = c.as_slice();
            c.get(j) == Some(&-1.0) && !any_nonzero(&c[..j]) && !any_nonzero(&c[j + 1..])
        }
        None => (0..m.nrows()).all(|i| m[(i, j)] == if i == j { -1.0 } else { 0.0 }),
    })
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::is_minus_identity;

    /// Against the entrywise definition, on `-I` with one entry changed (column-major and
    /// transposed views): signed zeros count as zero, NaN and tiny values do not.
    #[test]
    fn minus_identity_matches_the_entrywise_test() {
        let entrywise =
            |m: &Mat<f64>| (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)] == if i == j { -1.0 } else { 0.0 }));
        for n in [1, 3, 12, 37] {
            let minus = Mat::<f64>::from_fn(n, n, |i, j| if i == j { -1.0 } else { 0.0 });
            assert!(is_minus_identity(minus.as_ref()) && is_minus_identity(minus.transpose()));
            for (i, j) in [(0, 0), (n - 1, 0), (0, n - 1), (n / 2, n / 3), (n - 1, n - 1)] {
                for v in [-0.0, 0.0, 1e-300, -1.0, 1.0, f64::NAN, f64::INFINITY] {
                    let mut m = minus.clone();
                    m[(i, j)] = v;
                    let expected = entrywise(&m);
                    assert_eq!(is_minus_identity(m.as_ref()), expected, "n {n} ({i}, {j}) = {v}");
                    assert_eq!(is_minus_identity(m.transpose()), expected, "transposed");
                }
            }
        }
    }
}
