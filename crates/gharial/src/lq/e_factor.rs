//! The factorization of a knot's dynamics matrix `E` (step 1 of the recursion), which
//! uses that `E` is `-I` outside a leading principal block in the common cases.
//!
//! For explicit dynamics `f = φ(x, u) ⊖ y` on a product of a Lie group and vector spaces
//! (a free-flyer robot's phase space), `E = ∂(φ ⊖ y)/∂y` is the Jacobian of the group part
//! in its leading block and exactly `-I` on the vector-space coordinates. With the
//! smallest `k` such that `E = diag(E_b, -I)`, `E_b` of size `k × k`, only `E_b` is
//! factored and every product or solve with `E` costs `O(k²)` per column instead of
//! `O(ny²)`; `k = 0` is `E = -I`, `k = ny` a general `E`.

use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef};

use crate::linalg::{self, FactorError, Lu, SMALL_DIM, identity_block, matmul};

/// `E = diag(E_b, -I)` factored through `E_b` (module documentation).
#[derive(Debug)]
pub(crate) struct EFactor {
    /// Size of the leading block `E_b`.
    k: usize,
    /// `E_b` (in the leading `k × k` corner), for products with `Eᵀ`.
    block: Mat<f64>,
    /// `-E_b⁻¹` (leading `k × k` corner) when `k <= SMALL_DIM`: the solves are then
    /// products, a few multiply-adds per column in registers (the Riccati stage solves
    /// with all `nx + nu` columns of `[A B]`), where a blocked triangular solve spends
    /// most of its time outside the arithmetic.
    neg_inv: Mat<f64>,
    /// `-E_b⁻ᵀ`, stored for the same products.
    neg_inv_t: Mat<f64>,
    /// `E_b⁻¹E_b⁻ᵀ` scratch (leading `k × k` corner).
    inv: Mat<f64>,
    lu: Lu,
    /// Scratch: a copy of the right-hand side's block rows (`ny × max_rhs`), and the
    /// row-major rows of the solve that forms `-E_b⁻¹` (`ny²`).
    top: Mat<f64>,
    rows: Vec<f64>,
}

impl EFactor {
    /// Storage for matrices `E` up to `ny × ny`, solved with up to `max_rhs` columns.
    pub(crate) fn new(ny: usize, max_rhs: usize) -> Self {
        let max_rhs = max_rhs.max(ny).max(1);
        Self {
            k: 0,
            block: Mat::zeros(ny, ny),
            neg_inv: Mat::zeros(ny.min(SMALL_DIM), ny.min(SMALL_DIM)),
            neg_inv_t: Mat::zeros(ny.min(SMALL_DIM), ny.min(SMALL_DIM)),
            inv: Mat::zeros(ny, ny),
            lu: Lu::new(ny, max_rhs),
            top: Mat::zeros(ny.min(SMALL_DIM), max_rhs),
            rows: vec![0.0; ny.min(SMALL_DIM).pow(2)],
        }
    }

    /// Whether the last `E` factored was exactly `-I`.
    pub(crate) fn is_minus_identity(&self) -> bool {
        self.k == 0
    }

    /// Records `E = -I` without a factorization (knots whose step was computed elsewhere,
    /// as the square-root pass's).
    pub(crate) fn mark_minus_identity(&mut self) {
        self.k = 0;
    }

    /// Factors `e` (nothing to factor when `e = -I`; the vectorised exact test first,
    /// the block search only for other `E`), and forms `-E_b⁻¹` for small blocks.
    pub(crate) fn factor(&mut self, e: MatRef<'_, f64>) -> Result<(), FactorError> {
        self.k = if super::is_minus_identity(e) {
            0
        } else {
            identity_block(e, -1.0)
        };
        let k = self.k;
        if k == 0 {
            return Ok(());
        }
        let e_b = e.submatrix(0, 0, k, k);
        linalg::copy(self.block.as_mut().submatrix_mut(0, 0, k, k), e_b);
        self.lu.factor(e_b)?;
        if self.small() {
            let mut n = self.neg_inv.as_mut().submatrix_mut(0, 0, k, k);
            crate::spaces::set_identity(n.rb_mut(), 1.0);
            self.lu.solve_rows_in_place(n.rb_mut(), -1.0, &mut self.rows);
            linalg::copy_transposed(self.neg_inv_t.as_mut().submatrix_mut(0, 0, k, k), n.as_ref());
        }
        Ok(())
    }

