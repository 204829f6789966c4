//! Copies: [`copy`], [`copy_transposed`], the lower-triangle copy of the
//! factorizations, [`negate`], and the fill [`fill`].

use faer::prelude::ReborrowMut;
use faer::{MatMut, MatRef};

use super::views::{col_fixed, col_fixed_mut};

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
            copy_slice(d.as_slice_mut(), s.as_slice());
            continue;
        }
        for i in 0..src.nrows() {
            dst[(i, j)] = src[(i, j)];
        }
    }
}

/// `d = s` for slices of equal length: blocks of 16 entries and then the rest moved as
/// fixed-size arrays (inline vector moves, where a column's `copy_from_slice` is a
/// `memcpy` call), and `copy_from_slice` past 48 entries.
#[inline]
fn copy_slice(d: &mut [f64], s: &[f64]) {
    if d.len() > 48 {
        return d.copy_from_slice(s);
    }
    let (mut d, mut s) = (d, s);
    while d.len() > 16 {
        let (d16, d_rest) = d.split_at_mut(16);
        let (s16, s_rest) = s.split_at(16);
        copy_fixed_slice::<16>(d16, s16);
        (d, s) = (d_rest, s_rest);
    }
    with_fixed_len!(d.len(), copy_fixed_slice, (d, s));
}

/// `d = s` for slices of `N` entries.
#[inline]
fn copy_fixed_slice<const N: usize>(d: &mut [f64], s: &[f64]) {
    let d: &mut [f64; N] = d.try_into().expect("N entries");
    *d = *<&[f64; N]>::try_from(s).expect("N entries");
}

/// [`copy`] of column-major matrices with `M` rows: fixed-size column moves instead of
/// a `memcpy` call per column.
#[inline]
fn copy_fixed<const M: usize>(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
    for j in 0..src.ncols() {
        *col_fixed_mut::<M>(dst.rb_mut(), j) = *col_fixed::<M>(src, j);
    }
}

/// Every entry of `m` set to `v`. Columns of at most 16 entries are written as
/// fixed-size arrays (inline stores), longer ones by `slice::fill`: faer's
/// `MatMut::fill` calls `memset` once per column, which for the 3-row blocks of a cone
/// or the 12-row Jacobians of a control costs more than the stores.
#[inline]
pub fn fill(mut m: MatMut<'_, f64>, v: f64) {
    if m.row_stride() == 1 && with_fixed_len!(m.nrows(), fill_fixed, (m.rb_mut(), v)) {
        return;
    }
    for j in 0..m.ncols() {
        match m.rb_mut().col_mut(j).try_as_col_major_mut() {
            Some(c) => c.as_slice_mut().fill(v),
            None => m.rb_mut().col_mut(j).fill(v),
        }
    }
}

/// [`fill`] of a column-major matrix with `M` rows.
#[inline]
fn fill_fixed<const M: usize>(mut m: MatMut<'_, f64>, v: f64) {
    for j in 0..m.ncols() {
        *col_fixed_mut::<M>(m.rb_mut(), j) = [v; M];
    }
}

/// `dst = srcᵀ` (`dst` is `src.ncols() x src.nrows()`), reading `src` by columns: for
/// column-major `src` and `dst`, four columns of `src` at a time, each column of `dst`
/// taking their four entries in one store (as `symmetrize_from_lower`'s blocks).
#[inline]
pub(crate) fn copy_transposed(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (src.ncols(), src.nrows()));
    let mut j0 = 0;
    if src.row_stride() == 1 && dst.row_stride() == 1 {
        while j0 + 4 <= src.ncols() {
            let s: [&[f64]; 4] = std::array::from_fn(|k| super::views::col_slice(src, j0 + k));
            for i in 0..src.nrows() {
                let d: &mut [f64; 4] = (&mut super::views::col_slice_mut(dst.rb_mut(), i)[j0..j0 + 4])
                    .try_into()
                    .expect("four rows");
                *d = [s[0][i], s[1][i], s[2][i], s[3][i]];
            }
            j0 += 4;
        }
    }
    for j in j0..src.ncols() {
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

/// Copies the lower triangle (diagonal included) of `src` into `dst`.
#[inline]
pub(crate) fn copy_lower(mut dst: MatMut<'_, f64>, src: MatRef<'_, f64>) {
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

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::{copy, copy_transposed, negate};
    use crate::linalg::dot;
    use crate::linalg::tests::filled;

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

    #[test]
    fn transposed_copies_by_blocks_of_four_columns_and_the_rest() {
        // Sources of 1 to 13 columns (none, some and all in blocks of four) into a view
        // inside a larger matrix (the Q-function's `Sᵀ` block), whose border stays; and a
        // strided source (the column-by-column path).
        for (m, n) in [(36, 12), (5, 1), (7, 3), (2, 4), (9, 5), (3, 8), (4, 13)] {
            let a = filled(m, n, m + n);
            let mut big = Mat::<f64>::from_fn(n + 3, m + 2, |_, _| 7.0);
            copy_transposed(big.as_mut().submatrix_mut(2, 1, n, m), a.as_ref());
            for j in 0..m + 2 {
                for i in 0..n + 3 {
                    let inside = (2..2 + n).contains(&i) && (1..=m).contains(&j);
                    let expected = if inside { a[(j - 1, i - 2)] } else { 7.0 };
                    assert_eq!(big[(i, j)], expected, "{m} x {n}: ({i}, {j})");
                }
            }
            // `a` as a strided view (the transpose of its owned transpose).
            let at = a.transpose().to_owned();
            let mut t = Mat::<f64>::zeros(n, m);
            copy_transposed(t.as_mut(), at.as_ref().transpose());
            assert_eq!(t, at, "{m} x {n}: strided source");
        }
    }

    #[test]
    fn copies_of_every_column_length() {
        // Fixed-size columns (up to 16), blocks of 16 and a rest (up to 48), plain
        // slices beyond; into a view inside a larger matrix, whose border stays.
        for m in [1, 5, 16, 17, 31, 32, 36, 47, 48, 49, 70] {
            let a = filled(m, 3, m);
            let mut big = Mat::<f64>::from_fn(m + 2, 5, |_, _| 7.0);
            copy(big.as_mut().submatrix_mut(1, 1, m, 3), a.as_ref());
            for j in 0..5 {
                for i in 0..m + 2 {
                    let inside = (1..=m).contains(&i) && (1..=3).contains(&j);
                    let expected = if inside { a[(i - 1, j - 1)] } else { 7.0 };
                    assert_eq!(big[(i, j)], expected, "{m} rows: ({i}, {j})");
                }
            }
        }
    }
}
