//! One knot of the proximal Riccati recursion: Q-function, stage KKT solve, value update
//! and forward step (module docs of [`crate::lq`], steps 1-5).
//!
//! Memory traffic matters as much as flops here (a 36:12:32 knot holds about 50 kB of
//! data): when `E = -I` the knot's `A`, `B`, `f` are used in place, the stage KKT matrix is
//! assembled directly in its factorization's storage, and the products that are not kept
//! (`P̃[Ã B̃]`, `I + P'G`) live in a [`StageScratch`] shared by all knots.

use faer::prelude::ReborrowMut;
use faer::{Accum, Col, Mat, MatMut, MatRef};

use super::e_factor::EFactor;
use super::riccati::Outputs;
use super::{KnotDims, KnotVectors, LqError, LqKnot, blame};
use crate::linalg::{
    self, BunchKaufman, FactorError, Inertia, Ldlt, Llt, Lu, col_of, col_of_mut, matmul, matmul_lower_upper_free,
    matvec, matvec_t, slice, slice_mut, sum_is_finite,
};

/// Which gains beyond `k, K, ζ, Z` a stage computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ExtraGains {
    /// None.
    None,
    /// The closed loop `z = t0 + T x` (the parallel solver's parameter recursion).
    ClosedLoop,
    /// The closed loop and the rollout gains of `x_{t+1}` and `λ_{t+1}` (50b-c).
    Rollout,
}

/// Knots with `nx + nu` up to this copy `A` and `B` side by side for the products of the
/// Q-function (two calls instead of five: the calls' fixed cost matters more than the copy).
const SMALL_AB: usize = 24;

/// Scratch shared by the knots of a sweep: `P̃[Ã B̃]`, `[A B]` and `I + P'G`.
#[derive(Debug)]
pub(crate) struct StageScratch {
    pab: Mat<f64>,
    ab: Mat<f64>,
    m: Mat<f64>,
}

impl StageScratch {
    /// Scratch for knots of the given dimensions.
    pub(crate) fn new<'a>(dims: impl IntoIterator<Item = &'a KnotDims>) -> Self {
        let (ny, n) = dims
            .into_iter()
            .fold((0, 0), |(ny, n), d| (ny.max(d.nx_next), n.max(d.nx + d.nu)));
        Self {
            pab: Mat::zeros(ny, n),
            ab: Mat::zeros(ny, n.min(SMALL_AB)),
            m: Mat::zeros(ny, ny),
        }
    }
}

/// Workspace and results of one knot of the Riccati recursion.
///
/// All storage is allocated when the solver is built; the methods allocate nothing. Per
/// knot (backward in time) the solver computes the Q-function, then the stage solve
/// ([`solve_kkt`](Self::solve_kkt), [`solve_kkt_vectors`](Self::solve_kkt_vectors)); a
/// solver with its own control law replaces the stage solve by
/// [`value_from_gains`](Self::value_from_gains) (see
/// [`RiccatiSolver::backward_with`](super::RiccatiSolver::backward_with)).
#[derive(Debug)]
pub struct RiccatiStage {
    index: usize,
    nx: usize,
    nu: usize,
    nc: usize,
    ny: usize,
    extra: ExtraGains,
    // Step 1: [Ã B̃] and the factorization of E (general E only), f̃.
    e_fac: EFactor,
    ab_tilde: Mat<f64>,
    f_tilde: Col<f64>,
    // Step 2: proximal value, with M = I + P'G.
    mu_dyn: f64,
    g: Mat<f64>,
    prox: ProxFactor,
    ptilde: Mat<f64>,
    ptilde_vec: Col<f64>,
    v: Col<f64>,
    // Step 3: Q-function [Q_xx Q_xu; Q_ux Q_uu] and [Q_x; Q_u].
    qmat: Mat<f64>,
    qvec: Col<f64>,
    // Step 4: stage KKT factorization and gains [k K; ζ Z]; whether the knot's C is
    // zero (as for constraints on the controls alone), so that its products are skipped.
    kkt: KktFactor,
    c_is_zero: bool,
    gains: Mat<f64>,
    // Step 5: value function.
    P: Mat<f64>,
    p: Col<f64>,
    // Extra gains: [t0 | T] of z, [y0 | Y] of λ̃, [c | C] of x_{t+1}, [ξ | Ξ] of λ_{t+1}.
    zg: Mat<f64>,
    lg: Mat<f64>,
    xg: Mat<f64>,
    lamg: Mat<f64>,
    // Scratch: nu x nx and nu for value_from_gains, ny for the forward step.
    w_ux: Mat<f64>,
    w_u: Col<f64>,
    w_y: Col<f64>,
    // Copy of the vector part, for iterative refinement.
    saved: Vec<f64>,
}

/// `(Ã, B̃)`: the knot's `A`, `B` when `E = -I`, else `-E⁻¹A`, `-E⁻¹B`.
fn ab_of<'a>(e_minus_identity: bool, ab_tilde: &'a Mat<f64>, knot: &'a LqKnot) -> (MatRef<'a, f64>, MatRef<'a, f64>) {
    if e_minus_identity {
        (knot.A.as_ref(), knot.B.as_ref())
    } else {
        let (ny, nx, nu) = (knot.nx_next, knot.nx, knot.nu);
        (
            ab_tilde.as_ref().submatrix(0, 0, ny, nx),
            ab_tilde.as_ref().submatrix(0, nx, ny, nu),
        )
    }
}

impl RiccatiStage {
    /// Allocates the workspace of knot `index` with dimensions `nx, nu, nc` and next
    /// state dimension `ny` (0 at the last knot), computing the `extra` gains. `max_rhs` is
    /// the largest number of right-hand sides the proximal system `I + P'G` will be solved
    /// with (at least `ny + 1`).
    pub(crate) fn new(
        index: usize,
        nx: usize,
        nu: usize,
        nc: usize,
        ny: usize,
        extra: ExtraGains,
        max_rhs: usize,
    ) -> Self {
        let nk = nu + nc;
        let ng = if extra == ExtraGains::Rollout { ny } else { 0 };
        let nz = if extra == ExtraGains::None { 0 } else { ny };
        let max_rhs = max_rhs.max(ny + 1);
        Self {
            index,
            nx,
            nu,
            nc,
            ny,
            extra,
            e_fac: EFactor::new(ny, (nx + nu).max(max_rhs)),
            ab_tilde: Mat::zeros(ny, nx + nu),
            f_tilde: Col::zeros(ny),
            mu_dyn: 0.0,
            g: Mat::zeros(ny, ny),
            prox: ProxFactor {
                llt: Llt::new(ny),
                lu: Lu::new(ny, max_rhs),
                is_llt: true,
                congruent: false,
                w: Mat::zeros(ny, max_rhs),
            },
            ptilde: Mat::zeros(ny, ny),
            ptilde_vec: Col::zeros(ny),
            v: Col::zeros(ny),
            qmat: Mat::zeros(nx + nu, nx + nu),
            qvec: Col::zeros(nx + nu),
            kkt: KktFactor::new(nu, nc, (1 + nx).max(nu)),
            c_is_zero: false,
            gains: Mat::zeros(nk, 1 + nx),
            P: Mat::zeros(nx, nx),
            p: Col::zeros(nx),
            zg: Mat::zeros(nz, 1 + nx),
            lg: Mat::zeros(ng, 1 + nx),
            xg: Mat::zeros(ng, 1 + nx),
            lamg: Mat::zeros(ng, 1 + nx),
            w_ux: Mat::zeros(nu, nx),
            w_u: Col::zeros(nu),
            w_y: Col::zeros(ny),
            saved: vec![0.0; 2 * nx + 2 * nu + nc + 3 * ny + nz + 3 * ng],
        }
    }

