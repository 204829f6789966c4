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
use faer::prelude::ReborrowMut;

pub use faer::{Accum, Col, ColMut, ColRef, Mat, MatMut, MatRef};

/// Products with at most this many multiply-adds use the loops of [`small_matmul`]: faer's
/// fixed cost per call (dispatch, blocking) dominates below it (measured: `Aᵀ B` for 4 x 4
/// takes 113 ns in faer, about 20 ns in the loops).
const SMALL_PRODUCT: usize = 512;

/// `dst = alpha * lhs * rhs` (`Accum::Replace`) or `dst += alpha * lhs * rhs` (`Accum::Add`).
#[inline]
pub fn matmul(mut dst: MatMut<'_, f64>, accum: Accum, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, alpha: f64) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (lhs.nrows(), rhs.ncols()));
    debug_assert_eq!(lhs.ncols(), rhs.nrows());
    if dst.nrows() * dst.ncols() * lhs.ncols() <= SMALL_PRODUCT
        && small_matmul(dst.rb_mut(), accum, lhs, rhs, alpha, false)
    {
        return;
    }
    faer::linalg::matmul::matmul(dst, accum, lhs, rhs, alpha, Par::Seq);
}

/// Lower triangle (diagonal included) of `dst = alpha * lhs * rhs` (`Accum::Replace`) or
/// `dst += alpha * lhs * rhs` (`Accum::Add`); the strict upper triangle of `dst` is not
/// touched. For products known to be symmetric, such as `Aᵀ P A`, at half the cost.
#[inline]
pub fn matmul_lower(mut dst: MatMut<'_, f64>, accum: Accum, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, alpha: f64) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (lhs.nrows(), rhs.ncols()));
    debug_assert_eq!(lhs.ncols(), rhs.nrows());
    if dst.nrows() * dst.ncols() * lhs.ncols() <= 2 * SMALL_PRODUCT
        && small_matmul(dst.rb_mut(), accum, lhs, rhs, alpha, true)
    {
        return;
    }
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

/// Calls `$f::<N>$args` when `$n` is one of the lengths with a fixed-size kernel (1 to
/// 16) and evaluates to whether it did.
macro_rules! with_fixed_len {
    ($n:expr, $f:ident, $args:tt) => {
        with_fixed_len!(@arms $n, $f, $args, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16)
    };
    (@arms $n:expr, $f:ident, $args:tt, $($len:literal)*) => {
        match $n {
            $($len => {
                $f::<$len> $args;
                true
            })*
            _ => false,
        }
    };
}

/// Largest inner dimension of the product loop kernels (their slices are gathered in a
/// fixed array, initialised at every call: small on purpose).
const MAX_SMALL_DIM: usize = 16;

/// Largest dimension of the vector LDLᵀ solve kernel.
const MAX_SOLVE_DIM: usize = 64;

/// Loops for small products (all of `dst`, or its lower triangle): axpy form when the
/// columns of `lhs` are contiguous, dot form when its rows are and the columns of `rhs`
/// are. Returns `false` (and does nothing) for other layouts.
fn small_matmul(
    mut dst: MatMut<'_, f64>,
    accum: Accum,
    lhs: MatRef<'_, f64>,
    rhs: MatRef<'_, f64>,
    alpha: f64,
    lower: bool,
) -> bool {
    let (m, n, k) = (dst.nrows(), dst.ncols(), lhs.ncols());
    let lhs_cols = lhs.row_stride() == 1;
    let dot_form = !lhs_cols && lhs.col_stride() == 1 && rhs.row_stride() == 1;
    let gathered = if lhs_cols { k } else { m };
    if dst.row_stride() != 1 || !(lhs_cols || dot_form) || gathered > MAX_SMALL_DIM {
        return false;
    }
    let mut a: [&[f64]; MAX_SMALL_DIM] = [&[]; MAX_SMALL_DIM];
    if lhs_cols {
        for (l, al) in a.iter_mut().enumerate().take(k) {
            *al = lhs.col(l).try_as_col_major().expect("checked").as_slice();
        }
    } else {
        for (i, ai) in a.iter_mut().enumerate().take(m) {
            *ai = lhs.row(i).try_as_row_major().expect("checked").as_slice();
        }
    }
    for j in 0..n {
        let i0 = if lower { j.min(m) } else { 0 };
        let d = &mut dst
            .rb_mut()
            .col_mut(j)
            .try_as_col_major_mut()
            .expect("checked")
            .as_slice_mut()[i0..];
        if accum == Accum::Replace {
            d.fill(0.0);
        }
        if lhs_cols {
            let mut s = [0.0; MAX_SMALL_DIM];
            for (l, sl) in s.iter_mut().enumerate().take(k) {
                *sl = alpha * rhs[(l, j)];
            }
            let (a, s) = (&a[..k], &s[..k]);
            if !with_fixed_len!(d.len(), axpy_fixed, (d, a, i0, s)) {
                for (al, &sl) in a.iter().zip(s) {
                    if sl != 0.0 {
                        for (di, ai) in d.iter_mut().zip(&al[i0..]) {
                            *di += sl * ai;
                        }
                    }
                }
            }
        } else {
            let b = rhs.col(j).try_as_col_major().expect("checked").as_slice();
            let rows = &a[i0..m];
            if !with_fixed_len!(k, dots_fixed, (d, rows, b, alpha)) {
                for (di, ai) in d.iter_mut().zip(rows) {
                    *di += alpha * dot(ai, b);
                }
            }
        }
    }
    true
}

/// `d[i] += Σ_l s[l] a[l][off + i]` for `d` of length `M`, skipping zero `s[l]`: the axpy
/// loop of [`small_matmul`] unrolled, with `d` in registers (same order of additions).
#[inline]
fn axpy_fixed<const M: usize>(d: &mut [f64], a: &[&[f64]], off: usize, s: &[f64]) {
    let d: &mut [f64; M] = d.try_into().expect("M rows");
    let mut acc = *d;
    for (al, &sl) in a.iter().zip(s) {
        if sl == 0.0 {
            continue;
        }
        let c: &[f64; M] = al[off..off + M].try_into().expect("M rows");
        for i in 0..M {
            acc[i] += sl * c[i];
        }
    }
    *d = acc;
}

/// `d[i] += alpha * rows[i]ᵀb` for `b` of length `K`: the dot loop of [`small_matmul`]
/// with [`dot_fixed`] (same partial sums as [`dot`]).
#[inline]
fn dots_fixed<const K: usize>(d: &mut [f64], rows: &[&[f64]], b: &[f64], alpha: f64) {
    let b: &[f64; K] = b.try_into().expect("K rows");
    for (di, ai) in d.iter_mut().zip(rows) {
        let a: &[f64; K] = ai[..K].try_into().expect("K columns");
        *di += alpha * dot_fixed(a, b);
    }
}

/// [`matvec`] (after the `Replace` zeroing) for a column-major `A` with `M` rows: `y`
/// lives in registers and each column is one fixed-size, unrolled axpy, with the
/// additions in the order of the generic loop (bit-identical results).
#[inline]
fn matvec_fixed<const M: usize>(y: &mut [f64], a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    let y: &mut [f64; M] = y.try_into().expect("M rows");
    let mut acc = *y;
    for (j, &xj) in x.iter().enumerate() {
        let s = alpha * xj;
        if s == 0.0 {
            continue;
        }
        let c: &[f64; M] = a
            .col(j)
            .try_as_col_major()
            .expect("checked")
            .as_slice()
            .try_into()
            .expect("M rows");
        for i in 0..M {
            acc[i] += s * c[i];
        }
    }
    *y = acc;
}

/// [`matvec_t`] for a column-major `A` with `M` rows: fixed-size, unrolled dot products
/// with the partial sums of [`dot`] (bit-identical results).
#[inline]
fn matvec_t_fixed<const M: usize>(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    let x: &[f64; M] = x.try_into().expect("M rows");
    for (j, yj) in y.iter_mut().enumerate() {
        let c: &[f64; M] = a
            .col(j)
            .try_as_col_major()
            .expect("checked")
            .as_slice()
            .try_into()
            .expect("M rows");
        let s = dot_fixed(c, x);
        *yj = if accum == Accum::Replace {
            alpha * s
        } else {
            *yj + alpha * s
        };
    }
}

/// [`dot`] for slices of a fixed length, with the same partial sums.
#[inline]
fn dot_fixed<const M: usize>(a: &[f64; M], b: &[f64; M]) -> f64 {
    let mut acc = [0.0; 4];
    for c in 0..M / 4 {
        for k in 0..4 {
            acc[k] += a[4 * c + k] * b[4 * c + k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for i in 4 * (M / 4)..M {
        s += a[i] * b[i];
    }
    s
}

/// `y = alpha * A x` (`Accum::Replace`) or `y += alpha * A x` (`Accum::Add`) on slices.
#[inline]
pub fn matvec(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    debug_assert_eq!(a.nrows(), y.len());
    debug_assert_eq!(a.ncols(), x.len());
    if accum == Accum::Replace {
        y.fill(0.0);
    }
    if a.row_stride() == 1 && with_fixed_len!(y.len(), matvec_fixed, (y, a, x, alpha)) {
        return;
    }
    // Column-major saxpy loop: faster than a faer call at the small sizes of this library.
    for (j, &xj) in x.iter().enumerate() {
        let s = alpha * xj;
        if s == 0.0 {
            continue;
        }
        match a.col(j).try_as_col_major() {
            Some(c) => {
                for (yi, ci) in y.iter_mut().zip(c.as_slice()) {
                    *yi += s * ci;
                }
            }
            None => {
                let c = a.col(j);
                for (i, yi) in y.iter_mut().enumerate() {
                    *yi += s * c[i];
                }
            }
        }
    }
}

/// `y = alpha * Aᵀ x` (`Accum::Replace`) or `y += alpha * Aᵀ x` (`Accum::Add`) on slices.
#[inline]
pub fn matvec_t(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    debug_assert_eq!(a.ncols(), y.len());
    debug_assert_eq!(a.nrows(), x.len());
    if a.row_stride() == 1 && with_fixed_len!(x.len(), matvec_t_fixed, (y, accum, a, x, alpha)) {
        return;
    }
    for (j, yj) in y.iter_mut().enumerate() {
        let s = match a.col(j).try_as_col_major() {
            Some(c) => dot(c.as_slice(), x),
            None => {
                let c = a.col(j);
                x.iter().enumerate().map(|(i, xi)| c[i] * xi).sum()
            }
        };
        *yj = if accum == Accum::Replace {
            alpha * s
        } else {
            *yj + alpha * s
        };
    }
}

/// Lower triangle (diagonal included) of `dst = aᵀ b` for `a`, `b` with contiguous
/// columns and the same number of rows (the residual size of a Gram product
/// `Jᵀ (W J)`): each entry is the dot product of two columns. For short columns the
/// general kernels' per-entry set-up dominates; this visits each pair once. Falls back
/// to [`matmul_lower`] for other layouts.
pub fn matmul_tn_lower(mut dst: MatMut<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (a.ncols(), b.ncols()));
    debug_assert_eq!(a.nrows(), b.nrows());
    if a.row_stride() != 1 || b.row_stride() != 1 {
        return matmul_lower(dst, Accum::Replace, a.transpose(), b, 1.0);
    }
    fn cols<'a>(m: MatRef<'a, f64>, j: usize) -> &'a [f64] {
        m.col(j).try_as_col_major().expect("unit row stride").as_slice()
    }
    for j in 0..dst.ncols() {
        let bj = cols(b, j);
        for i in j..dst.nrows() {
            dst[(i, j)] = dot(cols(a, i), bj);
        }
    }
}

/// `aᵀb` with four partial sums (vectorisable).
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// `Σ |v_i|` with four partial sums (vectorisable); NaN if `v` holds a NaN.
#[inline]
pub fn norm_l1(v: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for x in chunks {
        for k in 0..4 {
            acc[k] += x[k].abs();
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + rest.iter().map(|x| x.abs()).sum::<f64>()
}

/// `dst = src` (same shape), column by column.
#[inline]
pub fn copy(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (src.nrows(), src.ncols()));
    if src.row_stride() == 1 && dst.row_stride() == 1 && with_fixed_len!(src.nrows(), copy_fixed, (dst.rb_mut(), src)) {
        return;
    }
    for j in 0..src.ncols() {
        let pair = (
            src.col(j).try_as_col_major(),
            dst.rb_mut().col_mut(j).try_as_col_major_mut(),
        );
        if let (Some(s), Some(d)) = pair {
            d.as_slice_mut().copy_from_slice(s.as_slice());
            continue;
        }
        for i in 0..src.nrows() {
            dst[(i, j)] = src[(i, j)];
        }
    }
}

/// [`copy`] of column-major matrices with `M` rows: fixed-size column moves instead of
/// a `memcpy` call per column.
#[inline]
fn copy_fixed<const M: usize>(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
    for j in 0..src.ncols() {
        let s: &[f64; M] = src
            .col(j)
            .try_as_col_major()
            .expect("checked")
            .as_slice()
            .try_into()
            .expect("M rows");
        let d: &mut [f64; M] = dst
            .rb_mut()
            .col_mut(j)
            .try_as_col_major_mut()
            .expect("checked")
            .as_slice_mut()
            .try_into()
            .expect("M rows");
        *d = *s;
    }
}

/// `dst = srcᵀ` (`dst` is `src.ncols() x src.nrows()`), reading `src` by columns.
#[inline]
pub fn copy_transposed(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (src.ncols(), src.nrows()));
    for j in 0..src.ncols() {
        match src.col(j).try_as_col_major() {
            Some(s) => {
                for (i, v) in s.as_slice().iter().enumerate() {
                    dst[(j, i)] = *v;
                }
            }
            None => {
                for i in 0..src.nrows() {
                    dst[(j, i)] = src[(i, j)];
                }
            }
        }
    }
}

/// `m = -m`.
#[inline]
pub fn negate(mut m: MatMut<'_, f64>) {
    for j in 0..m.ncols() {
        match m.rb_mut().col_mut(j).try_as_col_major_mut() {
            Some(c) => c.as_slice_mut().iter_mut().for_each(|v| *v = -*v),
            None => {
                for i in 0..m.nrows() {
                    m[(i, j)] = -m[(i, j)];
                }
            }
        }
    }
}

/// Whether the lower triangle (diagonal included) of a square matrix holds only finite
/// values (its sum is finite).
#[inline]
fn lower_sum_is_finite(m: MatRef<'_, f64>) -> bool {
    let mut sum = 0.0;
    for j in 0..m.ncols() {
        match m.col(j).try_as_col_major() {
            Some(c) => sum += c.as_slice()[j..].iter().sum::<f64>(),
            None => (j..m.nrows()).for_each(|i| sum += m[(i, j)]),
        }
    }
    sum.is_finite()
}

/// Copies the lower triangle (diagonal included) of `src` into `dst`.
#[inline]
fn copy_lower(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
    let n = src.nrows();
    for j in 0..n {
        let pair = (
            src.col(j).try_as_col_major(),
            dst.rb_mut().col_mut(j).try_as_col_major_mut(),
        );
        if let (Some(s), Some(d)) = pair {
            d.as_slice_mut()[j..].copy_from_slice(&s.as_slice()[j..]);
            continue;
        }
        for i in j..n {
            dst[(i, j)] = src[(i, j)];
        }
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
    if m.row_stride() == 1 && with_fixed_len!(n, symmetrize_from_lower_fixed, (m.rb_mut())) {
        return;
    }
    for j in 0..n {
        // Column j below the diagonal is row j right of the diagonal.
        for i in (j + 1)..n {
            let v = m[(i, j)];
            m[(j, i)] = v;
        }
    }
}

/// Replaces a square matrix by its symmetric part `(M + Mᵀ) / 2`.
pub fn symmetrize(mut m: MatMut<'_, f64>) {
    let n = m.nrows();
    if m.row_stride() == 1 && with_fixed_len!(n, symmetrize_fixed, (m.rb_mut())) {
        return;
    }
    for j in 0..n {
        for i in (j + 1)..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

/// The columns of a column-major `N x N` matrix, copied into an array (fixed size: the
/// loops of the symmetrization kernels unroll without bounds checks).
#[inline]
fn columns_fixed<const N: usize>(m: MatRef<'_, f64>) -> [[f64; N]; N] {
    let mut a = [[0.0; N]; N];
    for (j, aj) in a.iter_mut().enumerate() {
        *aj = *col_fixed::<N>(m, j);
    }
    a
}

/// Column `j` of a column-major matrix with `N` rows as a fixed-size array.
#[inline]
fn col_fixed<const N: usize>(m: MatRef<'_, f64>, j: usize) -> &[f64; N] {
    m.col(j)
        .try_as_col_major()
        .expect("checked")
        .as_slice()
        .try_into()
        .expect("N rows")
}

/// Column `j` of a column-major matrix with `N` rows as a fixed-size array.
#[inline]
fn col_fixed_mut<'a, const N: usize>(m: MatMut<'a, f64>, j: usize) -> &'a mut [f64; N] {
    m.col_mut(j)
        .try_as_col_major_mut()
        .expect("checked")
        .as_slice_mut()
        .try_into()
        .expect("N rows")
}

/// [`symmetrize_from_lower`] of a column-major `N x N` matrix: the columns read once,
/// the strict upper triangle written from that copy.
#[inline]
fn symmetrize_from_lower_fixed<const N: usize>(mut m: MatMut<'_, f64>) {
    let low = columns_fixed::<N>(m.as_ref());
    for i in 1..N {
        let c = col_fixed_mut::<N>(m.rb_mut(), i);
        for j in 0..i {
            c[j] = low[j][i];
        }
    }
}

/// [`symmetrize`] of a column-major `N x N` matrix, from a copy of its columns (the same
/// sums `(m_ij + m_ji) / 2` as the generic loop).
#[inline]
fn symmetrize_fixed<const N: usize>(mut m: MatMut<'_, f64>) {
    let a = columns_fixed::<N>(m.as_ref());
    for j in 0..N {
        let c = col_fixed_mut::<N>(m.rb_mut(), j);
        for i in 0..N {
            if i != j {
                c[i] = 0.5 * (a[j][i] + a[i][j]);
            }
        }
    }
}

/// Lower triangle (diagonal included) of `dst = I + alpha * src` for square matrices; the
/// strict upper triangle of `dst` is not touched.
pub fn identity_plus_scaled_lower(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    let n = dst.nrows();
    debug_assert_eq!((src.nrows(), src.ncols(), dst.ncols()), (n, n, n));
    if src.row_stride() == 1
        && dst.row_stride() == 1
        && with_fixed_len!(n, identity_plus_scaled_lower_fixed, (dst.rb_mut(), src, alpha))
    {
        return;
    }
    for j in 0..n {
        let pair = (
            src.col(j).try_as_col_major(),
            dst.rb_mut().col_mut(j).try_as_col_major_mut(),
        );
        if let (Some(s), Some(d)) = pair {
            for (di, si) in d.as_slice_mut()[j..].iter_mut().zip(&s.as_slice()[j..]) {
                *di = alpha * si;
            }
        } else {
            for i in j..n {
                dst[(i, j)] = alpha * src[(i, j)];
            }
        }
        dst[(j, j)] += 1.0;
    }
}

/// [`identity_plus_scaled_lower`] of column-major `N x N` matrices: fixed-size columns,
/// the same products and diagonal sums.
#[inline]
fn identity_plus_scaled_lower_fixed<const N: usize>(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    for j in 0..N {
        let s = col_fixed::<N>(src, j);
        let d = col_fixed_mut::<N>(dst.rb_mut(), j);
        for i in j..N {
            d[i] = alpha * s[i];
        }
        d[j] += 1.0;
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

/// Calls `$f::<N>$args` when `$n` is at most 12 and evaluates to `Some` of its result,
/// `None` otherwise. Factorizations and solves up to this dimension use the fixed-size
/// kernels below ([`small_factor`], [`ldlt_solve_fixed`], [`llt_solve_fixed`]) instead of
/// faer's blocked code, whose fixed cost per call dominates at these sizes.
macro_rules! with_small_dim {
    ($n:expr, $f:ident, $args:tt) => {
        with_small_dim!(@arms $n, $f, $args, 1 2 3 4 5 6 7 8 9 10 11 12)
    };
    (@arms $n:expr, $f:ident, $args:tt, $($len:literal)*) => {
        match $n {
            $($len => Some($f::<$len> $args),)*
            _ => None,
        }
    };
}

/// The `N` columns of an owned `N x N` matrix as fixed-size arrays.
#[inline(always)]
fn columns<const N: usize>(m: MatRef<'_, f64>) -> [&[f64; N]; N] {
    std::array::from_fn(|j| col_fixed::<N>(m, j))
}

/// In-place factorization of the lower triangle of an owned `N x N` matrix, right-looking
/// with the matrix in registers: `A = L Lᵀ` (`cholesky`: `L` in the lower triangle, fails
/// on a pivot that is not positive) or `A = L D Lᵀ` (`D` on the diagonal, the unit lower
/// `L` below it; fails on a zero pivot), both as faer stores them.
#[inline(always)]
fn small_factor<const N: usize>(mut a: MatMut<'_, f64>, cholesky: bool) -> Result<(), FactorError> {
    let mut m = columns_fixed::<N>(a.as_ref());
    for j in 0..N {
        let d = m[j][j];
        if cholesky {
            if d.is_nan() || d <= 0.0 {
                return Err(FactorError::Singular { index: j });
            }
            let l_jj = d.sqrt();
            m[j][j] = l_jj;
            for i in j + 1..N {
                m[j][i] /= l_jj;
            }
            for c in j + 1..N {
                let s = m[j][c];
                for i in c..N {
                    m[c][i] -= s * m[j][i];
                }
            }
        } else {
            if d == 0.0 {
                return Err(FactorError::Singular { index: j });
            }
            // w = column below the pivot, l = w / d, trailing -= (w_c / d) w.
            for c in j + 1..N {
                let s = m[j][c] / d;
                for i in c..N {
                    m[c][i] -= s * m[j][i];
                }
            }
            for i in j + 1..N {
                m[j][i] /= d;
            }
        }
    }
    for (j, mj) in m.iter().enumerate() {
        let col: &mut [f64; N] = a
            .rb_mut()
            .col_mut(j)
            .try_as_col_major_mut()
            .expect("owned storage")
            .as_slice_mut()
            .try_into()
            .expect("N rows");
        *col = *mj;
    }
    Ok(())
}

/// Right-hand sides solved together by the fixed-size solves: the kernels work on rows
/// of this many columns, which the compiler maps to vector registers.
const LANES: usize = 2;

/// Applies `solve` to the columns of `rhs`, [`LANES`] at a time (the last group padded
/// with zero columns): `x[i][w]` is row `i` of the `w`-th column of the group.
#[inline(always)]
fn solve_columns<const N: usize>(mut rhs: MatMut<'_, f64>, solve: impl Fn(&mut [[f64; LANES]; N])) {
    let ncols = rhs.ncols();
    let mut c0 = 0;
    while c0 < ncols {
        let w = (ncols - c0).min(LANES);
        let mut x = [[0.0; LANES]; N];
        for k in 0..w {
            let col = rhs.as_ref().col(c0 + k);
            match col.try_as_col_major() {
                Some(v) => {
                    let v: &[f64; N] = v.as_slice().try_into().expect("N rows");
                    (0..N).for_each(|i| x[i][k] = v[i]);
                }
                None => (0..N).for_each(|i| x[i][k] = col[i]),
            }
        }
        solve(&mut x);
        for k in 0..w {
            let mut col = rhs.rb_mut().col_mut(c0 + k);
            match col.rb_mut().try_as_col_major_mut() {
                Some(v) => {
                    let v: &mut [f64; N] = v.as_slice_mut().try_into().expect("N rows");
                    (0..N).for_each(|i| v[i] = x[i][k]);
                }
                None => (0..N).for_each(|i| col[i] = x[i][k]),
            }
        }
        c0 += w;
    }
}

/// Solves `L D Lᵀ X = B` in place for an `N x N` factorization in faer's storage (the
/// unit lower `L` below the diagonal, `D` on it).
#[inline(always)]
fn ldlt_solve_fixed<const N: usize>(f: MatRef<'_, f64>, rhs: MatMut<'_, f64>) {
    let l = columns::<N>(f);
    solve_columns::<N>(rhs, |v| {
        for j in 0..N {
            let vj = v[j];
            for i in j + 1..N {
                for k in 0..LANES {
                    v[i][k] -= l[j][i] * vj[k];
                }
            }
        }
        for j in 0..N {
            for k in 0..LANES {
                v[j][k] /= l[j][j];
            }
        }
        for j in (0..N).rev() {
            let mut s = [0.0; LANES];
            for i in j + 1..N {
                for k in 0..LANES {
                    s[k] += l[j][i] * v[i][k];
                }
            }
            for k in 0..LANES {
                v[j][k] -= s[k];
            }
        }
    });
}

/// Solves `L Lᵀ X = B` in place for an `N x N` Cholesky factor in faer's storage.
#[inline(always)]
fn llt_solve_fixed<const N: usize>(f: MatRef<'_, f64>, rhs: MatMut<'_, f64>) {
    let l = columns::<N>(f);
    solve_columns::<N>(rhs, |v| {
        for j in 0..N {
            let mut vj = v[j];
            for k in 0..LANES {
                vj[k] /= l[j][j];
            }
            v[j] = vj;
            for i in j + 1..N {
                for k in 0..LANES {
                    v[i][k] -= l[j][i] * vj[k];
                }
            }
        }
        for j in (0..N).rev() {
            let mut s = v[j];
            for i in j + 1..N {
                for k in 0..LANES {
                    s[k] -= l[j][i] * v[i][k];
                }
            }
            for k in 0..LANES {
                v[j][k] = s[k] / l[j][j];
            }
        }
    });
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

/// `A = L D Lᵀ` without pivoting, for symmetric quasi-definite matrices such as the
/// regularised stage KKT blocks `[[R, Dᵀ], [D, -mu I]]`.
pub struct Ldlt {
    factors: Mat<f64>,
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
            buf: stack_buffer(req),
            scratch: vec![0.0; n],
        }
    }

    /// Dimension of the factorization.
    pub fn dim(&self) -> usize {
        self.factors.nrows()
    }

    /// Factors the lower triangle of `a` and returns the inertia read off `D`.
    pub fn factor(&mut self, a: MatRef<'_, f64>) -> Result<Inertia, FactorError> {
        debug_assert_eq!((a.nrows(), a.ncols()), (self.dim(), self.dim()));
        copy_lower(self.factors.as_mut(), a);
        self.factor_filled()
    }

    /// The storage of the matrix to factor: write its lower triangle here, then call
    /// [`factor_filled`](Self::factor_filled) (saves a copy).
    pub fn matrix_mut(&mut self) -> MatMut<'_, f64> {
        self.factors.as_mut()
    }

    /// Factors the lower triangle written through [`matrix_mut`](Self::matrix_mut) and
    /// returns the inertia read off `D`.
    pub fn factor_filled(&mut self) -> Result<Inertia, FactorError> {
        let n = self.dim();
        if !lower_sum_is_finite(self.factors.as_ref()) {
            return Err(FactorError::NonFinite);
        }
        if let Some(res) = with_small_dim!(n, small_factor, (self.factors.as_mut(), false)) {
            res?;
        } else {
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
    pub fn solve_in_place(&mut self, mut rhs: MatMut<'_, f64>) {
        let n = self.dim();
        if with_small_dim!(n, ldlt_solve_fixed, (self.factors.as_ref(), rhs.rb_mut())).is_some() {
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

    /// Entry-by-entry product, the reference of the kernel tests.
    fn naive(lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>) -> Mat<f64> {
        Mat::from_fn(lhs.nrows(), rhs.ncols(), |i, j| {
            (0..lhs.ncols()).map(|l| lhs[(i, l)] * rhs[(l, j)]).sum()
        })
    }

    fn filled(m: usize, n: usize, seed: usize) -> Mat<f64> {
        Mat::from_fn(m, n, |i, j| (((i * 31 + j * 17 + seed * 7) % 23) as f64 - 11.0) / 7.0)
    }

    #[test]
    fn products_match_the_naive_product_for_every_layout_and_size() {
        // Small sizes take the loop kernels, larger ones faer; lhs plain or transposed,
        // rhs plain or transposed, full or lower destination, replace or add.
        for (m, n, k) in [
            (1, 1, 1),
            (2, 3, 4),
            (4, 4, 4),
            (6, 5, 3),
            (8, 8, 8),
            (12, 7, 12),
            (17, 17, 9),
            (40, 36, 44),
        ] {
            let a = filled(m, k, 1);
            let at = filled(k, m, 2);
            let b = filled(k, n, 3);
            let bt = filled(n, k, 4);
            for (lhs, rhs) in [
                (a.as_ref(), b.as_ref()),
                (at.transpose(), b.as_ref()),
                (a.as_ref(), bt.transpose()),
                (at.transpose(), bt.transpose()),
            ] {
                let reference = naive(lhs, rhs);
                let init = filled(m, n, 5);
                let mut c = init.clone();
                matmul(c.as_mut(), Accum::Add, lhs, rhs, -0.5);
                let mut r = init.clone();
                matmul(r.as_mut(), Accum::Replace, lhs, rhs, 2.0);
                for j in 0..n {
                    for i in 0..m {
                        assert!((c[(i, j)] - (init[(i, j)] - 0.5 * reference[(i, j)])).abs() < 1e-12);
                        assert!((r[(i, j)] - 2.0 * reference[(i, j)]).abs() < 1e-12);
                    }
                }
                if m == n {
                    let mut l = init.clone();
                    matmul_lower(l.as_mut(), Accum::Add, lhs, rhs, 1.0);
                    for j in 0..n {
                        for i in 0..m {
                            let expected = if i >= j {
                                init[(i, j)] + reference[(i, j)]
                            } else {
                                init[(i, j)]
                            };
                            assert!((l[(i, j)] - expected).abs() < 1e-12, "lower {m}: ({i}, {j})");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn matvec_kernels_match_the_naive_product_on_strided_views() {
        // Sizes around the four-column blocking, on a submatrix of a larger matrix
        // (contiguous columns, column stride > rows) and on a transposed one (rows
        // strided): both the loop kernels and the strided fallbacks.
        for (m, n) in [(1, 1), (3, 5), (4, 4), (5, 3), (7, 9), (8, 8), (13, 6), (6, 13)] {
            let big = filled(m + 3, n + 2, m + n);
            let bigt = filled(n + 2, m + 3, m * n);
            let x: Vec<f64> = (0..n).map(|i| (i as f64 - 2.5) / 3.0).collect();
            let xt: Vec<f64> = (0..m).map(|i| (1.5 - i as f64) / 5.0).collect();
            for a in [
                big.as_ref().submatrix(2, 1, m, n),
                bigt.as_ref().submatrix(1, 2, n, m).transpose(),
            ] {
                let ax = naive(a, as_mat(&x));
                let atx = naive(a.transpose(), as_mat(&xt));
                let mut y: Vec<f64> = (0..m).map(|i| i as f64).collect();
                matvec(&mut y, Accum::Add, a, &x, -2.0);
                let mut yt: Vec<f64> = (0..n).map(|i| 0.5 * i as f64).collect();
                matvec_t(&mut yt, Accum::Add, a, &xt, 3.0);
                for i in 0..m {
                    assert!((y[i] - (i as f64 - 2.0 * ax[(i, 0)])).abs() < 1e-12, "matvec {m}x{n}");
                }
                for j in 0..n {
                    assert!(
                        (yt[j] - (0.5 * j as f64 + 3.0 * atx[(j, 0)])).abs() < 1e-12,
                        "matvec_t {m}x{n}"
                    );
                }
                matvec(&mut y, Accum::Replace, a, &x, 1.0);
                matvec_t(&mut yt, Accum::Replace, a, &xt, 1.0);
                for i in 0..m {
                    assert!((y[i] - ax[(i, 0)]).abs() < 1e-12);
                }
                for j in 0..n {
                    assert!((yt[j] - atx[(j, 0)]).abs() < 1e-12);
                }
            }
        }
    }

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

    /// Solves `a x = b` in place with `solve`, and the strided system whose right-hand
    /// sides are the rows of `filled(cols, n, cols)`, and checks both residuals.
    fn assert_solves_system(
        mut solve: impl FnMut(MatMut<'_, f64>),
        a: MatRef<'_, f64>,
        b: &Mat<f64>,
        cols: usize,
        tol: f64,
    ) {
        let n = a.nrows();
        let mut x = b.clone();
        solve(x.as_mut());
        assert!(residual(a, x.as_ref(), b.as_ref()) < tol, "n {n}, {cols} columns");
        let bt = filled(cols, n, cols);
        let mut xt = bt.clone();
        solve(xt.as_mut().transpose_mut());
        assert!(residual(a, xt.transpose(), bt.transpose()) < tol, "n {n}, transposed");
    }

    /// Solves `b` (contiguous right-hand sides) and `btᵀ` (strided ones) in place with
    /// `solve` and compares them with the reference solutions `x_ref` and `xt_ref`.
    fn assert_solves_match(
        mut solve: impl FnMut(MatMut<'_, f64>),
        b: &Mat<f64>,
        bt: &Mat<f64>,
        x_ref: &Mat<f64>,
        xt_ref: &Mat<f64>,
        tol: f64,
        what: &str,
    ) {
        let mut x = b.clone();
        solve(x.as_mut());
        let mut xt = bt.clone();
        solve(xt.as_mut().transpose_mut());
        let n = b.nrows();
        for j in 0..n {
            for i in 0..b.ncols() {
                assert!((x[(j, i)] - x_ref[(j, i)]).abs() < tol, "{what} solve n {n}");
            }
            for i in 0..bt.nrows() {
                assert!((xt[(i, j)] - xt_ref[(j, i)]).abs() < tol, "{what} strided solve n {n}");
            }
        }
    }

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

    #[test]
    fn symmetrization_and_shifted_lower_match_their_definitions() {
        // Fixed-size paths (column-major, every size up to 16) and the index fallbacks
        // (more columns, transposed views), against the entrywise definitions.
        for n in 1usize..=17 {
            let a = filled(n, n, n);
            let mut big = filled(n + 1, n + 1, 3);
            for view in 0..2 {
                let mut sym = a.clone();
                let mut low = a.clone();
                if view == 0 {
                    symmetrize(sym.as_mut());
                    symmetrize_from_lower(low.as_mut());
                } else {
                    symmetrize(sym.as_mut().transpose_mut());
                    symmetrize_from_lower(low.as_mut().transpose_mut());
                }
                for j in 0..n {
                    for i in 0..n {
                        assert_eq!(sym[(i, j)], 0.5 * (a[(i, j)] + a[(j, i)]), "symmetrize {n}");
                        // Lower triangle of the view: of `a` or of `aᵀ`.
                        let (r, c) = if (i >= j) == (view == 0) { (i, j) } else { (j, i) };
                        assert_eq!(low[(i, j)], a[(r, c)], "from lower {n}, view {view}");
                    }
                }
                let src = if view == 0 { a.as_ref() } else { a.transpose() };
                let init = big.clone();
                identity_plus_scaled_lower(big.as_mut().submatrix_mut(1, 0, n, n), src, -0.25);
                for j in 0..n {
                    for i in 0..n {
                        let expected = if i >= j {
                            -0.25 * src[(i, j)] + if i == j { 1.0 } else { 0.0 }
                        } else {
                            init[(1 + i, j)]
                        };
                        assert_eq!(big[(1 + i, j)], expected, "I + alpha A, {n}");
                    }
                }
            }
        }
    }

    #[test]
    fn copies_negation_and_dot() {
        let a = filled(5, 3, 1);
        let mut t = Mat::<f64>::zeros(3, 5);
        copy_transposed(t.as_mut(), a.as_ref());
        let mut c = Mat::<f64>::zeros(5, 3);
        copy(c.as_mut(), t.transpose());
        negate(c.as_mut());
        for j in 0..3 {
            for i in 0..5 {
                assert_eq!(t[(j, i)], a[(i, j)]);
                assert_eq!(c[(i, j)], -a[(i, j)]);
            }
        }
        let x: Vec<f64> = (0..11).map(|i| i as f64 - 3.0).collect();
        let y: Vec<f64> = (0..11).map(|i| 0.5 * i as f64).collect();
        assert_eq!(dot(&x, &y), x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>());
    }
}
