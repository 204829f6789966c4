//! Small helpers shared by the models of the modelling layer.

use faer::reborrow::ReborrowMut;
use faer::{MatMut, MatRef};

use super::Workspace;

/// Downcasts a model's workspace to its concrete type.
///
/// # Panics
/// If the data was created by another model (a programming error, not user input).
pub(crate) fn downcast<T: 'static>(ws: &mut Workspace) -> &mut T {
    ws.downcast_mut::<T>()
        .expect("model data used with a model that did not create it")
}

/// `dst += alpha * src` for matrices of the same shape.
pub(crate) fn add_scaled(mut dst: MatMut<'_, f64>, alpha: f64, src: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (src.nrows(), src.ncols()));
    let contiguous = dst.row_stride() == 1 && src.row_stride() == 1;
    for j in 0..dst.ncols() {
        if contiguous {
            let mut dj = dst.rb_mut().col_mut(j);
            let d = dj
                .rb_mut()
                .try_as_col_major_mut()
                .expect("unit row stride")
                .as_slice_mut();
            let s = src.col(j).try_as_col_major().expect("unit row stride").as_slice();
            for (di, si) in d.iter_mut().zip(s) {
                *di += alpha * si;
            }
        } else {
            for i in 0..dst.nrows() {
                dst[(i, j)] += alpha * src[(i, j)];
            }
        }
    }
}

/// Writes the identity into a square matrix.
pub(crate) fn set_identity(mut dst: MatMut<'_, f64>) {
    dst.fill(0.0);
    dst.diagonal_mut().column_vector_mut().fill(1.0);
}

/// Copies a matrix argument of a constructor, checking its shape and finiteness.
pub(crate) fn checked_mat(
    what: &str,
    m: MatRef<'_, f64>,
    nrows: Option<usize>,
    ncols: Option<usize>,
) -> crate::Result<faer::Mat<f64>> {
    if let Some(r) = nrows {
        crate::error::check_dim(format!("{what} rows"), r, m.nrows())?;
    }
    if let Some(c) = ncols {
        crate::error::check_dim(format!("{what} columns"), c, m.ncols())?;
    }
    if !crate::linalg::all_finite(m) {
        return Err(crate::Error::non_finite(what));
    }
    Ok(m.to_owned())
}

/// Copies a vector argument of a constructor, checking its length and finiteness.
pub(crate) fn checked_vec(what: &str, v: &[f64], len: usize) -> crate::Result<Vec<f64>> {
    crate::error::check_dim(what, len, v.len())?;
    crate::error::check_finite(what, v)?;
    Ok(v.to_vec())
}

/// The symmetric part `(M + Mᵀ) / 2` of a square matrix argument, checked.
pub(crate) fn checked_sym(what: &str, m: MatRef<'_, f64>, n: usize) -> crate::Result<faer::Mat<f64>> {
    let mut s = checked_mat(what, m, Some(n), Some(n))?;
    crate::linalg::symmetrize(s.as_mut());
    Ok(s)
}

/// `dst = alpha * src` for matrices of the same shape.
pub(crate) fn copy_scaled(mut dst: MatMut<'_, f64>, alpha: f64, src: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols()), (src.nrows(), src.ncols()));
    for j in 0..dst.ncols() {
        for i in 0..dst.nrows() {
            dst[(i, j)] = alpha * src[(i, j)];
        }
    }
}

/// Checks that a time step is finite and positive.
pub(crate) fn check_dt(what: &str, dt: f64) -> crate::Result<()> {
    if dt.is_finite() && dt > 0.0 {
        Ok(())
    } else {
        Err(crate::Error::option(
            format!("{what} dt"),
            format!("must be finite and > 0, got {}", crate::error::Num(dt)),
        ))
    }
}

/// `dst *= alpha`.
pub(crate) fn scale(mut dst: MatMut<'_, f64>, alpha: f64) {
    for j in 0..dst.ncols() {
        for i in 0..dst.nrows() {
            dst[(i, j)] *= alpha;
        }
    }
}
