//! [`Llt`]: `A = L Lᵀ` for symmetric positive-definite matrices.

#[cfg(test)]
use faer::MatRef;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::prelude::ReborrowMut;
use faer::{Mat, MatMut, Par};

#[cfg(test)]
use super::copy::copy_lower;
use super::reduce::lower_sum_is_finite;
use super::small::{llt_solve_fixed, small_factor};
use super::{FactorError, stack_buffer};

/// `A = L Lᵀ` for symmetric positive-definite matrices.
pub(crate) struct Llt {
    factors: Mat<f64>,
    buf: MemBuffer,
}

impl std::fmt::Debug for Llt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Llt").field("dim", &self.dim()).finish()
    }
}

impl Llt {
    /// Allocates a factorization of dimension `n`.
    pub fn new(n: usize) -> Self {
        let req = llt::factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default());
        Self {
            factors: Mat::zeros(n, n),
            buf: stack_buffer(req),
        }
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.factors.nrows()
    }

    /// Factors the lower triangle of `a`; fails on a non-positive pivot.
    #[cfg(test)]
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<(), FactorError> {
        debug_assert_eq!((a.nrows(), a.ncols()), (self.dim(), self.dim()));
        copy_lower(self.factors.as_mut(), a);
        self.factor_filled()
    }

    /// The storage of the matrix to factor: write its lower triangle here, then call
    /// [`factor_filled`](Self::factor_filled) (saves a copy).
    pub fn matrix_mut(&mut self) -> MatMut<'_, f64> {
        self.factors.as_mut()
    }

    /// Factors the lower triangle written through [`matrix_mut`](Self::matrix_mut); fails
    /// on a non-positive pivot.
    pub fn factor_filled(&mut self) -> Result<(), FactorError> {
        let n = self.dim();
        if !lower_sum_is_finite(self.factors.as_ref()) {
            return Err(FactorError::NonFinite);
        }
        if let Some(res) = with_small_dim!(n, small_factor, (self.factors.as_mut(), true)) {
            return res;
        }
        let stack = MemStack::new(&mut self.buf);
        match llt::factor::cholesky_in_place(
            self.factors.as_mut(),
            Default::default(),
            Par::Seq,
            stack,
            Default::default(),
        ) {
            Ok(_) => Ok(()),
            Err(llt::factor::LltError::NonPositivePivot { index }) => Err(FactorError::Singular { index }),
        }
    }

    /// The lower-triangular factor `L` (upper triangle is unspecified).
    #[cfg(test)]
    pub fn l(&self) -> MatRef<'_, f64> {
        self.factors.as_ref()
    }

    /// Solves `A X = B` in place.
    pub fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        let n = self.dim();
        if with_small_dim!(n, llt_solve_fixed, (self.factors.as_ref(), rhs.rb_mut())).is_some() {
            return;
        }
        let stack = MemStack::new(&mut self.buf);
        llt::solve::solve_in_place(self.factors.as_ref(), rhs, Par::Seq, stack);
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::Llt;
    use crate::linalg::FactorError;
    use crate::linalg::tests::{assert_solves_system, filled, naive, spd};

    #[test]
    fn llt_small_and_blocked_paths_solve_strided_right_hand_sides() {
        for n in [1usize, 2, 5, 8, 11, 12, 13, 20] {
            let a = spd(n, 7 + n as u64);
            let mut f = Llt::new(n);
            f.factor(a.as_ref()).unwrap();
            // L Lᵀ reproduces the lower triangle of A.
            let l = Mat::from_fn(n, n, |i, j| if i >= j { f.l()[(i, j)] } else { 0.0 });
            let llt = naive(l.as_ref(), l.transpose());
            for j in 0..n {
                for i in j..n {
                    assert!((llt[(i, j)] - a[(i, j)]).abs() < 1e-12, "n {n}: ({i}, {j})");
                }
            }
            for cols in [1, 3, 8] {
                let b = filled(n, cols, cols + n);
                assert_solves_system(|m| f.solve_in_place(m), a.as_ref(), &b, cols, 1e-10);
            }
        }
        let mut f = Llt::new(3);
        let mut a = spd(3, 1);
        a[(2, 2)] = -a[(2, 2)];
        a[(2, 1)] = 0.0;
        a[(2, 0)] = 0.0;
        assert_eq!(f.factor(a.as_ref()), Err(FactorError::Singular { index: 2 }));
    }
}