    /// Sets which extra gains the next backward passes compute (within the storage
    /// allocated by [`new`](Self::new)).
    pub(crate) fn set_extra(&mut self, extra: ExtraGains) {
        debug_assert!(extra == ExtraGains::None || self.lg.nrows() == self.ny);
        self.extra = extra;
    }

    /// Knot index (used in error messages).
    pub fn index(&self) -> usize {
        self.index
    }

    /// `(nx, nu, nc, nx_next)`.
    pub fn dims(&self) -> (usize, usize, usize, usize) {
        (self.nx, self.nu, self.nc, self.ny)
    }

    fn singular(&self, system: &'static str) -> LqError {
        LqError::Singular {
            knot: self.index,
            system,
        }
    }

    /// Matrix part of the Q-function (steps 1-3): `Q_xx, Q_xu, Q_uu` from the knot and the
    /// next value Hessian `P_next` (`None` at the last knot).
    pub(crate) fn q_function(
        &mut self,
        knot: &LqKnot,
        P_next: Option<MatRef<'_, f64>>,
        scratch: &mut StageScratch,
    ) -> Result<(), LqError> {
        let (nx, nu, ny) = (self.nx, self.nu, self.ny);
        {
            let mut h = self.qmat.as_mut();
            linalg::copy(h.rb_mut().submatrix_mut(0, 0, nx, nx), knot.Q.as_ref());
            linalg::copy_transposed(h.rb_mut().submatrix_mut(nx, 0, nu, nx), knot.S.as_ref());
            linalg::copy(h.rb_mut().submatrix_mut(nx, nx, nu, nu), knot.R.as_ref());
        }
        self.mu_dyn = knot.mu_dyn;
        if ny > 0 {
            let P_next = P_next.expect("a knot with dynamics has a next value function");
            self.dynamics_tilde(knot)?;
            // Step 2: P̃ = (I + P'G)⁻¹ P'.
            if self.mu_dyn > 0.0 {
                self.factor_prox(P_next, scratch.m.as_mut().submatrix_mut(0, 0, ny, ny))?;
                linalg::copy(self.ptilde.as_mut(), P_next);
                self.prox.solve_in_place(&mut self.e_fac, self.ptilde.as_mut());
                linalg::symmetrize(self.ptilde.as_mut());
            }
            self.add_dynamics_curvature(knot, P_next, scratch);
        }
        linalg::symmetrize_from_lower(self.qmat.as_mut());
        Ok(())
    }

    /// Step 1: factors `E` and, unless `E = -I`, forms `[Ã B̃] = -E⁻¹[A B]`.
    fn dynamics_tilde(&mut self, knot: &LqKnot) -> Result<(), LqError> {
        let (nx, nu, ny) = (self.nx, self.nu, self.ny);
        self.e_fac.factor(knot.E.as_ref()).map_err(|e| match e {
            FactorError::NonFinite => LqError::NonFinite {
                knot: self.index,
                field: "E",
            },
            FactorError::Singular { .. } => self.singular("dynamics matrix E"),
        })?;
        if !self.e_fac.is_minus_identity() {
            let mut ab = self.ab_tilde.as_mut();
            linalg::copy(ab.rb_mut().submatrix_mut(0, 0, ny, nx), knot.A.as_ref());
            linalg::copy(ab.rb_mut().submatrix_mut(0, nx, ny, nu), knot.B.as_ref());
            self.e_fac.neg_solve_in_place(ab);
        }
        Ok(())
    }

    /// Step 3: `Q += [Ã B̃]ᵀ P̃ [Ã B̃]` (lower triangle; `P̃ = P'` without the dynamics'
    /// proximal term): two products on a contiguous `[Ã B̃]` (the knot's `A` and `B`
    /// copied side by side when small: fewer calls), five on the knot's `A` and `B` in
    /// place when large (no copy).
    fn add_dynamics_curvature(&mut self, knot: &LqKnot, P_next: MatRef<'_, f64>, scratch: &mut StageScratch) {
        let (nx, nu, ny) = (self.nx, self.nu, self.ny);
        let pt = if self.mu_dyn > 0.0 {
            self.ptilde.as_ref()
        } else {
            P_next
        };
        if self.e_fac.is_minus_identity()
            && linalg::add_sandwich_lower(self.qmat.as_mut(), pt, knot.A.as_ref(), knot.B.as_ref())
        {
            return;
        }
        let n = nx + nu;
        let contiguous = if !self.e_fac.is_minus_identity() {
            Some(self.ab_tilde.as_ref())
        } else if n <= SMALL_AB {
            let mut ab = scratch.ab.as_mut().submatrix_mut(0, 0, ny, n);
            linalg::copy(ab.rb_mut().subcols_mut(0, nx), knot.A.as_ref());
            linalg::copy(ab.rb_mut().subcols_mut(nx, nu), knot.B.as_ref());
            Some(scratch.ab.as_ref().submatrix(0, 0, ny, n))
        } else {
            None
        };
        let mut w = scratch.pab.as_mut().submatrix_mut(0, 0, ny, n);
        let mut q = self.qmat.as_mut();
        if let Some(ab) = contiguous {
            matmul(w.rb_mut(), Accum::Replace, pt, ab, 1.0);
            matmul_lower_upper_free(q, Accum::Add, ab.transpose(), w.as_ref(), 1.0);
            return;
        }
        let (a, b) = (knot.A.as_ref(), knot.B.as_ref());
        matmul(w.rb_mut().subcols_mut(0, nx), Accum::Replace, pt, a, 1.0);
        matmul_lower_upper_free(
            q.rb_mut().submatrix_mut(0, 0, nx, nx),
            Accum::Add,
            a.transpose(),
            w.as_ref().subcols(0, nx),
            1.0,
        );
        if nu > 0 {
            matmul(w.rb_mut().subcols_mut(nx, nu), Accum::Replace, pt, b, 1.0);
            matmul(
                q.rb_mut().submatrix_mut(nx, 0, nu, nx),
                Accum::Add,
                b.transpose(),
                w.as_ref().subcols(0, nx),
                1.0,
            );
            matmul_lower_upper_free(
                q.rb_mut().submatrix_mut(nx, nx, nu, nu),
                Accum::Add,
                b.transpose(),
                w.as_ref().subcols(nx, nu),
                1.0,
            );
        }
    }

