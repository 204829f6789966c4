//! [`Lu`]: `P A = L U` with partial pivoting, for general square matrices.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting as lu;
use faer::perm::PermRef;
use faer::prelude::ReborrowMut;
use faer::{Mat, MatMut, MatRef, Par};

use super::reduce::all_finite;
use super::{FactorError, stack_buffer};

/// `P A = L U` with partial pivoting, for general square matrices of any dimension up to
/// the capacity given to [`Lu::new`].
pub struct Lu {
    /// Dimension of the last matrix factored.
    n: usize,
    factors: Mat<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    buf: MemBuffer,
    max_rhs: usize,
}

impl std::fmt::Debug for Lu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lu").field("dim", &self.dim()).finish()
    }
}

impl Lu {
    /// Allocates a factorization of matrices up to dimension `n` (`n` until another is
    /// factored), whose solves take up to `max_rhs` columns.
    pub fn new(n: usize, max_rhs: usize) -> Self {
        let req = lu::factor::lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default())
            .or(lu::solve::solve_in_place_scratch::<usize, f64>(
                n,
                max_rhs.max(1),
                Par::Seq,
            ))
            .or(lu::solve::solve_transpose_in_place_scratch::<usize, f64>(
                n,
                max_rhs.max(1),
                Par::Seq,
            ));
        Self {
            n,
            factors: Mat::zeros(n, n),
            perm: vec![0; n],
            perm_inv: vec![0; n],
            buf: stack_buffer(req),
            max_rhs: max_rhs.max(1),
        }
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Factors the square matrix `a` (of at most the capacity's dimension); fails if a
    /// pivot is exactly zero or not finite.
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<(), FactorError> {
        let n = a.nrows();
        debug_assert!(n == a.ncols() && n <= self.factors.nrows());
        if !all_finite(a) {
            return Err(FactorError::NonFinite);
        }
        self.n = n;
        let mut factors = self.factors.as_mut().submatrix_mut(0, 0, n, n);
        factors.copy_from(a);
        let stack = MemStack::new(&mut self.buf);
        lu::factor::lu_in_place(
            factors.rb_mut(),
            &mut self.perm[..n],
            &mut self.perm_inv[..n],
            Par::Seq,
            stack,
            Default::default(),
        );
        for i in 0..n {
            let p = self.factors[(i, i)];
            if p == 0.0 || !p.is_finite() {
                return Err(FactorError::Singular { index: i });
            }
        }
        Ok(())
    }

    /// Solves `A X = B` in place (`rhs` has at most `max_rhs` columns).
    pub fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        debug_assert!(rhs.ncols() <= self.max_rhs);
        let n = self.dim();
        let stack = MemStack::new(&mut self.buf);
        let perm = PermRef::new_checked(&self.perm[..n], &self.perm_inv[..n], n);
        let f = self.factors.as_ref().submatrix(0, 0, n, n);
        lu::solve::solve_in_place(f, f, perm, rhs, Par::Seq, stack);
    }

    /// Solves `Aᵀ X = B` in place (`rhs` has at most `max_rhs` columns).
    pub fn solve_transpose_in_place(&mut self, rhs: MatMut<'_, f64>) {
        debug_assert!(rhs.ncols() <= self.max_rhs);
        let n = self.dim();
        let stack = MemStack::new(&mut self.buf);
        let perm = PermRef::new_checked(&self.perm[..n], &self.perm_inv[..n], n);
        let f = self.factors.as_ref().submatrix(0, 0, n, n);
        lu::solve::solve_transpose_in_place(f, f, perm, rhs, Par::Seq, stack);
    }
}
