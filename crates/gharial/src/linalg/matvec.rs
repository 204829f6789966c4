//! Matrix-vector products on slices: [`matvec`] (`A x`) and [`matvec_t`] (`Aᵀ x`), with
//! fixed-size kernels for column-major matrices with 1 to 16 rows.

use faer::{Accum, MatRef};

use super::reduce::{dot, dot_fixed};

/// `y = alpha * A x` (`Accum::Replace`) or `y += alpha * A x` (`Accum::Add`) on slices.
#[inline]
pub fn matvec(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    debug_assert_eq!(a.nrows(), y.len());
    debug_assert_eq!(a.ncols(), x.len());
    if accum == Accum::Replace {
        y.fill(0.0);
    }
    if a.row_stride() == 1 {
        let m = y.len();
        if with_fixed_len!(m, matvec_fixed, (y, a, x, alpha)) {
            return;
        }
        // Taller: blocks of 16 rows through the fixed-size kernels (the same sums).
        for i in (0..m).step_by(16) {
            let rows = 16.min(m - i);
            with_fixed_len!(rows, matvec_fixed, (&mut y[i..i + rows], a.subrows(i, rows), x, alpha));
        }
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
pub(crate) fn matvec_t(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    debug_assert_eq!(a.ncols(), y.len());
    debug_assert_eq!(a.nrows(), x.len());
    if a.row_stride() == 1 && with_fixed_len!(x.len(), matvec_t_fixed, (y, accum, a, x, alpha)) {
        return;
    }
    let store = |yj: &mut f64, s: f64| {
        *yj = if accum == Accum::Replace {
            alpha * s
        } else {
            *yj + alpha * s
        };
    };
    if let Some(a) = a.try_as_col_major() {
        // Four columns at a time (each entry of x loaded once for four dot products).
        let done = y.len() - y.len() % 4;
        for (b, yb) in y.chunks_exact_mut(4).enumerate() {
            let cols = std::array::from_fn(|k| a.col(4 * b + k).as_slice());
            for (yj, s) in yb.iter_mut().zip(dot4(cols, x)) {
                store(yj, s);
            }
        }
        for (j, yj) in y.iter_mut().enumerate().skip(done) {
            store(yj, dot(a.col(j).as_slice(), x));
        }
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

/// [`matvec`] (after the `Replace` zeroing) for a column-major `A` with `M` rows: `y`
/// lives in registers and each column is one fixed-size, unrolled axpy, with the
/// additions in the order of the generic loop (bit-identical results).
#[inline]
fn matvec_fixed<const M: usize>(y: &mut [f64], a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    let y: &mut [f64; M] = y.try_into().expect("M rows");
    let mut acc = *y;
    // One stride check for the whole matrix; the column iterator checks no index.
    let a = a.try_as_col_major().expect("checked");
    for (c, &xj) in a.col_iter().zip(x) {
        let s = alpha * xj;
        if s == 0.0 {
            continue;
        }
        let c: &[f64; M] = c.as_slice().try_into().expect("M rows");
        for i in 0..M {
            acc[i] += s * c[i];
        }
    }
    *y = acc;
}

/// `[c_0ᵀx, c_1ᵀx, c_2ᵀx, c_3ᵀx]`, each with the partial sums of [`dot`] (bit-identical
/// to four calls); the columns have the length of `x`.
#[inline]
fn dot4(c: [&[f64]; 4], x: &[f64]) -> [f64; 4] {
    let n = x.len();
    let mut acc = [[0.0; 4]; 4];
    let main = n - n % 4;
    for i in (0..main).step_by(4) {
        let xs: &[f64; 4] = x[i..i + 4].try_into().expect("4 entries");
        for (acc_k, c_k) in acc.iter_mut().zip(&c) {
            let cs: &[f64; 4] = c_k[i..i + 4].try_into().expect("4 entries");
            for l in 0..4 {
                acc_k[l] += cs[l] * xs[l];
            }
        }
    }
    std::array::from_fn(|k| {
        let mut s = (acc[k][0] + acc[k][1]) + (acc[k][2] + acc[k][3]);
        for i in main..n {
            s += c[k][i] * x[i];
        }
        s
    })
}

/// [`matvec_t`] for a column-major `A` with `M` rows: fixed-size, unrolled dot products
/// with the partial sums of [`dot`] (bit-identical results).
#[inline]
fn matvec_t_fixed<const M: usize>(y: &mut [f64], accum: Accum, a: MatRef<'_, f64>, x: &[f64], alpha: f64) {
    let x: &[f64; M] = x.try_into().expect("M rows");
    let a = a.try_as_col_major().expect("checked");
    for (yj, c) in y.iter_mut().zip(a.col_iter()) {
        let c: &[f64; M] = c.as_slice().try_into().expect("M rows");
        let s = dot_fixed(c, x);
        *yj = if accum == Accum::Replace {
            alpha * s
        } else {
            *yj + alpha * s
        };
    }
}

/// `y += a x` for slices of one length: the row operation of the row-wise triangular
/// solves ([`super::Ldlt::solve_rows_in_place`], [`super::Lu::solve_rows_in_place`]).
pub(super) fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

#[cfg(test)]
mod tests {
    use faer::{Accum, Mat};

    use super::{dot, matvec, matvec_t};
    use crate::linalg::tests::{filled, naive};
    use crate::linalg::{as_mat, matmul};

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

    #[test]
    fn matvec_kernels_match_the_naive_product_on_strided_views() {
        // Sizes around the four-column blocking, on a submatrix of a larger matrix
        // (contiguous columns, column stride > rows) and on a transposed one (rows
        // strided): both the loop kernels and the strided fallbacks.
        for (m, n) in [
            (1, 1),
            (3, 5),
            (4, 4),
            (5, 3),
            (7, 9),
            (8, 8),
            (13, 6),
            (6, 13),
            (24, 12),
            (37, 5),
            (38, 9),
        ] {
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
                    // Column-major: the blocked dot products are those of `dot`, bit for bit.
                    if let Some(c) = a.col(j).try_as_col_major() {
                        assert_eq!(yt[j].to_bits(), dot(c.as_slice(), &xt).to_bits(), "matvec_t {m}x{n}");
                    }
                }
            }
        }
    }
}
