//! [`Ldlt`]: `A = L D Lᵀ` without pivoting, for symmetric quasi-definite matrices.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt;
use faer::prelude::ReborrowMut;
use faer::{Mat, MatMut, MatRef, Par};

#[cfg(test)]
use super::copy::copy_lower;
use super::reduce::{dot, lower_sum_is_finite};
use super::small::{ldlt_solve_fixed, small_factor};
use super::{FactorError, Inertia, stack_buffer};

/// Largest dimension of the vector LDLᵀ solve kernel.
const MAX_SOLVE_DIM: usize = 64;

/// `A = L D Lᵀ` without pivoting, for symmetric quasi-definite matrices such as the
/// regularised stage KKT blocks `[[R, Dᵀ], [D, -mu I]]`.
pub(crate) struct Ldlt {
    factors: Mat<f64>,
    /// The dimension in use (at most the allocated one): the leading block of `factors`.
    n: usize,
    buf: MemBuffer,
    scratch: Vec<f64>,
}

impl std::fmt::Debug for Ldlt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ldlt").field("dim", &self.dim()).finish()
    }
}

impl Ldlt {
    /// Allocates a factorization of dimension `n`.
    pub fn new(n: usize) -> Self {
        let req = ldlt::factor::cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default());
        Self {
            factors: Mat::zeros(n, n),
            n,
            buf: stack_buffer(req),
            scratch: vec![0.0; n],
        }
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Uses the leading `n × n` block of the storage from now on (`n` at most the
    /// dimension allocated by [`Ldlt::new`]); allocates nothing.
    pub fn set_dim(&mut self, n: usize) {
        assert!(
            n <= self.factors.nrows(),
            "Ldlt::set_dim beyond the allocated dimension"
        );
        self.n = n;
    }

    /// The leading block in use.
    fn active(&self) -> MatRef<'_, f64> {
        self.factors.as_ref().submatrix(0, 0, self.n, self.n)
    }

    /// The leading block in use, mutable.
    fn active_mut(&mut self) -> MatMut<'_, f64> {
        self.factors.as_mut().submatrix_mut(0, 0, self.n, self.n)
    }

    /// Factors the lower triangle of `a` and returns the inertia read off `D`.
    #[cfg(test)]
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<Inertia, FactorError> {
        debug_assert_eq!((a.nrows(), a.ncols()), (self.dim(), self.dim()));
        copy_lower(self.active_mut(), a);
        self.factor_filled()
    }

    /// The storage of the matrix to factor: write its lower triangle here, then call
    /// [`factor_filled`](Self::factor_filled) (saves a copy).
    pub fn matrix_mut(&mut self) -> MatMut<'_, f64> {
        self.active_mut()
    }

    /// Factors the lower triangle written through [`matrix_mut`](Self::matrix_mut) and
    /// returns the inertia read off `D`.
    pub fn factor_filled(&mut self) -> Result<Inertia, FactorError> {
        let n = self.dim();
        if !lower_sum_is_finite(self.active()) {
            return Err(FactorError::NonFinite);
        }
        if let Some(res) = with_small_dim!(n, small_factor, (self.active_mut(), false)) {
            res?;
        } else {
            let stack = MemStack::new(&mut self.buf);
            let f = self.factors.as_mut().submatrix_mut(0, 0, n, n);
            match ldlt::factor::cholesky_in_place(f, Default::default(), Par::Seq, stack, Default::default()) {
                Ok(_) => {}
                Err(ldlt::factor::LdltError::ZeroPivot { index }) => return Err(FactorError::Singular { index }),
            }
        }
        let mut inertia = Inertia::default();
        for i in 0..n {
            let d = self.factors[(i, i)];
            if !d.is_finite() {
                return Err(FactorError::NonFinite);
            }
            if d > 0.0 {
                inertia.positive += 1;
            } else if d < 0.0 {
                inertia.negative += 1;
            } else {
                inertia.zero += 1;
            }
        }
        Ok(inertia)
    }

    /// The diagonal `D` of the last factorization.
    #[cfg(test)]
    pub fn d(&self, i: usize) -> f64 {
        self.factors[(i, i)]
    }

    /// Solves `A X = B` in place (`rhs` holds `B` on entry, `X` on exit).
    pub fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        let n = self.dim();
        if with_small_dim!(n, ldlt_solve_fixed, (self.active(), rhs.rb_mut())).is_some() {
            return;
        }
        if rhs.ncols() <= 2 && n <= MAX_SOLVE_DIM {
            // Column by column with slices: faer's blocked solve costs more for few columns.
            let mut l: [&[f64]; MAX_SOLVE_DIM] = [&[]; MAX_SOLVE_DIM];
            for (j, lj) in l.iter_mut().enumerate().take(n) {
                *lj = &self
                    .factors
                    .col(j)
                    .try_as_col_major()
                    .expect("owned storage")
                    .as_slice()[j + 1..];
            }
            let l = &l[..n];
            for c in 0..rhs.ncols() {
                let mut col = rhs.rb_mut().col_mut(c);
                match col.rb_mut().try_as_col_major_mut() {
                    Some(x) => ldlt_solve_vec(l, self.factors.as_ref(), x.as_slice_mut()),
                    None => {
                        let x = &mut self.scratch[..n];
                        (0..n).for_each(|i| x[i] = col[i]);
                        ldlt_solve_vec(l, self.factors.as_ref(), x);
                        (0..n).for_each(|i| col[i] = x[i]);
                    }
                }
            }
            return;
        }
        let stack = MemStack::new(&mut self.buf);
        let f = self.factors.as_ref().submatrix(0, 0, n, n);
        ldlt::solve::solve_in_place(f, f.diagonal(), rhs, Par::Seq, stack);
    }
}

