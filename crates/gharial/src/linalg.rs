//! The one place where gharial calls faer's products and factorizations.
//!
//! Every dense kernel of the library goes through this module, so that a faer upgrade or
//! a hand-written kernel for tiny sizes (faer has a fixed cost per call that dominates
//! below n = 8) touches a single file. Factorization objects allocate their storage and
//! scratch memory in `new` and never allocate afterwards.

use faer::Par;
use faer::diag::{DiagMut, DiagRef};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::{lblt as bunch_kaufman, ldlt, llt};
use faer::linalg::lu::partial_pivoting as lu;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::perm::PermRef;

pub use faer::{Accum, Col, ColMut, ColRef, Mat, MatMut, MatRef};

/// `dst = alpha * lhs * rhs` (`Accum::Replace`) or `dst += alpha * lhs * rhs` (`Accum::Add`).
#[inline]
pub fn matmul(dst: MatMut<'_, f64>, accum: Accum, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, alpha: f64) {
    faer::linalg::matmul::matmul(dst, accum, lhs, rhs, alpha, Par::Seq);
}

/// Lower triangle (diagonal included) of `dst = alpha * lhs * rhs` (`Accum::Replace`) or
/// `dst += alpha * lhs * rhs` (`Accum::Add`); the strict upper triangle of `dst` is not
/// touched. For products known to be symmetric, such as `Aᵀ P A`, at half the cost.
#[inline]
pub fn matmul_lower(dst: MatMut<'_, f64>, accum: Accum, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, alpha: f64) {
    triangular::matmul(
        dst,
        BlockStructure::TriangularLower,
        accum,
        lhs,
        BlockStructure::Rectangular,
        rhs,
        BlockStructure::Rectangular,
        alpha,
        Par::Seq,
    );
}

/// `y = alpha * A x` (`Accum::Replace`) or `y += alpha * A x` (`Accum::Add`) on slices.
#[inline]
pub fn matvec(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    debug_assert_eq!(a.nrows(), y.len());
    debug_assert_eq!(a.ncols(), x.len());
    if accum == Accum::Replace {
        y.fill(0.0);
    }
    // Column-major saxpy loop: faster than a faer call at the small sizes of this library.
    for (j, &xj) in x.iter().enumerate() {
        let s = alpha * xj;
        if s != 0.0 {
            let col = a.col(j);
            for (i, yi) in y.iter_mut().enumerate() {
                *yi += s * col[i];
            }
        }
    }
}

/// `y = alpha * Aᵀ x` (`Accum::Replace`) or `y += alpha * Aᵀ x` (`Accum::Add`) on slices.
#[inline]
pub fn matvec_t(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    debug_assert_eq!(a.ncols(), y.len());
    debug_assert_eq!(a.nrows(), x.len());
    for (j, yj) in y.iter_mut().enumerate() {
        let col = a.col(j);
        let mut s = 0.0;
        for (i, &xi) in x.iter().enumerate() {
            s += col[i] * xi;
        }
        *yj = if accum == Accum::Replace {
            alpha * s
        } else {
            *yj + alpha * s
        };
    }
}

/// A column view of a slice.
#[inline]
pub fn col(s: &[f64]) -> ColRef<'_, f64> {
    ColRef::from_slice(s)
}

/// A mutable column view of a slice.
#[inline]
pub fn col_mut(s: &mut [f64]) -> ColMut<'_, f64> {
    ColMut::from_slice_mut(s)
}

/// An `n x 1` matrix view of a slice.
#[inline]
pub fn as_mat(s: &[f64]) -> MatRef<'_, f64> {
    ColRef::from_slice(s).as_mat()
}

/// An `n x 1` mutable matrix view of a slice.
#[inline]
pub fn as_mat_mut(s: &mut [f64]) -> MatMut<'_, f64> {
    ColMut::from_slice_mut(s).as_mat_mut()
}

/// The contiguous storage of an owned column.
#[inline]
pub fn slice(c: &Col<f64>) -> &[f64] {
    c.as_ref()
        .try_as_col_major()
        .expect("owned columns are contiguous")
        .as_slice()
}

