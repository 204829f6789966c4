//! In-place symmetrization of square matrices ([`symmetrize`], [`symmetrize_from_lower`]),
//! the shifted lower triangle [`identity_plus_scaled_lower`], with fixed-size kernels
//! for column-major matrices up to 16 x 16, and the lower-triangle updates
//! [`add_scaled_lower`] and [`fill_lower`].

use faer::prelude::ReborrowMut;
use faer::{MatMut, MatRef};

use super::views::{col_fixed, col_fixed_mut, columns_fixed};

/// Copies the lower triangle of a square matrix into its upper triangle.
pub(crate) fn symmetrize_from_lower(mut m: MatMut<'_, f64>) {
    let n = m.nrows();
    if m.row_stride() == 1 {
        if !with_fixed_len!(n, symmetrize_from_lower_fixed, (m.rb_mut())) {
            symmetrize_from_lower_by_columns(m);
        }
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

/// [`symmetrize_from_lower`] of a column-major matrix by blocks of four columns: the
/// rows of the four right of them are the transpose of the four below them
/// ([`copy_transposed`](super::copy_transposed)'s four-column blocks: one store per
/// column instead of two indexed accesses per entry); the 4 x 4 diagonal blocks entry by
/// entry.
fn symmetrize_from_lower_by_columns(mut m: MatMut<'_, f64>) {
    let n = m.nrows();
    for j in (0..n).step_by(4) {
        let w = 4.min(n - j);
        for b in 1..w {
            for a in 0..b {
                m[(j + a, j + b)] = m[(j + b, j + a)];
            }
        }
        if w < 4 {
            break;
        }
        let (left, right) = m.rb_mut().split_at_col_mut(j + 4);
        let rest = n - j - 4;
        super::copy_transposed(right.subrows_mut(j, 4), left.as_ref().submatrix(j + 4, j, rest, 4));
    }
}

/// Lower triangle (diagonal included) of `dst += alpha * src` for square matrices; the
/// strict upper triangle of `dst` is not touched.
pub(crate) fn add_scaled_lower(dst: MatMut<'_, f64>, alpha: f64, src: MatRef<'_, f64>) {
    zip_lower(dst, src, |d, s| *d += alpha * s);
}

/// `f(dst[i, j], src[i, j])` on the lower triangle (diagonal included) of square
/// matrices, column by column, on slices where both columns are contiguous.
#[inline]
fn zip_lower(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>, mut f: impl FnMut(&mut f64, f64)) {
    let n = dst.nrows();
    debug_assert_eq!((src.nrows(), src.ncols(), dst.ncols()), (n, n, n));
    for j in 0..n {
        let pair = (
            src.col(j).try_as_col_major(),
            dst.rb_mut().col_mut(j).try_as_col_major_mut(),
        );
        if let (Some(s), Some(d)) = pair {
            for (di, &si) in d.as_slice_mut()[j..].iter_mut().zip(&s.as_slice()[j..]) {
                f(di, si);
            }
        } else {
            for i in j..n {
                f(&mut dst[(i, j)], src[(i, j)]);
            }
        }
    }
}

/// Sets the lower triangle (diagonal included) of a square matrix to `v`; the strict
/// upper triangle is not touched.
pub(crate) fn fill_lower(mut m: MatMut<'_, f64>, v: f64) {
    let n = m.nrows();
    for j in 0..m.ncols() {
        m.rb_mut().col_mut(j).subrows_mut(j, n - j).fill(v);
    }
}

/// Replaces a square matrix by its symmetric part `(M + Mᵀ) / 2`.
pub(crate) fn symmetrize(mut m: MatMut<'_, f64>) {
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
pub(crate) fn identity_plus_scaled_lower(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    let n = dst.nrows();
    debug_assert_eq!((src.nrows(), src.ncols(), dst.ncols()), (n, n, n));
    if src.row_stride() == 1
        && dst.row_stride() == 1
        && with_fixed_len!(n, identity_plus_scaled_lower_fixed, (dst.rb_mut(), src, alpha))
    {
        return;
    }
    zip_lower(dst.rb_mut(), src, |d, s| *d = alpha * s);
    for j in 0..n {
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

#[cfg(test)]
mod tests {
    use super::{identity_plus_scaled_lower, symmetrize, symmetrize_from_lower};
    use crate::linalg::tests::filled;

    #[test]
    fn symmetrization_and_shifted_lower_match_their_definitions() {
        // Fixed-size paths (column-major, every size up to 16), the blocked path of larger
        // column-major ones (whole blocks and remainders) and the index fallbacks
        // (transposed views), against the entrywise definitions.
        for n in (1usize..=17).chain([19, 24, 37, 48]) {
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
}