/// Solves `L D Lᵀ x = b` in place for one vector; `l[j]` is column `j` of `L` below the
/// diagonal and `f` holds `D` on its diagonal (faer's storage).
fn ldlt_solve_vec(l: &[&[f64]], f: MatRef<'_, f64>, x: &mut [f64]) {
    let n = x.len();
    for j in 0..n {
        let xj = x[j];
        if xj != 0.0 {
            for (xi, li) in x[j + 1..].iter_mut().zip(l[j]) {
                *xi -= li * xj;
            }
        }
    }
    for (j, xj) in x.iter_mut().enumerate() {
        *xj /= f[(j, j)];
    }
    for j in (0..n).rev() {
        let s = dot(l[j], &x[j + 1..]);
        x[j] -= s;
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::Ldlt;
    use crate::linalg::tests::{assert_solves_match, assert_solves_system, filled, spd};
    use crate::linalg::{FactorError, Llt};

    #[test]
    fn small_factorizations_match_faer_around_the_size_threshold() {
        use faer::prelude::Solve;
        // The fixed-size kernels (n <= 12) and faer's blocked code (n > 12) against faer's
        // own dense factorizations and solves of the same matrices: the factors entry by
        // entry, the solutions of many, few and strided right-hand sides.
        for n in [1usize, 2, 3, 4, 7, 8, 11, 12, 13, 16] {
            let a = spd(n, 100 + n as u64);
            let b = filled(n, 9, n);
            let bt = filled(5, n, n + 1);

            let reference = a.as_ref().llt(faer::Side::Lower).unwrap();
            let mut f = Llt::new(n);
            f.factor(a.as_ref()).unwrap();
            for j in 0..n {
                for i in j..n {
                    assert!(
                        (f.l()[(i, j)] - reference.L()[(i, j)]).abs() < 1e-13,
                        "llt n {n}: ({i}, {j})"
                    );
                }
            }
            let (x_ref, xt_ref) = (reference.solve(b.as_ref()), reference.solve(bt.transpose()));
            assert_solves_match(|m| f.solve_in_place(m), &b, &bt, &x_ref, &xt_ref, 1e-12, "llt");

            // Quasi-definite [[H, Dᵀ], [D, -mu I]] (no pivoting needed).
            let nu = n.div_ceil(2);
            let mut k = a.clone();
            for i in nu..n {
                for j in nu..n {
                    k[(i, j)] = if i == j { -0.3 } else { 0.0 };
                }
            }
            let reference = k.as_ref().ldlt(faer::Side::Lower).unwrap();
            let mut f = Ldlt::new(n);
            let inertia = f.factor(k.as_ref()).unwrap();
            assert_eq!((inertia.positive, inertia.negative), (nu, n - nu));
            for j in 0..n {
                assert!((f.d(j) - reference.D()[j]).abs() < 1e-13, "ldlt n {n}: D {j}");
                for i in j + 1..n {
                    assert!(
                        (f.factors[(i, j)] - reference.L()[(i, j)]).abs() < 1e-13,
                        "ldlt n {n}: ({i}, {j})"
                    );
                }
            }
            let (x_ref, xt_ref) = (reference.solve(b.as_ref()), reference.solve(bt.transpose()));
            assert_solves_match(|m| f.solve_in_place(m), &b, &bt, &x_ref, &xt_ref, 1e-11, "ldlt");
        }
    }

    #[test]
    fn ldlt_small_and_blocked_paths_agree_with_the_system() {
        // Quasi-definite [[H, Dᵀ], [D, -mu I]] of sizes around 12 (the fixed-size kernels' limit), solved with one,
        // two and many right-hand sides (loop kernels and faer's blocked solve), and
        // through a non-contiguous right-hand side.
        for n in [1usize, 3, 11, 12, 13, 30, 70] {
            let nu = n.div_ceil(3);
            let mut k = spd(n, n as u64 + 3);
            for i in nu..n {
                for j in nu..n {
                    k[(i, j)] = if i == j { -1e-3 } else { 0.0 };
                }
            }
            let mut f = Ldlt::new(n);
            let inertia = f.factor(k.as_ref()).unwrap();
            assert_eq!((inertia.positive, inertia.negative), (nu, n - nu));
            for cols in [1, 2, 9] {
                let b = filled(n, cols, cols);
                assert_solves_system(|m| f.solve_in_place(m), k.as_ref(), &b, cols, 1e-9);
            }
        }
        // A zero pivot is reported by the small path too.
        let mut f = Ldlt::new(3);
        let z = Mat::<f64>::zeros(3, 3);
        assert!(matches!(f.factor(z.as_ref()), Err(FactorError::Singular { index: 0 })));
    }
}
