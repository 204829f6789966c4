//! Matrix products: [`matmul`], its lower-triangle variants [`matmul_lower`] and
//! [`matmul_lower_upper_free`], and the loop kernels that replace faer's call for small
//! products.

use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::prelude::ReborrowMut;
use faer::{Accum, MatMut, MatRef, Par};

use super::reduce::{dot, dot_fixed};
use super::views::{col_fixed, col_fixed_mut};

/// Products with at most this many multiply-adds use the loops of [`small_matmul`]: faer's
/// fixed cost per call (dispatch, blocking) dominates below it (measured: `Aᵀ B` for 4 x 4
/// takes 113 ns in faer, about 20 ns in the loops).
const SMALL_PRODUCT: usize = 512;

/// The same bound for [`matmul_lower`], whose loops do half the multiply-adds and faer's
/// triangular product costs more per call: the Riccati stage's `[A B]ᵀ P [A B]` at
/// `nx = 8`, `nu = 4` (1152 multiply-adds) is about 11 % of an LQR FDDP solve faster in
/// the loops (per-process minima, 60 alternating runs), while raising [`SMALL_PRODUCT`]
/// to 1024 makes that solve slower (faer's AVX-512 kernel wins on `P [A B]`).
const SMALL_LOWER_PRODUCT: usize = 4 * SMALL_PRODUCT;

/// Makes faer's packing buffer of the calling thread: faer keeps the packed operands of
/// its larger products in one buffer per thread, allocated at the thread's first such
/// product. One product (on zeros) when a workspace is built, or a team thread starts,
/// keeps that allocation out of the first solve.
pub(crate) fn reserve_packing_buffer() {
    const N: usize = 64;
    let a = faer::Mat::<f64>::zeros(N, N);
    let mut c = faer::Mat::<f64>::zeros(N, N);
    faer::linalg::matmul::matmul(c.as_mut(), Accum::Replace, a.as_ref(), a.as_ref(), 1.0, Par::Seq);
}

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

/// `dst = alpha * lhs * rhs` by the loop kernels whatever the number of columns (faer's
/// product when they do not apply: more than `MAX_SMALL_DIM` rows and columns of `lhs`,
/// or strided views): for a small square `lhs` applied to many columns, whose loops keep
/// each column of `dst` in registers where faer's kernels pack and dispatch.
pub(crate) fn matmul_loops(mut dst: MatMut<'_, f64>, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, alpha: f64) {
    if !small_matmul(dst.rb_mut(), Accum::Replace, lhs, rhs, alpha, false) {
        faer::linalg::matmul::matmul(dst, Accum::Replace, lhs, rhs, alpha, Par::Seq);
    }
}

/// Lower triangle (diagonal included) of `dst = alpha * lhs * rhs` (`Accum::Replace`) or
/// `dst += alpha * lhs * rhs` (`Accum::Add`); the strict upper triangle of `dst` is not
/// touched. For products known to be symmetric, such as `Aᵀ P A`, at half the cost.
#[inline]
pub(crate) fn matmul_lower(
    mut dst: MatMut<'_, f64>,
    accum: Accum,
    lhs: MatRef<'_, f64>,
    rhs: MatRef<'_, f64>,
    alpha: f64,
) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (lhs.nrows(), rhs.ncols()));
    debug_assert_eq!(lhs.ncols(), rhs.nrows());
    if dst.nrows() * dst.ncols() * lhs.ncols() <= SMALL_LOWER_PRODUCT
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

/// Largest product (multiply-adds of the full product) that
/// [`matmul_lower_upper_free`] gives to faer's full product rather than its triangular
/// one.
const FULL_FOR_LOWER_PRODUCT: usize = 16 * SMALL_PRODUCT;