    /// Factors `M = I + P'G`, computing `G` first for a general `E`; `m` is scratch.
    ///
    /// When `E = -I`, `M = I + mu P'` is symmetric: Cholesky if it is positive definite.
    /// For a general `E`, with `C = E⁻¹` (so `G = mu C Cᵀ`), `M = C⁻ᵀ (I + mu CᵀP'C) Cᵀ`:
    /// Cholesky of the congruent `I + mu E⁻ᵀP'E⁻¹` if positive definite. LU of `M`
    /// otherwise.
    fn factor_prox(&mut self, P_next: MatRef<'_, f64>, mut m: MatMut<'_, f64>) -> Result<(), LqError> {
        let ny = self.ny;
        let mu = self.mu_dyn;
        self.prox.congruent = false;
        if self.e_fac.is_minus_identity() {
            // Its lower triangle straight into the Cholesky factor's storage, the whole
            // of it for LU if that fails.
            linalg::identity_plus_scaled_lower(self.prox.llt.matrix_mut(), P_next, mu);
            self.prox.is_llt = self.prox.llt.factor_filled().is_ok();
            if self.prox.is_llt {
                return Ok(());
            }
            for j in 0..ny {
                for i in 0..ny {
                    m[(i, j)] = mu * P_next[(i, j)] + if i == j { 1.0 } else { 0.0 };
                }
            }
        } else {
            self.e_fac.inverse_gram(mu, self.g.as_mut());
            linalg::symmetrize(self.g.as_mut());
            // E⁻ᵀP'E⁻¹ = E⁻ᵀ(E⁻ᵀP')ᵀ, P' symmetric.
            linalg::copy(m.rb_mut(), P_next);
            self.e_fac.solve_transpose_in_place(m.rb_mut());
            let mut h = self.prox.llt.matrix_mut();
            linalg::copy_transposed(h.rb_mut(), m.as_ref());
            self.e_fac.solve_transpose_in_place(h.rb_mut());
            for j in 0..ny {
                for i in j..ny {
                    h[(i, j)] = mu * h[(i, j)] + if i == j { 1.0 } else { 0.0 };
                }
            }
            self.prox.is_llt = self.prox.llt.factor_filled().is_ok();
            if self.prox.is_llt {
                self.prox.congruent = true;
                return Ok(());
            }
            for j in 0..ny {
                for i in 0..ny {
                    m[(i, j)] = if i == j { 1.0 } else { 0.0 };
                }
            }
            matmul(m.rb_mut(), Accum::Add, P_next, self.g.as_ref(), 1.0);
        }
        self.prox.is_llt = false;
        self.prox.lu.factor(m.as_ref()).map_err(|e| match e {
            FactorError::NonFinite => LqError::NonFinite {
                knot: self.index,
                field: "next value function",
            },
            FactorError::Singular { .. } => self.singular("proximal dynamics system I + P'G"),
        })
    }