/// The contiguous mutable storage of an owned column.
#[inline]
pub fn slice_mut(c: &mut Col<f64>) -> &mut [f64] {
    c.as_mut()
        .try_as_col_major_mut()
        .expect("owned columns are contiguous")
        .as_slice_mut()
}

/// The contiguous storage of column `j` of an owned matrix.
#[inline]
pub fn col_of(m: &Mat<f64>, j: usize) -> &[f64] {
    m.col(j)
        .try_as_col_major()
        .expect("columns of owned matrices are contiguous")
        .as_slice()
}

/// The contiguous mutable storage of column `j` of an owned matrix.
#[inline]
pub fn col_of_mut(m: &mut Mat<f64>, j: usize) -> &mut [f64] {
    m.col_mut(j)
        .try_as_col_major_mut()
        .expect("columns of owned matrices are contiguous")
        .as_slice_mut()
}

/// Whether the sum of all entries is finite: false if any entry is NaN or infinite (or
/// if the entries are so large that their sum overflows). One pass, no branches per entry.
pub fn sum_is_finite(m: MatRef<'_, f64>) -> bool {
    let mut s = 0.0;
    for j in 0..m.ncols() {
        let c = m.col(j);
        match c.try_as_col_major() {
            Some(c) => s += c.as_slice().iter().sum::<f64>(),
            None => (0..m.nrows()).for_each(|i| s += c[i]),
        }
    }
    s.is_finite()
}

/// Copies the lower triangle of a square matrix into its upper triangle.
pub fn symmetrize_from_lower(mut m: MatMut<'_, f64>) {
    let n = m.nrows();
    for j in 0..n {
        for i in (j + 1)..n {
            let v = m[(i, j)];
            m[(j, i)] = v;
        }
    }
}

/// Replaces a square matrix by its symmetric part `(M + Mᵀ) / 2`.
pub fn symmetrize(mut m: MatMut<'_, f64>) {
    let n = m.nrows();
    for j in 0..n {
        for i in (j + 1)..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

/// Whether every entry of a matrix is finite.
pub fn all_finite(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

/// Largest absolute entry of a matrix (0 for an empty matrix).
pub fn norm_max(m: MatRef<'_, f64>) -> f64 {
    let mut r: f64 = 0.0;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            r = r.max(m[(i, j)].abs());
        }
    }
    r
}

/// Largest absolute entry of a slice (0 for an empty slice).
pub fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |a, x| a.max(x.abs()))
}

/// Inertia of a symmetric matrix: numbers of positive, negative and zero eigenvalues.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inertia {
    /// Number of positive eigenvalues.
    pub positive: usize,
    /// Number of negative eigenvalues.
    pub negative: usize,
    /// Number of (numerically) zero eigenvalues.
    pub zero: usize,
}

/// Why a factorization failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FactorError {
    /// The matrix contains a NaN or an infinity.
    NonFinite,
    /// A pivot was zero (or not positive, for a Cholesky factorization) at this index.
    Singular {
        /// Index of the failing pivot.
        index: usize,
    },
}

fn stack_buffer(req: StackReq) -> MemBuffer {
    MemBuffer::new(req)
}

/// `A = L D Lᵀ` without pivoting, for symmetric quasi-definite matrices such as the
/// regularised stage KKT blocks `[[R, Dᵀ], [D, -mu I]]`.
pub struct Ldlt {
    factors: Mat<f64>,
    buf: MemBuffer,
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
            buf: stack_buffer(req),
        }
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.factors.nrows()
    }

    /// Factors the lower triangle of `a` and returns the inertia read off `D`.
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<Inertia, FactorError> {
        let n = self.dim();
        debug_assert_eq!((a.nrows(), a.ncols()), (n, n));
        for j in 0..n {
            for i in j..n {
                let v = a[(i, j)];
                if !v.is_finite() {
                    return Err(FactorError::NonFinite);
                }
                self.factors[(i, j)] = v;
            }
        }
        let stack = MemStack::new(&mut self.buf);
        match ldlt::factor::cholesky_in_place(
            self.factors.as_mut(),
            Default::default(),
            Par::Seq,
            stack,
            Default::default(),
        ) {
            Ok(_) => {}
            Err(ldlt::factor::LdltError::ZeroPivot { index }) => return Err(FactorError::Singular { index }),
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
    pub fn d(&self, i: usize) -> f64 {
        self.factors[(i, i)]
    }

    /// Solves `A X = B` in place (`rhs` holds `B` on entry, `X` on exit).
    pub fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        let stack = MemStack::new(&mut self.buf);
        let f = self.factors.as_ref();
        ldlt::solve::solve_in_place(f, f.diagonal(), rhs, Par::Seq, stack);
    }
}