/// [`matmul_lower`] into a destination whose strict upper triangle the caller overwrites
/// afterwards (by mirroring the lower one), so that it may be written too: between the
/// loops' size and [`FULL_FOR_LOWER_PRODUCT`], faer's full product, whose kernels beat
/// its triangular one there at twice the arithmetic (the Riccati stage's `[A B]ᵀ P [A B]`
/// at `nx = 12`, `nu = 6`: the UR5 FDDP solve 3-7 % faster, per-process minima of
/// alternating runs); larger products keep the triangular one.
#[inline]
pub(crate) fn matmul_lower_upper_free(
    mut dst: MatMut<'_, f64>,
    accum: Accum,
    lhs: MatRef<'_, f64>,
    rhs: MatRef<'_, f64>,
    alpha: f64,
) {
    let work = dst.nrows() * dst.ncols() * lhs.ncols();
    if work <= SMALL_LOWER_PRODUCT && full_from_rows(dst.rb_mut(), accum, lhs, rhs, alpha) {
        return;
    }
    if work > SMALL_LOWER_PRODUCT && work <= FULL_FOR_LOWER_PRODUCT {
        return faer::linalg::matmul::matmul(dst, accum, lhs, rhs, alpha, Par::Seq);
    }
    matmul_lower(dst, accum, lhs, rhs, alpha);
}

/// The whole of a small `dst = alpha lhs rhs` (`Accum::Replace`) or `dst += ...`, for a
/// `lhs` stored by rows (such as `[A B]ᵀ`, `m` and its columns `k` at most 16): `lhs`
/// transposed into columns on the stack, then each column of `dst` in registers as a
/// sum of those columns (the axpy form of [`small_matmul`], vectorised over the rows)
/// instead of a dot product per entry. Returns `false` (and does nothing) for other
/// shapes and layouts.
fn full_from_rows(dst: MatMut<'_, f64>, accum: Accum, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, alpha: f64) -> bool {
    let (m, k) = (lhs.nrows(), lhs.ncols());
    let layout = lhs.col_stride() == 1 && lhs.row_stride() != 1 && dst.row_stride() == 1 && rhs.row_stride() == 1;
    if !layout || m > MAX_SMALL_DIM || k > MAX_SMALL_DIM {
        return false;
    }
    let mut t = [[0.0; MAX_SMALL_DIM]; MAX_SMALL_DIM];
    for i in 0..m {
        let row = lhs.row(i).try_as_row_major().expect("checked").as_slice();
        for (tl, &v) in t.iter_mut().zip(row) {
            tl[i] = v;
        }
    }
    with_fixed_len!(m, axpy_columns_fixed, (dst, accum, &t[..k], rhs, alpha))
}

/// Lower triangle of `q += [A B]ᵀ P [A B]` (`P`: `ny × ny`, `A`: `ny × nx`, `B`: `ny × nu`,
/// `q`: `(nx + nu)²`, all with unit row stride) in one pass when the products are small
/// enough for the loop kernels (`ny² (nx + nu)` at most [`SMALL_PRODUCT`] multiply-adds,
/// `nx + nu` at most 16): `P [A B]` column by column in registers, then the dot products,
/// in the order of [`matmul`] then [`matmul_lower`] on a copied `[A B]` (the same sums),
/// without the copy, the intermediate matrix and their per-call costs. Returns `false`
/// (and does nothing) otherwise.
pub(crate) fn add_sandwich_lower(
    q: MatMut<'_, f64>,
    p: MatRef<'_, f64>,
    a: MatRef<'_, f64>,
    b: MatRef<'_, f64>,
) -> bool {
    let (ny, n) = (p.nrows(), a.ncols() + b.ncols());
    let strides = [q.row_stride(), p.row_stride(), a.row_stride(), b.row_stride()];
    if ny * ny * n > SMALL_PRODUCT || n > MAX_SMALL_DIM || strides.iter().any(|&s| s != 1) {
        return false;
    }
    with_fixed_len!(ny, sandwich_fixed, (q, p, a, b))
}