    /// Solves `(I + P'G) X = B` in place with the factorization of the last Q-function
    /// (only when `mu_dyn > 0`).
    pub(crate) fn prox_solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        self.prox.solve_in_place(&mut self.e_fac, rhs);
    }

    /// Vector part of the Q-function: `Q_x, Q_u` from the vectors `q, r, f` and the next
    /// value function (`None` at the last knot).
    pub(crate) fn q_function_vectors(
        &mut self,
        knot: &LqKnot,
        v: KnotVectors<'_>,
        next: Option<(MatRef<'_, f64>, &[f64])>,
    ) {
        let (nx, ny) = (self.nx, self.ny);
        let qv = slice_mut(&mut self.qvec);
        qv[..nx].copy_from_slice(v.q);
        qv[nx..].copy_from_slice(v.r);
        if ny == 0 {
            return;
        }
        let (P_next, p_next) = next.expect("a knot with dynamics has a next value function");
        // f̃ = -E⁻¹ f.
        slice_mut(&mut self.f_tilde).copy_from_slice(v.f);
        if !self.e_fac.is_minus_identity() {
            self.e_fac.neg_solve_in_place(self.f_tilde.as_mut().as_mat_mut());
        }
        // p̃ = (I + P'G)⁻¹ p', v = P̃ f̃ + p̃.
        let pt_vec: &[f64] = if self.mu_dyn > 0.0 {
            slice_mut(&mut self.ptilde_vec).copy_from_slice(p_next);
            self.prox
                .solve_in_place(&mut self.e_fac, self.ptilde_vec.as_mut().as_mat_mut());
            slice(&self.ptilde_vec)
        } else {
            p_next
        };
        let vv = slice_mut(&mut self.v);
        vv.copy_from_slice(pt_vec);
        let pt = if self.mu_dyn > 0.0 {
            self.ptilde.as_ref()
        } else {
            P_next
        };
        matvec(vv, Accum::Add, pt, slice(&self.f_tilde), 1.0);
        // [Q_x; Q_u] += [Ã B̃]ᵀ v.
        let (a, b) = ab_of(self.e_fac.is_minus_identity(), &self.ab_tilde, knot);
        let qv = slice_mut(&mut self.qvec);
        let (qx, qu) = qv.split_at_mut(nx);
        matvec_t(qx, Accum::Add, a, slice(&self.v), 1.0);
        matvec_t(qu, Accum::Add, b, slice(&self.v), 1.0);
    }

    /// Matrix part of the stage solve (steps 4-5): factors the stage KKT system with the
    /// primal regularisation `primal_reg`, computes the feedback gains `K`, `Z`, the value
    /// Hessian `P` and (if enabled) the feedback parts of the extra gains. `P_next` is the
    /// next value Hessian (`None` at the last knot). Needs the Q-function.
    pub fn solve_kkt(
        &mut self,
        knot: &LqKnot,
        P_next: Option<MatRef<'_, f64>>,
        primal_reg: f64,
    ) -> Result<(), LqError> {
        self.check_knot(knot)?;
        self.check_next(P_next, None)?;
        self.solve_kkt_impl(knot, P_next, primal_reg, None)
    }

    /// Checks that `knot` has this stage's dimensions (for the public stage methods).
    fn check_knot(&self, knot: &LqKnot) -> Result<(), LqError> {
        knot.check_shapes(self.index)?;
        if (knot.nx, knot.nu, knot.nc, knot.nx_next) != (self.nx, self.nu, self.nc, self.ny) {
            return Err(LqError::Dimension {
                knot: self.index,
                field: "knot dimensions (nx + nu + nc + nx_next)",
                expected: (self.nx + self.nu + self.nc + self.ny, 1),
                got: (knot.nx + knot.nu + knot.nc + knot.nx_next, 1),
            });
        }
        Ok(())
    }

    /// Checks the next value function given to the public stage methods: present exactly
    /// when the knot has dynamics, of size `nx_next`.
    fn check_next(&self, P_next: Option<MatRef<'_, f64>>, p_next: Option<&[f64]>) -> Result<(), LqError> {
        let ny = self.ny;
        let shape = P_next.map_or((0, 0), |P| (P.nrows(), P.ncols()));
        if (ny > 0 || P_next.is_some()) && shape != (ny, ny) {
            return Err(LqError::Dimension {
                knot: self.index,
                field: "next value Hessian",
                expected: (ny, ny),
                got: shape,
            });
        }
        match p_next {
            Some(p) if p.len() != ny => Err(LqError::Dimension {
                knot: self.index,
                field: "next value gradient",
                expected: (ny, 1),
                got: (p.len(), 1),
            }),
            _ => Ok(()),
        }
    }

    /// [`solve_kkt`](Self::solve_kkt), also solving for the feedforward column `[k; ζ]`
    /// with constraint offset `d` in the same solve (finish with
    /// [`solve_kkt_vectors_solved`](Self::solve_kkt_vectors_solved)).
    pub(crate) fn solve_kkt_with_feedforward(
        &mut self,
        knot: &LqKnot,
        P_next: Option<MatRef<'_, f64>>,
        primal_reg: f64,
        d: &[f64],
    ) -> Result<(), LqError> {
        self.solve_kkt_impl(knot, P_next, primal_reg, Some(d))
    }

    /// The stage KKT solve (47): factors `[[Q_uu + ρI, Dᵀ], [D, -diag(mu_c)]]`, solves for
    /// the gains `[K; Z]` (and the feedforward column with `d`), then the value Hessian.
    fn solve_kkt_impl(
        &mut self,
        knot: &LqKnot,
        P_next: Option<MatRef<'_, f64>>,
        primal_reg: f64,
        d: Option<&[f64]>,
    ) -> Result<(), LqError> {
        // Exact zeros only (a NaN in C keeps the products, which report it).
        self.c_is_zero = (0..self.nx).all(|j| linalg::norm_l1(col_of(&knot.C, j)) == 0.0);
        if self.nu + self.nc > 0 {
            self.factor_stage_kkt(knot, primal_reg)?;
            self.solve_gains(knot, d);
        }
        self.value_hessian(knot)?;
        if self.ny > 0 && self.extra != ExtraGains::None {
            self.feedback_extra_gains(knot, P_next.expect("a knot with dynamics has a next value function"));
        }
        Ok(())
    }

    /// Fills the lower triangle of `[[Q_uu + ρI, ·], [D, -diag(mu_c)]]` into the factor's
    /// storage and factors it (LDLᵀ, Bunch-Kaufman when a row has `mu_c = 0`), checking
    /// the inertia `(nu, nc, 0)`. Constraint rows that do not depend on the control (`D`
    /// row zero, `mu_c > 0`: obstacles, state bounds) decouple from the rest and stay out
    /// of the LDLᵀ factorization: their multipliers are their right-hand side over
    /// `-mu_c` (170 wall discs per knot: one 2 × 2 factorization instead of 172 × 172).
    fn factor_stage_kkt(&mut self, knot: &LqKnot, primal_reg: f64) -> Result<(), LqError> {
        let (nx, nu, nc) = (self.nx, self.nu, self.nc);
        let f = &mut self.kkt;
        f.use_bk = (0..nc).any(|i| knot.mu_c[i] == 0.0);
        f.partition(knot);
        // The constraint rows in the factorization (all of them unless some decouple).
        let mc = f.coupled.len() - nu;
        let mut k = if f.use_bk {
            f.bk.matrix_mut()
        } else {
            f.ldlt.matrix_mut()
        };
        linalg::copy(
            k.rb_mut().submatrix_mut(0, 0, nu, nu),
            self.qmat.as_ref().submatrix(nx, nx, nu, nu),
        );
        for i in 0..nu {
            k[(i, i)] += primal_reg;
        }
        k.rb_mut().submatrix_mut(nu, nu, mc, mc).fill(0.0);
        for (a, &r) in f.coupled[nu..].iter().enumerate() {
            for j in 0..nu {
                k[(nu + a, j)] = knot.D[(r - nu, j)];
            }
            k[(nu + a, nu + a)] = -knot.mu_c[r - nu];
        }
        let res = if f.use_bk {
            f.bk.factor_filled(0.0)
        } else {
            f.ldlt.factor_filled()
        };
        // The decoupled rows' pivots -mu_c are negative: the inertia of the whole system.
        let n_free = f.free.len();
        let expected = Inertia {
            positive: nu,
            negative: nc,
            zero: 0,
        };
        match res.map(|got| Inertia {
            negative: got.negative + n_free,
            ..got
        }) {
            Ok(inertia) if inertia == expected => Ok(()),
            Ok(got) => Err(LqError::Inertia {
                knot: self.index,
                system: "stage KKT",
                expected,
                got,
            }),
            Err(FactorError::NonFinite) => Err(LqError::NonFinite {
                knot: self.index,
                field: "Q_uu",
            }),
            Err(FactorError::Singular { index }) => Err(LqError::Inertia {
                knot: self.index,
                system: "stage KKT",
                expected,
                got: Inertia {
                    positive: index.min(nu),
                    negative: index.saturating_sub(nu) + n_free,
                    zero: 1,
                },
            }),
        }
    }

    /// Solves the factored stage KKT system for the feedback gains `[K; Z]` from the
    /// right-hand side `-[Q_ux; C]` (47a), and for the feedforward column too with `d`.
    fn solve_gains(&mut self, knot: &LqKnot, d: Option<&[f64]>) {
        if self.solve_gains_decoupled(knot, d) {
            return;
        }
        let (nx, nu, nc) = (self.nx, self.nu, self.nc);
        let mut rhs = self.gains.as_mut().submatrix_mut(0, 1, nu + nc, nx);
        linalg::copy(
            rhs.rb_mut().submatrix_mut(0, 0, nu, nx),
            self.qmat.as_ref().submatrix(nx, 0, nu, nx),
        );
        linalg::copy(rhs.rb_mut().submatrix_mut(nu, 0, nc, nx), knot.C.as_ref());
        linalg::negate(rhs.rb_mut());
        match d {
            Some(d) => {
                self.fill_feedforward_rhs(d);
                self.kkt.solve_in_place(self.gains.as_mut());
            }
            None => self.kkt.solve_in_place(rhs),
        }
    }

    /// [`solve_gains`](Self::solve_gains) (47a) when no constraint row couples with the
    /// controls (inactive constraints, constraints on the state alone) and `nu` is small: `K` is
    /// solved straight from `Q_xu` (the mirror of `Q_ux`, whose rows it holds contiguously)
    /// into the gains, and the constraint rows are `Z = C / mu_c` (`ζ = d / mu_c`), the
    /// general path's `-C / -mu_c` to the bit, without the copies into the gains. Returns
    /// `false` (and does nothing) when these conditions do not hold.
    fn solve_gains_decoupled(&mut self, knot: &LqKnot, d: Option<&[f64]>) -> bool {
        let (nx, nu, nc) = (self.nx, self.nu, self.nc);
        if !self.kkt.controls_alone(nu) {
            return false;
        }
        let q_xu = self.qmat.as_ref().submatrix(0, nx, nx, nu);
        let k = self.gains.as_mut().submatrix_mut(0, 1, nu, nx);
        let KktFactor { ldlt, gather, .. } = &mut self.kkt;
        if nu > 0 && !ldlt.solve_neg_transposed(q_xu, k, gather) {
            return false;
        }
        for j in 0..nx {
            let (z, c) = (&mut col_of_mut(&mut self.gains, j + 1)[nu..], col_of(&knot.C, j));
            for ((z, &c), &mu) in z.iter_mut().zip(c).zip(slice(&knot.mu_c)) {
                *z = c / mu;
            }
        }
        if let Some(d) = d {
            self.fill_feedforward_rhs(d);
            let g0 = col_of_mut(&mut self.gains, 0);
            if nu > 0 {
                self.kkt
                    .ldlt
                    .solve_in_place(MatMut::from_column_major_slice_mut(&mut g0[..nu], nu, 1));
            }
            for ((z, &di), &mu) in g0[nu..nu + nc].iter_mut().zip(d).zip(slice(&knot.mu_c)) {
                *z = di / mu;
            }
        }
        true
    }

    /// `P = Q_xx + [Q_xu Cᵀ][K; Z]` (47b), the Schur complement of the stage KKT matrix.
    /// (The equivalent sum of semidefinite terms `[I; K]ᵀH[I; K] + Zᵀdiag(mu_c)Z` is not
    /// used: it agrees with the gains only to the accuracy of the KKT solve, about `ε/mu`
    /// relative, which the forward pass's co-states `P x + p` would inherit.) Lower
    /// triangle, then mirrored.
    fn value_hessian(&mut self, knot: &LqKnot) -> Result<(), LqError> {
        let (nx, nu, nc) = (self.nx, self.nu, self.nc);
        let fb = self.gains.as_ref().submatrix(0, 1, nu + nc, nx);
        let (q_xx, q_xu) = (
            self.qmat.as_ref().submatrix(0, 0, nx, nx),
            self.qmat.as_ref().submatrix(0, nx, nx, nu),
        );
        // Small stages in one pass; the copy and the product otherwise.
        if !(nu > 0 && linalg::copy_add_product(self.P.as_mut(), q_xx, q_xu, fb.subrows(0, nu))) {
            linalg::copy(self.P.as_mut(), q_xx);
            if nu > 0 {
                matmul_lower_upper_free(self.P.as_mut(), Accum::Add, q_xu, fb.subrows(0, nu), 1.0);
            }
        }
        if nc > 0 && !self.c_is_zero {
            matmul_lower_upper_free(self.P.as_mut(), Accum::Add, knot.C.transpose(), fb.subrows(nu, nc), 1.0);
        }
        linalg::symmetrize_from_lower(self.P.as_mut());
        if !sum_is_finite(self.P.as_ref()) {
            return Err(LqError::NonFinite {
                knot: self.index,
                field: "value Hessian P",
            });
        }
        Ok(())
    }

    /// Solves the factored stage KKT system in place, for any number of right-hand sides
    /// (in blocks of the columns the factorization's scratch holds).
    pub(crate) fn kkt_solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        let (n, block) = (rhs.ncols(), self.kkt.max_rhs.max(1));
        for j in (0..n).step_by(block) {
            let c = block.min(n - j);
            self.kkt.solve_in_place(rhs.rb_mut().subcols_mut(j, c));
        }
    }

    /// `T = Ã + B̃K` (feedback of `z`), and with rollout gains `Y = P̃T`, `C = T - GY`,
    /// `Ξ = -E⁻ᵀY`.
    fn feedback_extra_gains(&mut self, knot: &LqKnot, P_next: MatRef<'_, f64>) {
        let (nx, nu, ny) = (self.nx, self.nu, self.ny);
        let (a, b) = ab_of(self.e_fac.is_minus_identity(), &self.ab_tilde, knot);
        {
            let mut t = self.zg.as_mut().submatrix_mut(0, 1, ny, nx);
            linalg::copy(t.rb_mut(), a);
            if nu > 0 {
                matmul(t, Accum::Add, b, self.gains.as_ref().submatrix(0, 1, nu, nx), 1.0);
            }
        }
        if self.extra != ExtraGains::Rollout {
            return;
        }
        let pt = if self.mu_dyn > 0.0 {
            self.ptilde.as_ref()
        } else {
            P_next
        };
        let t = self.zg.as_ref().submatrix(0, 1, ny, nx);
        matmul(self.lg.as_mut().submatrix_mut(0, 1, ny, nx), Accum::Replace, pt, t, 1.0);
        let y = self.lg.as_ref().submatrix(0, 1, ny, nx);
        let mut c = self.xg.as_mut().submatrix_mut(0, 1, ny, nx);
        linalg::copy(c.rb_mut(), t);
        sub_g_times(self.mu_dyn, self.e_fac.is_minus_identity(), self.g.as_ref(), c, y);
        let mut xi = self.lamg.as_mut().submatrix_mut(0, 1, ny, nx);
        linalg::copy(xi.rb_mut(), y);
        if !self.e_fac.is_minus_identity() {
            self.e_fac.solve_transpose_in_place(xi.rb_mut());
            linalg::negate(xi);
        }
    }

    /// Vector part of the stage solve: feedforward `k`, `ζ`, value gradient `p` and the
    /// feedforward parts of the extra gains, reusing the factorization of
    /// [`solve_kkt`](Self::solve_kkt). `next` is the next value function (`None` at the
    /// last knot).
    pub fn solve_kkt_vectors(&mut self, knot: &LqKnot, next: Option<(MatRef<'_, f64>, &[f64])>) -> Result<(), LqError> {
        self.check_knot(knot)?;
        self.check_next(next.map(|n| n.0), next.map(|n| n.1))?;
        self.solve_kkt_vectors_with(knot, KnotVectors::of(knot).d, next)
    }

    /// [`solve_kkt_vectors`](Self::solve_kkt_vectors) with the constraint offset `d` given.
    pub(crate) fn solve_kkt_vectors_with(
        &mut self,
        knot: &LqKnot,
        d: &[f64],
        next: Option<(MatRef<'_, f64>, &[f64])>,
    ) -> Result<(), LqError> {
        if self.nu + self.nc > 0 {
            self.fill_feedforward_rhs(d);
            self.kkt.solve_in_place(self.gains.as_mut().subcols_mut(0, 1));
        }
        self.solve_kkt_vectors_solved(knot, next)
    }

    /// `-[Q_u; d]` in the feedforward column.
    fn fill_feedforward_rhs(&mut self, d: &[f64]) {
        let (nx, nu) = (self.nx, self.nu);
        let g0 = col_of_mut(&mut self.gains, 0);
        for i in 0..nu {
            g0[i] = -self.qvec[nx + i];
        }
        for (g, di) in g0[nu..].iter_mut().zip(d) {
            *g = -di;
        }
    }

    /// The vector part after the feedforward column was solved for: `p` and the
    /// feedforward parts of the extra gains.
    pub(crate) fn solve_kkt_vectors_solved(
        &mut self,
        knot: &LqKnot,
        next: Option<(MatRef<'_, f64>, &[f64])>,
    ) -> Result<(), LqError> {
        let (nx, nu, nc) = (self.nx, self.nu, self.nc);
        let nk = nu + nc;
        // p = Q_x + Q_xu k + Cᵀ ζ.
        let p = slice_mut(&mut self.p);
        p.copy_from_slice(&slice(&self.qvec)[..nx]);
        if nk > 0 {
            let ff = col_of(&self.gains, 0);
            matvec(
                p,
                Accum::Add,
                self.qmat.as_ref().submatrix(0, nx, nx, nu),
                &ff[..nu],
                1.0,
            );
            if !self.c_is_zero {
                matvec_t(p, Accum::Add, knot.C.as_ref(), &ff[nu..], 1.0);
            }
        }
        if !p.iter().sum::<f64>().is_finite() {
            return Err(LqError::NonFinite {
                knot: self.index,
                field: "value gradient p",
            });
        }
        if self.ny > 0 && self.extra != ExtraGains::None {
            let (P_next, p_next) = next.expect("a knot with dynamics has a next value function");
            self.feedforward_extra_gains(knot, P_next, p_next);
        }
        Ok(())
    }

    /// `t0 = B̃k + f̃`, and with rollout gains `y0 = P̃t0 + p̃`, `c = t0 - Gy0`, `ξ = -E⁻ᵀy0`.
    fn feedforward_extra_gains(&mut self, knot: &LqKnot, P_next: MatRef<'_, f64>, p_next: &[f64]) {
        let nu = self.nu;
        let (_, b) = ab_of(self.e_fac.is_minus_identity(), &self.ab_tilde, knot);
        {
            let t0 = col_of_mut(&mut self.zg, 0);
            t0.copy_from_slice(slice(&self.f_tilde));
            matvec(t0, Accum::Add, b, &col_of(&self.gains, 0)[..nu], 1.0);
        }
        if self.extra != ExtraGains::Rollout {
            return;
        }
        let pt_vec: &[f64] = if self.mu_dyn > 0.0 {
            slice(&self.ptilde_vec)
        } else {
            p_next
        };
        {
            let y0 = col_of_mut(&mut self.lg, 0);
            y0.copy_from_slice(pt_vec);
            let pt = if self.mu_dyn > 0.0 {
                self.ptilde.as_ref()
            } else {
                P_next
            };
            matvec(y0, Accum::Add, pt, col_of(&self.zg, 0), 1.0);
        }
        col_of_mut(&mut self.xg, 0).copy_from_slice(col_of(&self.zg, 0));
        sub_g_times(
            self.mu_dyn,
            self.e_fac.is_minus_identity(),
            self.g.as_ref(),
            self.xg.as_mut().subcols_mut(0, 1),
            self.lg.as_ref().subcols(0, 1),
        );
        col_of_mut(&mut self.lamg, 0).copy_from_slice(col_of(&self.lg, 0));
        if !self.e_fac.is_minus_identity() {
            let mut xi = self.lamg.as_mut().subcols_mut(0, 1);
            self.e_fac.solve_transpose_in_place(xi.rb_mut());
            linalg::negate(xi);
        }
    }

    /// Value update from arbitrary control gains `u = k + K x` (for solvers with their own
    /// control law, e.g. box-DDP): `P = Q_xx + KᵀQ_uu K + Q_xu K + KᵀQ_ux`,
    /// `p = Q_x + KᵀQ_uu k + Q_xu k + KᵀQ_u`. The gains are stored as this knot's control
    /// gains (the multiplier gains are left untouched). Needs the Q-function.
    pub fn value_from_gains(&mut self, k: &[f64], K: MatRef<'_, f64>) -> Result<(), LqError> {
        let (nx, nu) = (self.nx, self.nu);
        if k.len() != nu {
            return Err(LqError::Dimension {
                knot: self.index,
                field: "feedforward gain k",
                expected: (nu, 1),
                got: (k.len(), 1),
            });
        }
        if (K.nrows(), K.ncols()) != (nu, nx) {
            return Err(LqError::Dimension {
                knot: self.index,
                field: "feedback gain K",
                expected: (nu, nx),
                got: (K.nrows(), K.ncols()),
            });
        }
        let q = self.qmat.as_ref();
        let (q_xx, q_xu, q_ux, q_uu) = (
            q.submatrix(0, 0, nx, nx),
            q.submatrix(0, nx, nx, nu),
            q.submatrix(nx, 0, nu, nx),
            q.submatrix(nx, nx, nu, nu),
        );
        // W = Q_uu K + Q_ux, P = Q_xx + KᵀW + Q_xu K.
        linalg::copy(self.w_ux.as_mut(), q_ux);
        matmul(self.w_ux.as_mut(), Accum::Add, q_uu, K, 1.0);
        linalg::copy(self.P.as_mut(), q_xx);
        matmul(self.P.as_mut(), Accum::Add, K.transpose(), self.w_ux.as_ref(), 1.0);
        matmul(self.P.as_mut(), Accum::Add, q_xu, K, 1.0);
        linalg::symmetrize(self.P.as_mut());
        // w = Q_uu k + Q_u, p = Q_x + Kᵀw + Q_xu k.
        let qv = slice(&self.qvec);
        let w = slice_mut(&mut self.w_u);
        w.copy_from_slice(&qv[nx..]);
        matvec(w, Accum::Add, q_uu, k, 1.0);
        let p = slice_mut(&mut self.p);
        p.copy_from_slice(&qv[..nx]);
        matvec_t(p, Accum::Add, K, slice(&self.w_u), 1.0);
        matvec(p, Accum::Add, q_xu, k, 1.0);
        col_of_mut(&mut self.gains, 0)[..nu].copy_from_slice(k);
        linalg::copy(self.gains.as_mut().submatrix_mut(0, 1, nu, nx), K);
        if !sum_is_finite(self.P.as_ref()) || !p.iter().sum::<f64>().is_finite() {
            return Err(LqError::NonFinite {
                knot: self.index,
                field: "value function from gains",
            });
        }
        Ok(())
    }

    /// Forward step (50): from `x`, writes `u = k + K x`, `ν = ζ + Z x` and, at a knot with
    /// dynamics, `x_{t+1} = z - Gλ̃` and `λ_{t+1} = -E⁻ᵀλ̃` with `z = Ãx + B̃u + f̃`,
    /// `λ̃ = P̃z + p̃` (`next` is the next value function, unused at the last knot). With
    /// `Outputs::Primal`, `ν` and `λ_{t+1}` are not written (`lambda_next` holds `λ̃` when
    /// `x_{t+1}` needs it, `G ≠ 0`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn forward_step(
        &mut self,
        knot: &LqKnot,
        x: &[f64],
        u: &mut [f64],
        nu_out: &mut [f64],
        next: Option<(MatRef<'_, f64>, &[f64])>,
        x_next: &mut [f64],
        lambda_next: &mut [f64],
        outputs: Outputs,
    ) {
        let (nx, nu, nc, ny) = (self.nx, self.nu, self.nc, self.ny);
        let all = outputs == Outputs::All;
        if nu + nc > 0 {
            let ff = col_of(&self.gains, 0);
            let fb = self.gains.as_ref().submatrix(0, 1, nu + nc, nx);
            u.copy_from_slice(&ff[..nu]);
            matvec(u, Accum::Add, fb.subrows(0, nu), x, 1.0);
            if all {
                nu_out.copy_from_slice(&ff[nu..]);
                matvec(nu_out, Accum::Add, fb.subrows(nu, nc), x, 1.0);
            }
        }
        if ny == 0 {
            return;
        }
        let (P_next, p_next) = next.expect("a knot with dynamics has a next value function");
        // z = Ã x + B̃ u + f̃ (in x_next).
        let (a, b) = ab_of(self.e_fac.is_minus_identity(), &self.ab_tilde, knot);
        x_next.copy_from_slice(slice(&self.f_tilde));
        matvec(x_next, Accum::Add, a, x, 1.0);
        matvec(x_next, Accum::Add, b, u, 1.0);
        if !all && self.mu_dyn == 0.0 {
            return; // x_{t+1} = z.
        }
        // λ̃ = P̃ z + p̃ (in lambda_next).
        let (pt, pt_vec) = if self.mu_dyn > 0.0 {
            (self.ptilde.as_ref(), slice(&self.ptilde_vec))
        } else {
            (P_next, p_next)
        };
        lambda_next.copy_from_slice(pt_vec);
        matvec(lambda_next, Accum::Add, pt, x_next, 1.0);
        // x_{t+1} = z - G λ̃.
        if self.mu_dyn > 0.0 {
            if self.e_fac.is_minus_identity() {
                for i in 0..ny {
                    x_next[i] -= self.mu_dyn * lambda_next[i];
                }
            } else {
                matvec(x_next, Accum::Add, self.g.as_ref(), lambda_next, -1.0);
            }
        }
        // λ_{t+1} = -E⁻ᵀ λ̃.
        if all && !self.e_fac.is_minus_identity() {
            slice_mut(&mut self.w_y).copy_from_slice(lambda_next);
            self.e_fac.solve_transpose_in_place(self.w_y.as_mut().as_mat_mut());
            for i in 0..ny {
                lambda_next[i] = -self.w_y[i];
            }
        }
    }

    /// Every quantity of the vector part, in a fixed order.
    fn vector_part_mut(&mut self) -> [&mut [f64]; 10] {
        [
            slice_mut(&mut self.qvec),
            slice_mut(&mut self.f_tilde),
            slice_mut(&mut self.ptilde_vec),
            slice_mut(&mut self.v),
            col_of_mut(&mut self.gains, 0),
            slice_mut(&mut self.p),
            col_of_mut(&mut self.zg, 0),
            col_of_mut(&mut self.lg, 0),
            col_of_mut(&mut self.xg, 0),
            col_of_mut(&mut self.lamg, 0),
        ]
    }

    /// Saves the vector part (before a refinement pass overwrites it with a correction).
    pub(crate) fn save_vector_part(&mut self) {
        let mut saved = std::mem::take(&mut self.saved);
        let mut off = 0;
        for s in self.vector_part_mut() {
            saved[off..off + s.len()].copy_from_slice(s);
            off += s.len();
        }
        self.saved = saved;
    }

    /// Adds the saved vector part to the current one (a correction): the vector part
    /// becomes that of the refined solution.
    pub(crate) fn add_saved_vector_part(&mut self) {
        let saved = std::mem::take(&mut self.saved);
        let mut off = 0;
        for s in self.vector_part_mut() {
            let len = s.len();
            for (a, b) in s.iter_mut().zip(&saved[off..off + len]) {
                *a += b;
            }
            off += len;
        }
        self.saved = saved;
    }

    /// `[Q_xx Q_xu; Q_ux Q_uu]`, the Hessian of the Q-function (37d-f).
    pub fn q_hessian(&self) -> MatRef<'_, f64> {
        self.qmat.as_ref()
    }

    /// Adds `[H_xx H_xu; H_xuᵀ H_uu]` to the Q-function's Hessian after
    /// [`RiccatiSolver::backward_with`](super::RiccatiSolver::backward_with) computed it
    /// and before the control law factors it: second-order terms that depend on the next
    /// value function, such as classical DDP's `V_x'·f_xx` (Tassa et al. 2012).
    ///
    /// # Errors
    /// [`LqError::Dimension`] if a block does not have this stage's dimensions.
    pub fn add_q_hessian(
        &mut self,
        H_xx: MatRef<'_, f64>,
        H_xu: MatRef<'_, f64>,
        H_uu: MatRef<'_, f64>,
    ) -> Result<(), LqError> {
        let (nx, nu) = (self.nx, self.nu);
        for (field, m, shape) in [
            ("H_xx", H_xx, (nx, nx)),
            ("H_xu", H_xu, (nx, nu)),
            ("H_uu", H_uu, (nu, nu)),
        ] {
            if (m.nrows(), m.ncols()) != shape {
                return Err(LqError::Dimension {
                    knot: self.index,
                    field,
                    expected: shape,
                    got: (m.nrows(), m.ncols()),
                });
            }
        }
        let mut q = self.qmat.as_mut();
        for j in 0..nx {
            for i in 0..nx {
                q[(i, j)] += H_xx[(i, j)];
            }
        }
        for j in 0..nu {
            for i in 0..nx {
                q[(i, nx + j)] += H_xu[(i, j)];
                q[(nx + j, i)] += H_xu[(i, j)];
            }
            for i in 0..nu {
                q[(nx + i, nx + j)] += H_uu[(i, j)];
            }
        }
        Ok(())
    }

    /// `Q_xx` (`nx x nx`).
    pub fn Q_xx(&self) -> MatRef<'_, f64> {
        self.qmat.as_ref().submatrix(0, 0, self.nx, self.nx)
    }

    /// `Q_xu` (`nx x nu`).
    pub fn Q_xu(&self) -> MatRef<'_, f64> {
        self.qmat.as_ref().submatrix(0, self.nx, self.nx, self.nu)
    }

    /// `Q_uu` (`nu x nu`), without the primal regularisation.
    pub fn Q_uu(&self) -> MatRef<'_, f64> {
        self.qmat.as_ref().submatrix(self.nx, self.nx, self.nu, self.nu)
    }

    /// `Q_x` (`nx`).
    pub fn Q_x(&self) -> &[f64] {
        &slice(&self.qvec)[..self.nx]
    }

    /// `Q_u` (`nu`).
    pub fn Q_u(&self) -> &[f64] {
        &slice(&self.qvec)[self.nx..]
    }

    /// Value Hessian `P_t = V_xx`.
    pub fn P(&self) -> MatRef<'_, f64> {
        self.P.as_ref()
    }

    /// Value gradient `p_t = V_x`.
    pub fn p(&self) -> &[f64] {
        slice(&self.p)
    }

    /// Feedforward control gain `k`.
    pub fn k(&self) -> &[f64] {
        &col_of(&self.gains, 0)[..self.nu]
    }

    /// Feedback control gain `K` (`nu x nx`).
    pub fn K(&self) -> MatRef<'_, f64> {
        self.gains.as_ref().submatrix(0, 1, self.nu, self.nx)
    }

    /// Feedforward multiplier gain `ζ`.
    pub fn zeta(&self) -> &[f64] {
        &col_of(&self.gains, 0)[self.nu..]
    }

    /// Feedback multiplier gain `Z` (`nc x nx`).
    pub fn Z(&self) -> MatRef<'_, f64> {
        self.gains.as_ref().submatrix(self.nu, 1, self.nc, self.nx)
    }

    /// Gains `(c, C)` of the next state `x_{t+1} = c + C x_t` (50b), if enabled.
    pub fn x_next_gains(&self) -> Option<(&[f64], MatRef<'_, f64>)> {
        (self.extra == ExtraGains::Rollout)
            .then(|| (col_of(&self.xg, 0), self.xg.as_ref().submatrix(0, 1, self.ny, self.nx)))
    }

    /// Gains `(ξ, Ξ)` of the next co-state `λ_{t+1} = ξ + Ξ x_t` (50c), if enabled.
    pub fn lambda_next_gains(&self) -> Option<(&[f64], MatRef<'_, f64>)> {
        (self.extra == ExtraGains::Rollout).then(|| {
            (
                col_of(&self.lamg, 0),
                self.lamg.as_ref().submatrix(0, 1, self.ny, self.nx),
            )
        })
    }

    /// Whether `E` was exactly `-I` at the last Q-function.
    pub fn e_is_minus_identity(&self) -> bool {
        self.e_fac.is_minus_identity()
    }

    /// `B̃` (the knot's `B` when `E = -I`).
    pub(crate) fn b_tilde<'a>(&'a self, knot: &'a LqKnot) -> MatRef<'a, f64> {
        ab_of(self.e_fac.is_minus_identity(), &self.ab_tilde, knot).1
    }

    /// `Ã` (the knot's `A` when `E = -I`).
    pub(crate) fn a_tilde<'a>(&'a self, knot: &'a LqKnot) -> MatRef<'a, f64> {
        ab_of(self.e_fac.is_minus_identity(), &self.ab_tilde, knot).0
    }

    /// `f̃ = -E⁻¹f` of the last vector pass.
    pub(crate) fn f_tilde(&self) -> &[f64] {
        slice(&self.f_tilde)
    }

    /// `[t0 | T]`: the closed-loop `z = Ã x + B̃ u + f̃ = t0 + T x`.
    pub(crate) fn z_gains(&self) -> MatRef<'_, f64> {
        self.zg.as_ref()
    }

    /// `t0 = B̃k + f̃`.
    pub(crate) fn z_feedforward(&self) -> &[f64] {
        col_of(&self.zg, 0)
    }

    /// `p̃` (only when `mu_dyn > 0`).
    pub(crate) fn ptilde_vec(&self) -> &[f64] {
        slice(&self.ptilde_vec)
    }

    /// `mu_dyn` of the last Q-function.
    pub(crate) fn mu_dyn(&self) -> f64 {
        self.mu_dyn
    }

    /// `G` (only for a general `E` with `mu_dyn > 0`).
    pub(crate) fn g(&self) -> MatRef<'_, f64> {
        self.g.as_ref()
    }

    /// The results a square-root step ([`super::sqrt`]) writes: the Q-function, the gains,
    /// the value function and `f̃`; marks the knot as one with `E = -I` and `mu_dyn = 0`
    /// (the only knots that step accepts), so that the forward pass (50) reads it as such.
    pub(super) fn square_root_parts(&mut self) -> SquareRootParts<'_> {
        self.e_fac.mark_minus_identity();
        self.mu_dyn = 0.0;
        SquareRootParts {
            qmat: &mut self.qmat,
            qvec: &mut self.qvec,
            gains: &mut self.gains,
            P: &mut self.P,
            p: &mut self.p,
            f_tilde: &mut self.f_tilde,
        }
    }

    /// Names the offending input after a numerical failure of this knot.
    pub(crate) fn blame(&self, problem: &super::LqProblem, e: LqError) -> LqError {
        match e {
            LqError::NonFinite { .. } => blame(problem, self.index, e),
            _ => e,
        }
    }
}