/// `A = L Lᵀ` for symmetric positive-definite matrices.
pub struct Llt {
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
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<(), FactorError> {
        let n = self.dim();
        debug_assert_eq!((a.nrows(), a.ncols()), (n, n));
        for j in 0..n {
            for i in j..n {
                let v = a[(i, j)];
                if !v.is_finite() {
                    return Err(FactorError::NonFinite);
                }
                self.factors[(i, j)] = v;
            }
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
    pub fn l(&self) -> MatRef<'_, f64> {
        self.factors.as_ref()
    }

    /// Solves `A X = B` in place.
    pub fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        let stack = MemStack::new(&mut self.buf);
        llt::solve::solve_in_place(self.factors.as_ref(), rhs, Par::Seq, stack);
    }
}

/// `P A Pᵀ = L B Lᵀ` (Bunch-Kaufman, rook pivoting) for any symmetric matrix, including
/// singular-regularised saddle points; gives the inertia from the 1x1 / 2x2 blocks of `B`.
pub struct BunchKaufman {
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
        let n = self.dim();
        debug_assert_eq!((a.nrows(), a.ncols()), (n, n));
        for j in 0..n {
            for i in j..n {
                let v = a[(i, j)];
                if !v.is_finite() {
                    return Err(FactorError::NonFinite);
                }
                self.factors[(i, j)] = v;
            }
        }
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

/// `P A = L U` with partial pivoting, for general square matrices.
pub struct Lu {
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
    /// Allocates a factorization of dimension `n` whose solves take up to `max_rhs` columns.
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
            factors: Mat::zeros(n, n),
            perm: vec![0; n],
            perm_inv: vec![0; n],
            buf: stack_buffer(req),
            max_rhs: max_rhs.max(1),
        }
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.factors.nrows()
    }

    /// Factors `a`; fails if a pivot is exactly zero or not finite.
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<(), FactorError> {
        let n = self.dim();
        debug_assert_eq!((a.nrows(), a.ncols()), (n, n));
        if !all_finite(a) {
            return Err(FactorError::NonFinite);
        }
        self.factors.copy_from(a);
        let stack = MemStack::new(&mut self.buf);
        lu::factor::lu_in_place(
            self.factors.as_mut(),
            &mut self.perm,
            &mut self.perm_inv,
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
        let perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let f = self.factors.as_ref();
        lu::solve::solve_in_place(f, f, perm, rhs, Par::Seq, stack);
    }

    /// Solves `Aᵀ X = B` in place (`rhs` has at most `max_rhs` columns).
    pub fn solve_transpose_in_place(&mut self, rhs: MatMut<'_, f64>) {
        debug_assert!(rhs.ncols() <= self.max_rhs);
        let n = self.dim();
        let stack = MemStack::new(&mut self.buf);
        let perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let f = self.factors.as_ref();
        lu::solve::solve_transpose_in_place(f, f, perm, rhs, Par::Seq, stack);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spd(n: usize, seed: u64) -> Mat<f64> {
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
        };
        let l = Mat::from_fn(n, n, |_, _| next());
        let mut a = Mat::<f64>::identity(n, n);
        matmul(a.as_mut(), Accum::Add, l.as_ref(), l.transpose(), 1.0);
        a
    }

    fn residual(a: MatRef<'_, f64>, x: MatRef<'_, f64>, b: MatRef<'_, f64>) -> f64 {
        let mut r = b.to_owned();
        matmul(r.as_mut(), Accum::Add, a, x, -1.0);
        norm_max(r.as_ref())
    }

    #[test]
    fn factorizations_solve_random_systems() {
        for n in [1, 2, 5, 13, 40] {
            let a = spd(n, n as u64);
            let b = Mat::from_fn(n, 3, |i, j| (i as f64 + 1.0) * (j as f64 - 1.0) + 0.5);

            let mut f = Llt::new(n);
            f.factor(a.as_ref()).unwrap();
            let mut x = b.clone();
            f.solve_in_place(x.as_mut());
            assert!(residual(a.as_ref(), x.as_ref(), b.as_ref()) < 1e-10);

            let mut f = Ldlt::new(n);
            let inertia = f.factor(a.as_ref()).unwrap();
            assert_eq!(
                inertia,
                Inertia {
                    positive: n,
                    negative: 0,
                    zero: 0
                }
            );
            let mut x = b.clone();
            f.solve_in_place(x.as_mut());
            assert!(residual(a.as_ref(), x.as_ref(), b.as_ref()) < 1e-10);

            // Saddle point [[A, I], [I, 0]]: inertia (n, n, 0).
            let mut k = Mat::<f64>::zeros(2 * n, 2 * n);
            k.as_mut().submatrix_mut(0, 0, n, n).copy_from(a.as_ref());
            for i in 0..n {
                k[(n + i, i)] = 1.0;
                k[(i, n + i)] = 1.0;
            }
            let b2 = Mat::from_fn(2 * n, 2, |i, j| (i * 3 + j) as f64 - 2.0);
            let mut f = BunchKaufman::new(2 * n);
            let inertia = f.factor(k.as_ref(), 1e-13).unwrap();
            assert_eq!(
                inertia,
                Inertia {
                    positive: n,
                    negative: n,
                    zero: 0
                }
            );
            let mut x = b2.clone();
            f.solve_in_place(x.as_mut());
            assert!(residual(k.as_ref(), x.as_ref(), b2.as_ref()) < 1e-9);

            let mut f = Lu::new(2 * n, 2);
            f.factor(k.as_ref()).unwrap();
            let mut x = b2.clone();
            f.solve_in_place(x.as_mut());
            assert!(residual(k.as_ref(), x.as_ref(), b2.as_ref()) < 1e-9);
            let mut x = b2.clone();
            f.solve_transpose_in_place(x.as_mut());
            assert!(residual(k.transpose(), x.as_ref(), b2.as_ref()) < 1e-9);
        }
    }

    #[test]
    fn singular_and_non_finite_are_reported() {
        let mut f = Llt::new(2);
        let a = Mat::from_fn(2, 2, |i, j| if i == j { -1.0 } else { 0.0 });
        assert!(matches!(f.factor(a.as_ref()), Err(FactorError::Singular { .. })));
        let a = Mat::from_fn(2, 2, |_, _| f64::NAN);
        assert_eq!(f.factor(a.as_ref()), Err(FactorError::NonFinite));
        let mut lu = Lu::new(2, 1);
        let z = Mat::<f64>::zeros(2, 2);
        assert!(matches!(lu.factor(z.as_ref()), Err(FactorError::Singular { .. })));
    }

    #[test]
    fn matvec_matches_matmul() {
        let a = Mat::from_fn(4, 3, |i, j| (i as f64) - 2.0 * (j as f64) + 0.25);
        let x = [1.0, -2.0, 0.5];
        let mut y = [0.0; 4];
        matvec(&mut y, Accum::Replace, a.as_ref(), &x, 2.0);
        let mut yt = [0.0; 3];
        matvec_t(&mut yt, Accum::Replace, a.as_ref(), &y, 1.0);
        let mut y2 = Mat::<f64>::zeros(4, 1);
        matmul(y2.as_mut(), Accum::Replace, a.as_ref(), as_mat(&x), 2.0);
        let mut yt2 = Mat::<f64>::zeros(3, 1);
        matmul(yt2.as_mut(), Accum::Replace, a.transpose(), y2.as_ref(), 1.0);
        for i in 0..4 {
            assert!((y[i] - y2[(i, 0)]).abs() < 1e-14);
        }
        for i in 0..3 {
            assert!((yt[i] - yt2[(i, 0)]).abs() < 1e-12);
        }
    }
}
