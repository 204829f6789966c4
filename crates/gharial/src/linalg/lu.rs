//! [`Lu`]: `P A = L U` with partial pivoting, for general square matrices.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting as lu;
use faer::perm::PermRef;
use faer::prelude::ReborrowMut;
use faer::{Mat, MatMut, MatRef, Par};

use super::matvec::axpy;
use super::reduce::all_finite;
use super::views::{col_slice, col_slice_mut};
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

    /// Solves `A X = B` in place and scales, `B ← scale · A⁻¹B`, by rows (`B` column-major):
    /// the rows of `B` are gathered in pivot order into `rows` (row-major scratch of at
    /// least `n` times `B`'s columns), the two substitutions run on whole rows (vectorised
    /// across the columns) and the scaled rows are written back. The same arithmetic as the
    /// textbook column solve; for small factors with many columns, where faer's blocked
    /// solve spends most of its time outside the arithmetic.
    pub fn solve_rows_in_place(&self, mut rhs: MatMut<'_, f64>, scale: f64, rows: &mut [f64]) {
        let (n, m) = (self.dim(), rhs.ncols());
        debug_assert!(rhs.nrows() == n && rhs.row_stride() == 1);
        let rows = &mut rows[..n * m];
        let perm = &self.perm[..n];
        for c in 0..m {
            let col = col_slice(rhs.as_ref(), c);
            for (i, &p) in perm.iter().enumerate() {
                rows[i * m + c] = col[p];
            }
        }
        let f = &self.factors;
        // L y = P b (L unit lower triangular), row i minus the rows above it.
        for i in 1..n {
            let (done, rest) = rows.split_at_mut(i * m);
            for (j, yj) in done.chunks_exact(m).enumerate() {
                axpy(&mut rest[..m], -f[(i, j)], yj);
            }
        }
        // U x = y, from the last row up.
        for i in (0..n).rev() {
            let (head, below) = rows.split_at_mut((i + 1) * m);
            let xi = &mut head[i * m..];
            for (j, xj) in below.chunks_exact(m).enumerate() {
                axpy(xi, -f[(i, i + 1 + j)], xj);
            }
            let d = f[(i, i)];
            xi.iter_mut().for_each(|v| *v /= d);
        }
        for c in 0..m {
            let col = col_slice_mut(rhs.rb_mut(), c);
            for (i, v) in col.iter_mut().enumerate() {
                *v = scale * rows[i * m + c];
            }
        }
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
