//! [`BunchKaufman`]: `P A Pᵀ = L B Lᵀ` with rook pivoting, for any symmetric matrix.

use faer::diag::{DiagMut, DiagRef};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::lblt as bunch_kaufman;
use faer::perm::PermRef;
use faer::{Col, Mat, MatMut, MatRef, Par};

use super::copy::copy_lower;
use super::reduce::lower_sum_is_finite;
use super::views::{slice, slice_mut};
use super::{FactorError, Inertia, stack_buffer};

/// `P A Pᵀ = L B Lᵀ` (Bunch-Kaufman, rook pivoting) for any symmetric matrix, including
/// singular-regularised saddle points; gives the inertia from the 1x1 / 2x2 blocks of `B`.
pub(crate) struct BunchKaufman {
    factors: Mat<f64>,
    subdiag: Col<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    buf: MemBuffer,
    max_rhs: usize,
}

impl std::fmt::Debug for BunchKaufman {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BunchKaufman").field("dim", &self.dim()).finish()
    }
}

impl BunchKaufman {
    /// Allocates a factorization of dimension `n` whose solves take up to `max(n, 1)`
    /// right-hand sides.
    #[cfg(test)]
    pub fn new(n: usize) -> Self {
        Self::with_max_rhs(n, n)
    }

    /// Allocates a factorization of dimension `n` whose solves take up to `max_rhs`
    /// right-hand sides (at least 1).
    pub fn with_max_rhs(n: usize, max_rhs: usize) -> Self {
        let params = Self::params();
        let req = bunch_kaufman::factor::cholesky_in_place_scratch::<usize, f64>(n, Par::Seq, params).or(
            bunch_kaufman::solve::solve_in_place_scratch::<usize, f64>(n, max_rhs.max(1), Par::Seq),
        );
        Self {
            factors: Mat::zeros(n, n),
            subdiag: Col::zeros(n),
            perm: vec![0; n],
            perm_inv: vec![0; n],
            buf: stack_buffer(req),
            max_rhs: max_rhs.max(1),
        }
    }

    fn params() -> faer::Spec<bunch_kaufman::factor::LbltParams, f64> {
        let mut p: faer::Spec<bunch_kaufman::factor::LbltParams, f64> = Default::default();
        p.config.pivoting = bunch_kaufman::factor::PivotingStrategy::Rook;
        p
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.factors.nrows()
    }

    /// Factors the lower triangle of `a` and returns its inertia. Eigenvalues of the
    /// block-diagonal factor below `zero_tol * max|B|` in magnitude count as zero.
    pub fn factor(&mut self, a: MatRef<'_, f64>, zero_tol: f64) -> Result<Inertia, FactorError> {
        debug_assert_eq!((a.nrows(), a.ncols()), (self.dim(), self.dim()));
        copy_lower(self.factors.as_mut(), a);
        self.factor_filled(zero_tol)
    }

    /// The storage of the matrix to factor: write its lower triangle here, then call
    /// [`factor_filled`](Self::factor_filled) (saves a copy).
    pub fn matrix_mut(&mut self) -> MatMut<'_, f64> {
        self.factors.as_mut()
    }

    /// Factors the lower triangle written through [`matrix_mut`](Self::matrix_mut); see
    /// [`factor`](Self::factor).
    pub fn factor_filled(&mut self, zero_tol: f64) -> Result<Inertia, FactorError> {
        let n = self.dim();
        if !lower_sum_is_finite(self.factors.as_ref()) {
            return Err(FactorError::NonFinite);
        }
        // faer writes the subdiagonal of the 2x2 pivots only: a zero marks a 1x1 pivot
        // (below and in the solve), so the entries of an earlier factorization go.
        self.subdiag.fill(0.0);
        let stack = MemStack::new(&mut self.buf);
        bunch_kaufman::factor::cholesky_in_place(
            self.factors.as_mut(),
            DiagMut::from_slice_mut(slice_mut(&mut self.subdiag)),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            stack,
            Self::params(),
        );
        // Eigenvalues of the 1x1 and 2x2 diagonal blocks.
        let eig = |lam: f64, scale: f64, inertia: &mut Inertia| {
            if !lam.is_finite() {
                return Err(FactorError::NonFinite);
            }
            if lam.abs() <= zero_tol * scale {
                inertia.zero += 1;
            } else if lam > 0.0 {
                inertia.positive += 1;
            } else {
                inertia.negative += 1;
            }
            Ok(())
        };
        let mut scale: f64 = 0.0;
        for i in 0..n {
            scale = scale.max(self.factors[(i, i)].abs()).max(self.subdiag[i].abs());
        }
        let mut inertia = Inertia::default();
        let mut i = 0;
        while i < n {
            let s = if i + 1 < n { self.subdiag[i] } else { 0.0 };
            if s != 0.0 {
                let (a11, a22) = (self.factors[(i, i)], self.factors[(i + 1, i + 1)]);
                let mean = 0.5 * (a11 + a22);
                let rad = (0.25 * (a11 - a22) * (a11 - a22) + s * s).sqrt();
                eig(mean + rad, scale, &mut inertia)?;
                eig(mean - rad, scale, &mut inertia)?;
                i += 2;
            } else {
                eig(self.factors[(i, i)], scale, &mut inertia)?;
                i += 1;
            }
        }
        Ok(inertia)
    }

    /// Solves `A X = B` in place; `rhs` has at most `max_rhs` columns (see
    /// [`with_max_rhs`](Self::with_max_rhs)).
    pub fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        debug_assert!(rhs.ncols() <= self.max_rhs);
        let n = self.dim();
        let stack = MemStack::new(&mut self.buf);
        let perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let f = self.factors.as_ref();
        bunch_kaufman::solve::solve_in_place(
            f,
            f.diagonal(),
            DiagRef::from_slice(slice(&self.subdiag)),
            perm,
            rhs,
            Par::Seq,
            stack,
        );
    }
}