/// [`add_sandwich_lower`] for `ny = M`.
#[inline]
fn sandwich_fixed<const M: usize>(mut q: MatMut<'_, f64>, p: MatRef<'_, f64>, a: MatRef<'_, f64>, b: MatRef<'_, f64>) {
    let nx = a.ncols();
    let n = nx + b.ncols();
    let zero = [0.0; M];
    let mut ab = [&zero; MAX_SMALL_DIM];
    for (j, c) in ab.iter_mut().enumerate().take(n) {
        *c = if j < nx {
            col_fixed::<M>(a, j)
        } else {
            col_fixed::<M>(b, j - nx)
        };
    }
    let pc: [&[f64; M]; M] = std::array::from_fn(|l| col_fixed::<M>(p, l));
    // w_j = P [A B]_j, the axpy form of `small_matmul` (zero factors skipped).
    let mut w = [[0.0; M]; MAX_SMALL_DIM];
    for (wj, c) in w.iter_mut().zip(&ab).take(n) {
        for (l, &s) in c.iter().enumerate() {
            if s == 0.0 {
                continue;
            }
            for i in 0..M {
                wj[i] += s * pc[l][i];
            }
        }
    }
    for (j, wj) in w.iter().enumerate().take(n) {
        let d = &mut q
            .rb_mut()
            .col_mut(j)
            .try_as_col_major_mut()
            .expect("checked")
            .as_slice_mut()[j..n];
        for (di, ai) in d.iter_mut().zip(&ab[j..n]) {
            *di += dot_fixed(ai, wj);
        }
    }
}

/// `dst = base + lhs rhs` (`dst`, `base`: `m × n` with `m` at most 16; `lhs`: `m × k`,
/// `k` at most 16; all column-major) in one pass when the product is small enough for
/// the loop kernels: each column of `dst` starts from `base`'s in registers and takes the
/// axpys of [`small_matmul`] (the same sums as [`copy`](super::copy) then
/// [`matmul_lower`] in the lower triangle), without the copy's and the product's
/// per-call costs. Returns `false` (and does nothing) otherwise.
pub(crate) fn copy_add_product(
    dst: MatMut<'_, f64>,
    base: MatRef<'_, f64>,
    lhs: MatRef<'_, f64>,
    rhs: MatRef<'_, f64>,
) -> bool {
    let (m, n, k) = (dst.nrows(), dst.ncols(), lhs.ncols());
    let strides = [dst.row_stride(), base.row_stride(), lhs.row_stride(), rhs.row_stride()];
    if m * n * k > SMALL_LOWER_PRODUCT || k > MAX_SMALL_DIM || strides.iter().any(|&s| s != 1) {
        return false;
    }
    with_fixed_len!(m, copy_add_product_fixed, (dst, base, lhs, rhs))
}

/// [`copy_add_product`] for `m = M`.
#[inline]
fn copy_add_product_fixed<const M: usize>(
    mut dst: MatMut<'_, f64>,
    base: MatRef<'_, f64>,
    lhs: MatRef<'_, f64>,
    rhs: MatRef<'_, f64>,
) {
    let k = lhs.ncols();
    let zero = [0.0; M];
    let mut a = [&zero; MAX_SMALL_DIM];
    for (l, al) in a.iter_mut().enumerate().take(k) {
        *al = col_fixed::<M>(lhs, l);
    }
    for j in 0..dst.ncols() {
        let mut acc = *col_fixed::<M>(base, j);
        let s = &rhs.col(j).try_as_col_major().expect("checked").as_slice()[..k];
        for (al, &sl) in a.iter().zip(s) {
            if sl == 0.0 {
                continue;
            }
            for i in 0..M {
                acc[i] += sl * al[i];
            }
        }
        *col_fixed_mut::<M>(dst.rb_mut(), j) = acc;
    }
}

/// The smallest `k` such that `m = diag(m_b, s I)` with `m_b` of size `k × k` (`0`: `m`
/// is `s I`): the structure of Jacobians on a Lie group times vector spaces.
pub(crate) fn identity_block(m: MatRef<'_, f64>, s: f64) -> usize {
    let mut k = 0;
    for j in 0..m.ncols() {
        let differs = |i: usize| m[(i, j)] != if i == j { s } else { 0.0 };
        // A column of `s I` (the common case) in one vectorised test; the last entry
        // that differs searched for only in the others.
        let column_of_s_i = match m.col(j).try_as_col_major() {
            Some(c) => {
                let c = c.as_slice();
                c.get(j).is_none_or(|&d| d == s)
                    && !super::any_nonzero(&c[..j.min(c.len())])
                    && !super::any_nonzero(c.get(j + 1..).unwrap_or(&[]))
            }
            None => false,
        };
        if column_of_s_i {
            continue;
        }
        if let Some(i) = (0..m.nrows()).rev().find(|&i| differs(i)) {
            k = k.max(i.max(j) + 1);
        }
    }
    k
}