    /// Whether `-E_b⁻¹` is formed.
    fn small(&self) -> bool {
        self.k <= SMALL_DIM
    }

    /// `X ← -E⁻¹X = diag(-E_b⁻¹, I) X`: the rows past the block stay as they are.
    pub(crate) fn neg_solve_in_place(&mut self, x: MatMut<'_, f64>) {
        let k = self.k;
        if k == 0 {
            return;
        }
        let mut x_b = x.subrows_mut(0, k);
        if !self.small() {
            self.lu.solve_in_place(x_b.rb_mut());
            return linalg::negate(x_b);
        }
        self.apply_small_inverse(x_b, false, 1.0);
    }

    /// `X ← E⁻ᵀX = diag(E_b⁻ᵀ, -I) X`.
    pub(crate) fn solve_transpose_in_place(&mut self, mut x: MatMut<'_, f64>) {
        let k = self.k;
        let rest = x.nrows() - k;
        linalg::negate(x.rb_mut().subrows_mut(k, rest));
        if k == 0 {
            return;
        }
        let x_b = x.subrows_mut(0, k);
        if !self.small() {
            return self.lu.solve_transpose_in_place(x_b);
        }
        self.apply_small_inverse(x_b, true, -1.0);
    }

    /// `X_b ← alpha (-E_b⁻¹) X_b` (or `-E_b⁻ᵀ` with `transposed`) for small blocks, on
    /// a copy of `X_b` in the scratch.
    fn apply_small_inverse(&mut self, x_b: MatMut<'_, f64>, transposed: bool, alpha: f64) {
        let (k, m) = (self.k, x_b.ncols());
        let mut top = self.top.as_mut().submatrix_mut(0, 0, k, m);
        linalg::copy(top.rb_mut(), x_b.as_ref());
        let n = if transposed { &self.neg_inv_t } else { &self.neg_inv };
        linalg::matmul_loops(x_b, n.as_ref().submatrix(0, 0, k, k), top.as_ref(), alpha);
    }

    /// `X ← EᵀX`; `w` is scratch of at least `k` rows and `X`'s columns.
    pub(crate) fn mul_transpose_in_place(&self, mut x: MatMut<'_, f64>, mut w: MatMut<'_, f64>) {
        let (k, n) = (self.k, x.ncols());
        let rest = x.nrows() - k;
        linalg::negate(x.rb_mut().subrows_mut(k, rest));
        if k > 0 {
            let mut w = w.rb_mut().submatrix_mut(0, 0, k, n);
            linalg::copy(w.rb_mut(), x.as_ref().subrows(0, k));
            let e_b = self.block.as_ref().submatrix(0, 0, k, k);
            matmul(x.subrows_mut(0, k), Accum::Replace, e_b.transpose(), w.as_ref(), 1.0);
        }
    }

    /// `G = mu E⁻¹E⁻ᵀ = mu diag(E_b⁻¹E_b⁻ᵀ, I)` into `g` (`ny × ny`).
    pub(crate) fn inverse_gram(&mut self, mu: f64, mut g: MatMut<'_, f64>) {
        let k = self.k;
        g.fill(0.0);
        for i in 0..g.nrows() {
            g[(i, i)] = mu;
        }
        if k == 0 {
            return;
        }
        if self.small() {
            // E_b⁻¹E_b⁻ᵀ = (-E_b⁻¹)(-E_b⁻¹)ᵀ.
            let n = self.neg_inv.as_ref().submatrix(0, 0, k, k);
            return matmul(g.submatrix_mut(0, 0, k, k), Accum::Replace, n, n.transpose(), mu);
        }
        let mut inv = self.inv.as_mut().submatrix_mut(0, 0, k, k);
        inv.fill(0.0);
        for i in 0..k {
            inv[(i, i)] = 1.0;
        }
        self.lu.solve_in_place(inv.rb_mut());
        let inv = self.inv.as_ref().submatrix(0, 0, k, k);
        matmul(g.submatrix_mut(0, 0, k, k), Accum::Replace, inv, inv.transpose(), mu);
    }
}