/// The fields of a [`RiccatiStage`] that the square-root step writes.
pub(super) struct SquareRootParts<'a> {
    /// `[Q_xx Q_xu; Q_ux Q_uu]`.
    pub qmat: &'a mut Mat<f64>,
    /// `[Q_x; Q_u]`.
    pub qvec: &'a mut Col<f64>,
    /// `[k K; ζ Z]`.
    pub gains: &'a mut Mat<f64>,
    /// `P = V_xx`.
    pub P: &'a mut Mat<f64>,
    /// `p = V_x`.
    pub p: &'a mut Col<f64>,
    /// `f̃ = f` (`E = -I`).
    pub f_tilde: &'a mut Col<f64>,
}

/// The factorization of `M = I + P'G`: Cholesky of `M` (`E = -I`) or of its congruent
/// `I + mu E⁻ᵀP'E⁻¹` (`congruent`, general `E`) when possible, LU of `M` otherwise.
#[derive(Debug)]
struct ProxFactor {
    llt: Llt,
    lu: Lu,
    is_llt: bool,
    congruent: bool,
    /// Scratch for the products with `Eᵀ`.
    w: Mat<f64>,
}

impl ProxFactor {
    /// `X ← M⁻¹X`; with the congruent factor `M⁻¹ = Eᵀ (I + mu E⁻ᵀP'E⁻¹)⁻¹ E⁻ᵀ`.
    fn solve_in_place(&mut self, e: &mut EFactor, mut rhs: MatMut<'_, f64>) {
        if self.congruent {
            e.solve_transpose_in_place(rhs.rb_mut());
            self.llt.solve_in_place(rhs.rb_mut());
            e.mul_transpose_in_place(rhs, self.w.as_mut());
        } else if self.is_llt {
            self.llt.solve_in_place(rhs);
        } else {
            self.lu.solve_in_place(rhs);
        }
    }
}