/// `dst = m src` for a square `m = diag(m_b, I)` (`k` = [`identity_block`]`(m, 1)`): the
/// rows past `k` are copied, the first `k` multiplied by `m_b`.
pub(crate) fn matmul_identity_block(mut dst: MatMut<'_, f64>, m: MatRef<'_, f64>, src: MatRef<'_, f64>, k: usize) {
    let (n, rest) = (src.ncols(), src.nrows() - k);
    super::copy(dst.rb_mut().subrows_mut(k, rest), src.subrows(k, rest));
    if k > 0 {
        matmul(
            dst.subrows_mut(0, k),
            Accum::Replace,
            m.submatrix(0, 0, k, k),
            src.submatrix(0, 0, k, n),
            1.0,
        );
    }
}

/// Largest inner dimension of the product loop kernels (their slices are gathered in a
/// fixed array, initialised at every call: small on purpose).
const MAX_SMALL_DIM: usize = 16;

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
    if lhs_cols && !lower && with_fixed_len!(m, axpy_columns_fixed, (dst.rb_mut(), accum, &a[..k], rhs, alpha)) {
        return true;
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
    add_columns(&mut acc, a, off, s.iter().copied());
    *d = acc;
}

/// `acc[i] += Σ_l s_l a[l][off + i]` over the pairs of `a` and `s`, `l` in order,
/// skipping zero `s_l`: the column sum of every axpy kernel of this module.
#[inline(always)]
fn add_columns<const M: usize>(
    acc: &mut [f64; M],
    a: &[impl AsRef<[f64]>],
    off: usize,
    s: impl IntoIterator<Item = f64>,
) {
    for (al, sl) in a.iter().zip(s) {
        if sl == 0.0 {
            continue;
        }
        let c: &[f64; M] = al.as_ref()[off..off + M].try_into().expect("M rows");
        for i in 0..M {
            acc[i] += sl * c[i];
        }
    }
}

