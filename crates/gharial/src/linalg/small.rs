//! Fixed-size kernels of the LLᵀ and LDLᵀ factorizations and solves up to 12 x 12
//! (dispatched by `with_small_dim!`): the matrix in registers, no call into
//! faer, whose fixed cost per call dominates at these sizes.

use faer::prelude::ReborrowMut;
use faer::{MatMut, MatRef};

use super::FactorError;
use super::views::{col_fixed, columns_fixed};

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
pub(super) fn small_factor<const N: usize>(mut a: MatMut<'_, f64>, cholesky: bool) -> Result<(), FactorError> {
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
/// of this many columns, which the compiler maps to vector registers (one AVX2 register;
/// the harness's `ur5` FDDP executes 0.35 % fewer instructions than with two).
const LANES: usize = 4;

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
pub(super) fn ldlt_solve_fixed<const N: usize>(f: MatRef<'_, f64>, rhs: MatMut<'_, f64>) {
    let l = columns::<N>(f);
    solve_columns::<N>(rhs, |v| {
        // L Y = B row by row (left-looking: one row in registers, the solved rows read),
        // subtracting l_ij y_j with j ascending: the right-looking loop's operations.
        for i in 1..N {
            let mut a = v[i];
            for j in 0..i {
                for k in 0..LANES {
                    a[k] -= l[j][i] * v[j][k];
                }
            }
            v[i] = a;
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
pub(super) fn llt_solve_fixed<const N: usize>(f: MatRef<'_, f64>, rhs: MatMut<'_, f64>) {
    let l = columns::<N>(f);
    solve_columns::<N>(rhs, |v| {
        // L Y = B row by row, left-looking as in `ldlt_solve_lanes`.
        for i in 0..N {
            let mut a = v[i];
            for j in 0..i {
                for k in 0..LANES {
                    a[k] -= l[j][i] * v[j][k];
                }
            }
            for k in 0..LANES {
                a[k] /= l[i][i];
            }
            v[i] = a;
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