/// The factorization of the stage KKT matrix: LDLᵀ, or Bunch-Kaufman with hard rows.
#[derive(Debug)]
struct KktFactor {
    ldlt: Ldlt,
    bk: BunchKaufman,
    use_bk: bool,
    /// Rows of the system in the LDLᵀ factorization when some are decoupled: the `nu`
    /// control rows and the constraint rows with a nonzero `D` row.
    coupled: Vec<usize>,
    /// The decoupled rows (constraint rows with `D` row zero and `mu_c > 0`) with their
    /// pivot `-mu_c`: `[K; Z]` on them is the right-hand side divided by the pivot.
    free: Vec<(usize, f64)>,
    /// The coupled rows of a right-hand side, gathered (by rows for the small
    /// factorizations, by columns for faer's).
    gather: Vec<f64>,
    /// Right-hand side columns the gather buffer holds.
    max_rhs: usize,
}

impl KktFactor {
    /// For `nu` controls, `nc` constraint rows and right-hand sides of up to `max_rhs`
    /// columns.
    fn new(nu: usize, nc: usize, max_rhs: usize) -> Self {
        let nk = nu + nc;
        Self {
            ldlt: Ldlt::new(nk),
            bk: BunchKaufman::with_max_rhs(nk, max_rhs),
            use_bk: false,
            coupled: Vec::with_capacity(nk),
            free: Vec::with_capacity(nc),
            gather: vec![0.0; nk * max_rhs],
            max_rhs,
        }
    }