/// The axpy loop of [`small_matmul`] over every column of a `dst` of `M` rows, the
/// column kept in registers: `d = [d +] Σ_l (alpha rhs[l, j]) a[l]`, skipping zero
/// `alpha rhs[l, j]` (the same sums in the same order).
#[inline]
fn axpy_columns_fixed<const M: usize>(
    mut dst: MatMut<'_, f64>,
    accum: Accum,
    a: &[impl AsRef<[f64]>],
    rhs: MatRef<'_, f64>,
    alpha: f64,
) {
    for j in 0..dst.ncols() {
        let d = col_fixed_mut::<M>(dst.rb_mut(), j);
        let mut acc = if accum == Accum::Replace { [0.0; M] } else { *d };
        match rhs.col(j).try_as_col_major() {
            Some(b) => add_columns(&mut acc, a, 0, b.as_slice().iter().map(|&v| alpha * v)),
            None => add_columns(&mut acc, a, 0, (0..a.len()).map(|l| alpha * rhs[(l, j)])),
        }
        *d = acc;
    }
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

#[cfg(test)]
mod tests {
    use faer::Accum;

    use faer::Mat;

    use super::{add_sandwich_lower, copy_add_product, matmul, matmul_lower, matmul_lower_upper_free};
    use crate::linalg::tests::{filled, naive};

    /// `base + lhs rhs` in one pass equals, bit for bit in the lower triangle, the copy
    /// and the lower product it replaces, and the naive sum everywhere; it declines
    /// large sizes.
    #[test]
    fn copy_add_product_is_the_copy_and_the_product() {
        for (m, k) in [(1, 1), (4, 2), (6, 3), (8, 4), (12, 6), (16, 8), (17, 2), (12, 16)] {
            let base = filled(m, m, 1);
            let lhs = filled(m, k, 2);
            let mut rhs = filled(k, m, 3);
            rhs[(0, 0)] = 0.0;
            let mut d = Mat::<f64>::zeros(m, m);
            let done = copy_add_product(d.as_mut(), base.as_ref(), lhs.as_ref(), rhs.as_ref());
            assert_eq!(done, m <= 16 && m * m * k <= 2048, "{m} {k}");
            if !done {
                assert!(d.col_iter().all(|c| c.iter().all(|v| *v == 0.0)));
                continue;
            }
            let mut r = base.clone();
            matmul_lower(r.as_mut(), Accum::Add, lhs.as_ref(), rhs.as_ref(), 1.0);
            let reference = naive(lhs.as_ref(), rhs.as_ref());
            for j in 0..m {
                for i in 0..m {
                    if i >= j {
                        assert_eq!(d[(i, j)].to_bits(), r[(i, j)].to_bits(), "{m} {k}: ({i}, {j})");
                    }
                    assert!((d[(i, j)] - base[(i, j)] - reference[(i, j)]).abs() < 1e-12);
                }
            }
        }
    }

    /// The one-pass `[A B]ᵀ P [A B]` equals, bit for bit, the two products on a copied
    /// `[A B]` it replaces, and matches the naive product; it declines large sizes.
    #[test]
    fn sandwich_is_the_two_products_bit_for_bit() {
        for (ny, nx, nu) in [
            (1, 1, 0),
            (2, 2, 1),
            (4, 4, 2),
            (3, 6, 2),
            (5, 4, 3),
            (2, 12, 4),
            (8, 8, 4),
            (4, 16, 2),
        ] {
            let n = nx + nu;
            let p = filled(ny, ny, 1);
            let mut a = filled(ny, nx, 2);
            a[(0, 0)] = 0.0;
            let b = filled(ny, nu, 3);
            let ab = Mat::from_fn(ny, n, |i, j| if j < nx { a[(i, j)] } else { b[(i, j - nx)] });
            let init = filled(n, n, 4);
            let mut q = init.clone();
            let done = add_sandwich_lower(q.as_mut(), p.as_ref(), a.as_ref(), b.as_ref());
            assert_eq!(done, ny * ny * n <= 512 && n <= 16, "{ny} {nx} {nu}");
            if !done {
                assert_eq!(q, init);
                continue;
            }
            let mut w = Mat::<f64>::zeros(ny, n);
            matmul(w.as_mut(), Accum::Replace, p.as_ref(), ab.as_ref(), 1.0);
            let mut r = init.clone();
            matmul_lower(r.as_mut(), Accum::Add, ab.transpose(), w.as_ref(), 1.0);
            let reference = naive(ab.transpose(), naive(p.as_ref(), ab.as_ref()).as_ref());
            for j in 0..n {
                for i in 0..n {
                    if i >= j {
                        assert_eq!(q[(i, j)].to_bits(), r[(i, j)].to_bits(), "{ny} {nx} {nu}: ({i}, {j})");
                        assert!((q[(i, j)] - init[(i, j)] - reference[(i, j)]).abs() < 1e-12);
                    } else {
                        assert_eq!(q[(i, j)], init[(i, j)]);
                    }
                }
            }
        }
    }

    #[test]
    fn products_match_the_naive_product_for_every_layout_and_size() {
        // Small sizes take the loop kernels, larger ones faer; lhs plain or transposed,
        // rhs plain or transposed, full or lower destination, replace or add.
        for (m, n, k) in [
            (1, 1, 1),
            (2, 3, 4),
            (3, 48, 3),
            (4, 4, 4),
            (6, 5, 3),
            (8, 8, 8),
            (12, 7, 12),
            (12, 12, 8),
            (16, 16, 16),
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
                    // The upper-free variant: the same lower triangle, adding or replacing.
                    let mut f = init.clone();
                    matmul_lower_upper_free(f.as_mut(), Accum::Add, lhs, rhs, 1.0);
                    let mut g = init.clone();
                    matmul_lower_upper_free(g.as_mut(), Accum::Replace, lhs, rhs, -0.5);
                    for j in 0..n {
                        for i in j..m {
                            assert!((f[(i, j)] - l[(i, j)]).abs() < 1e-12, "upper free {m}: ({i}, {j})");
                            let expected = -0.5 * reference[(i, j)];
                            assert!((g[(i, j)] - expected).abs() < 1e-12, "upper free {m}: ({i}, {j})");
                        }
                    }
                }
            }
        }
    }
}
