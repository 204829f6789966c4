//! [`Ldlt`]: `A = L D Lᵀ` without pivoting, for symmetric quasi-definite matrices.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::ldlt;
use faer::prelude::ReborrowMut;
use faer::{Mat, MatMut, MatRef, Par};

#[cfg(test)]
use super::copy::copy_lower;
use super::matvec::axpy;
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

    /// Solves `A X = B` in place for `X` stored by rows (`x[i·w..(i + 1)·w]` is row `i`
    /// of the `w` right-hand sides): every step of the substitutions updates whole rows,
    /// vectorised across the right-hand sides. For `n <= SMALL_DIM` the operations
    /// of [`solve_in_place`](Self::solve_in_place) in the same order (bit-identical).
    pub fn solve_rows_in_place(&self, x: &mut [f64], w: usize) {
        let (n, f) = (self.n, self.active());
        debug_assert_eq!(x.len(), n * w);
        if w == 0 {
            return;
        }
        // L Y = B, row j subtracted from the rows below it.
        for j in 0..n {
            let (head, tail) = x.split_at_mut((j + 1) * w);
            let x_j = &head[j * w..];
            for (i, x_i) in (j + 1..n).zip(tail.chunks_exact_mut(w)) {
                // x_i - l x_j, as x_i + (-l) x_j: the same rounding.
                axpy(x_i, -f[(i, j)], x_j);
            }
        }
        for (j, x_j) in x.chunks_exact_mut(w).enumerate() {
            let d = f[(j, j)];
            x_j.iter_mut().for_each(|a| *a /= d);
        }
        // Lᵀ X = D⁻¹Y, row j less the sum over the rows below it (summed first).
        for j in (0..n).rev() {
            let (head, tail) = x.split_at_mut((j + 1) * w);
            let x_j = &mut head[j * w..];
            let mut c = 0;
            while c + ROW_CHUNK <= w {
                sub_column_sums::<ROW_CHUNK>(f, j, x_j, tail, w, c);
                c += ROW_CHUNK;
            }
            while c < w {
                sub_column_sums::<1>(f, j, x_j, tail, w, c);
                c += 1;
            }
        }
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

    /// Solves `A X = -Bᵀ` for `X` (`n × m`, into `x`) from `B` (`m × n`) without forming
    /// `-Bᵀ` by columns: `B`'s columns, negated, are the rows of the right-hand side in
    /// [`solve_rows_in_place`](Self::solve_rows_in_place)'s layout (in `scratch`, at
    /// least `n·m` entries), whose substitutions run along whole rows, vectorised over
    /// the `m` columns (independent chains where the column solve waits on each entry).
    /// The same result to the bit as [`solve_in_place`](Self::solve_in_place) on `-Bᵀ`.
    /// Only for `n` up to [`SMALL_DIM`](super::SMALL_DIM) and unit row strides; returns
    /// `false` (and does nothing) otherwise.
    pub fn solve_neg_transposed(&self, b: MatRef<'_, f64>, mut x: MatMut<'_, f64>, scratch: &mut [f64]) -> bool {
        let (n, m) = (self.dim(), b.nrows());
        debug_assert_eq!((b.ncols(), x.nrows(), x.ncols()), (n, n, m));
        if n > super::SMALL_DIM || b.row_stride() != 1 || x.row_stride() != 1 {
            return false;
        }
        let rows = &mut scratch[..n * m];
        for (i, row) in rows.chunks_exact_mut(m.max(1)).enumerate().take(n) {
            for (r, &v) in row.iter_mut().zip(super::views::col_slice(b, i)) {
                *r = -v;
            }
        }
        self.solve_rows_in_place(rows, m);
        for j in 0..m {
            let col = super::views::col_slice_mut(x.rb_mut(), j);
            for (i, c) in col.iter_mut().enumerate() {
                *c = rows[i * m + j];
            }
        }
        true
    }
}

/// Columns of the right-hand sides summed together by [`Ldlt::solve_rows_in_place`].
const ROW_CHUNK: usize = 8;