    /// Whether the LDLᵀ path factors the `nu` control rows alone (every constraint row
    /// decoupled).
    fn controls_alone(&self, nu: usize) -> bool {
        !self.use_bk && self.coupled.len() == nu
    }

    /// Sorts the rows of the LDLᵀ path into coupled and decoupled ones (none decoupled
    /// with Bunch-Kaufman, for rows with `mu_c = 0`).
    fn partition(&mut self, knot: &LqKnot) {
        let (nu, nc) = (knot.nu, knot.nc);
        self.coupled.clear();
        self.free.clear();
        self.coupled.extend(0..nu);
        for i in 0..nc {
            let decoupled = !self.use_bk && (0..nu).all(|j| knot.D[(i, j)] == 0.0);
            if decoupled {
                self.free.push((nu + i, -knot.mu_c[i]));
            } else {
                self.coupled.push(nu + i);
            }
        }
        // All rows when none decouples (`coupled` then holds them in order).
        self.ldlt.set_dim(self.coupled.len());
    }

    /// Solves the factored system in place for the columns of `rhs` (at most
    /// `max_rhs`): the coupled rows through the LDLᵀ factorization (in place when they
    /// are the first rows: all of them, or the controls' when no constraint row couples),
    /// the decoupled ones divided by their pivots.
    fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        if self.use_bk {
            self.bk.solve_in_place(rhs);
            return;
        }
        let (m, c) = (self.coupled.len(), rhs.ncols());
        if self.coupled.last().is_none_or(|&r| r + 1 == m) {
            self.ldlt.solve_in_place(rhs.rb_mut().subrows_mut(0, m));
        } else {
            self.solve_gathered(rhs.rb_mut());
        }
        for j in 0..c {
            let dst = linalg::col_slice_mut(rhs.rb_mut(), j);
            for &(r, pivot) in &self.free {
                dst[r] /= pivot;
            }
        }
    }

    /// The coupled rows of [`KktFactor::solve_in_place`] when they are not the first:
    /// gathered, solved and scattered back.
    fn solve_gathered(&mut self, mut rhs: MatMut<'_, f64>) {
        let (m, c) = (self.coupled.len(), rhs.ncols());
        let g = &mut self.gather[..m * c];
        if m <= linalg::SMALL_DIM {
            // By rows (the gather transposes anyway): the row-wise solve vectorises
            // across the columns.
            for j in 0..c {
                let src = linalg::col_slice_mut(rhs.rb_mut(), j);
                for (a, &r) in self.coupled.iter().enumerate() {
                    g[a * c + j] = src[r];
                }
            }
            self.ldlt.solve_rows_in_place(g, c);
            for j in 0..c {
                let dst = linalg::col_slice_mut(rhs.rb_mut(), j);
                for (a, &r) in self.coupled.iter().enumerate() {
                    dst[r] = g[a * c + j];
                }
            }
        } else {
            for j in 0..c {
                let src = linalg::col_slice_mut(rhs.rb_mut(), j);
                for (d, &r) in g[j * m..(j + 1) * m].iter_mut().zip(&self.coupled) {
                    *d = src[r];
                }
            }
            self.ldlt.solve_in_place(MatMut::from_column_major_slice_mut(g, m, c));
            for j in 0..c {
                let dst = linalg::col_slice_mut(rhs.rb_mut(), j);
                for (s, &r) in g[j * m..(j + 1) * m].iter().zip(&self.coupled) {
                    dst[r] = *s;
                }
            }
        }
    }
}

/// `dst -= G src` with `G = mu_dyn E⁻¹E⁻ᵀ` (`mu_dyn I` when `E = -I`).
fn sub_g_times(
    mu_dyn: f64,
    e_minus_identity: bool,
    g: MatRef<'_, f64>,
    mut dst: MatMut<'_, f64>,
    src: MatRef<'_, f64>,
) {
    if mu_dyn == 0.0 {
        return;
    }
    if e_minus_identity {
        for j in 0..dst.ncols() {
            for i in 0..dst.nrows() {
                dst[(i, j)] -= mu_dyn * src[(i, j)];
            }
        }
    } else {
        matmul(dst, Accum::Add, g, src, -1.0);
    }
}