/// `x_j[c..c + W] -= Σ_(i > j) L_ij x_i[c..c + W]`, the sum accumulated from zero with `i`
/// ascending; `below` holds the rows `i > j` (`w` entries each).
#[inline(always)]
fn sub_column_sums<const W: usize>(f: MatRef<'_, f64>, j: usize, x_j: &mut [f64], below: &[f64], w: usize, c: usize) {
    let mut s = [0.0; W];
    for (i, x_i) in (j + 1..f.nrows()).zip(below.chunks_exact(w)) {
        let (l, x_i): (f64, &[f64; W]) = (f[(i, j)], x_i[c..c + W].try_into().expect("W entries"));
        for k in 0..W {
            s[k] += l * x_i[k];
        }
    }
    for k in 0..W {
        x_j[c + k] -= s[k];
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
    use crate::linalg::tests::{assert_solves_match, assert_solves_system, filled, residual, spd};
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
            let k = quasi_definite(n, nu, 100 + n as u64, 0.3);
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

    /// `[[H, Dᵀ], [D, -mu I]]` (`H` the leading `nu × nu` block) from a random SPD matrix.
    fn quasi_definite(n: usize, nu: usize, seed: u64, mu: f64) -> Mat<f64> {
        let mut k = spd(n, seed);
        for i in nu..n {
            for j in nu..n {
                k[(i, j)] = if i == j { -mu } else { 0.0 };
            }
        }
        k
    }

    #[test]
    fn ldlt_small_and_blocked_paths_agree_with_the_system() {
        // Quasi-definite [[H, Dᵀ], [D, -mu I]] of sizes around 12 (the fixed-size kernels' limit), solved with one,
        // two and many right-hand sides (loop kernels and faer's blocked solve), and
        // through a non-contiguous right-hand side.
        for n in [1usize, 3, 11, 12, 13, 30, 70] {
            let nu = n.div_ceil(3);
            let k = quasi_definite(n, nu, n as u64 + 3, 1e-3);
            let mut f = Ldlt::new(n);
            let inertia = f.factor(k.as_ref()).unwrap();
            assert_eq!((inertia.positive, inertia.negative), (nu, n - nu));
            for cols in [1, 2, 9] {
                let b = filled(n, cols, cols);
                assert_solves_system(|m| f.solve_in_place(m), k.as_ref(), &b, cols, 1e-9);
            }
        }
    }

    #[test]
    fn the_solve_by_rows_is_the_column_solve_bit_for_bit_up_to_the_small_size() {
        // Quasi-definite systems with 1, 7 (one chunk less one), 8, 9 and 37 right-hand
        // sides: for n <= 12 every entry of X equals the column solve's bit for bit; past
        // it (faer's blocked solve on the columns) X solves the system.
        for n in [1usize, 5, 12, 13, 20] {
            let k = quasi_definite(n, n.div_ceil(2), n as u64 + 7, 1e-2);
            let mut f = Ldlt::new(n);
            f.factor(k.as_ref()).unwrap();
            for w in [1usize, 7, 8, 9, 37] {
                let b = filled(n, w, n + w);
                let mut x_col = b.clone();
                f.solve_in_place(x_col.as_mut());
                let mut rows: Vec<f64> = (0..n)
                    .flat_map(|i| (0..w).map(move |j| (i, j)))
                    .map(|(i, j)| b[(i, j)])
                    .collect();
                f.solve_rows_in_place(&mut rows, w);
                let x_row = Mat::from_fn(n, w, |i, j| rows[i * w + j]);
                if n <= crate::linalg::SMALL_DIM {
                    for (i, j) in (0..n).flat_map(|i| (0..w).map(move |j| (i, j))) {
                        assert_eq!(
                            x_row[(i, j)].to_bits(),
                            x_col[(i, j)].to_bits(),
                            "n {n}, w {w}: ({i}, {j})"
                        );
                    }
                }
                assert!(residual(k.as_ref(), x_row.as_ref(), b.as_ref()) < 1e-9, "n {n}, w {w}");
            }
        }
    }

    #[test]
    fn the_negated_transposed_solve_is_the_in_place_solve_bit_for_bit() {
        // X = -A⁻¹Bᵀ from B (m × n) for m = 1 (one lane), 4 (one group), 37 (groups and a
        // padded rest): every entry equals the in-place solve of the negated transpose,
        // which solves the system; past n = 12, and for a strided B, it declines.
        for n in [1usize, 5, 12, 13] {
            let k = quasi_definite(n, n.div_ceil(2), n as u64 + 11, 1e-3);
            let mut f = Ldlt::new(n);
            f.factor(k.as_ref()).unwrap();
            for m in [1usize, 4, 37] {
                let b = filled(m, n, n + m);
                let mut x = Mat::<f64>::zeros(n, m);
                let mut scratch = vec![0.0; n * m];
                let done = f.solve_neg_transposed(b.as_ref(), x.as_mut(), &mut scratch);
                assert_eq!(done, n <= crate::linalg::SMALL_DIM, "n {n}, m {m}");
                if !done {
                    assert!(x.col_iter().all(|c| c.iter().all(|&v| v == 0.0)));
                    continue;
                }
                let neg_bt = Mat::from_fn(n, m, |i, j| -b[(j, i)]);
                let mut x_ref = neg_bt.clone();
                f.solve_in_place(x_ref.as_mut());
                for (i, j) in (0..n).flat_map(|i| (0..m).map(move |j| (i, j))) {
                    assert_eq!(x[(i, j)].to_bits(), x_ref[(i, j)].to_bits(), "n {n}, m {m}: ({i}, {j})");
                }
                assert!(residual(k.as_ref(), x.as_ref(), neg_bt.as_ref()) < 1e-9, "n {n}, m {m}");
                if n > 1 {
                    let by_rows = Mat::<f64>::zeros(n, m);
                    assert!(!f.solve_neg_transposed(by_rows.as_ref().transpose(), x.as_mut(), &mut scratch));
                }
            }
        }
    }

    #[test]
    fn zero_pivots_are_reported_by_the_small_path_too() {
        let mut f = Ldlt::new(3);
        let z = Mat::<f64>::zeros(3, 3);
        assert!(matches!(f.factor(z.as_ref()), Err(FactorError::Singular { index: 0 })));
    }
}
