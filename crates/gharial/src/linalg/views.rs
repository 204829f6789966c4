//! Views: slices and faer views of owned columns and matrices, and fixed-size arrays of
//! the columns of column-major matrices (for the fixed-size kernels).

use faer::{Col, ColMut, ColRef, Mat, MatMut, MatRef};

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
pub(crate) fn col_of(m: &Mat<f64>, j: usize) -> &[f64] {
    m.col(j)
        .try_as_col_major()
        .expect("columns of owned matrices are contiguous")
        .as_slice()
}

/// The contiguous mutable storage of column `j` of an owned matrix.
#[inline]
pub(crate) fn col_of_mut(m: &mut Mat<f64>, j: usize) -> &mut [f64] {
    m.col_mut(j)
        .try_as_col_major_mut()
        .expect("columns of owned matrices are contiguous")
        .as_slice_mut()
}

/// A column view of a slice.
#[cfg(test)]
#[inline]
pub(crate) fn col(s: &[f64]) -> ColRef<'_, f64> {
    ColRef::from_slice(s)
}

/// An `n x 1` matrix view of a slice.
#[inline]
pub(crate) fn as_mat(s: &[f64]) -> MatRef<'_, f64> {
    ColRef::from_slice(s).as_mat()
}

/// An `n x 1` mutable matrix view of a slice.
#[inline]
pub(crate) fn as_mat_mut(s: &mut [f64]) -> MatMut<'_, f64> {
    ColMut::from_slice_mut(s).as_mat_mut()
}

/// The columns of a column-major `N x N` matrix, copied into an array (fixed size: the
/// loops of the symmetrization kernels unroll without bounds checks).
#[inline]
pub(super) fn columns_fixed<const N: usize>(m: MatRef<'_, f64>) -> [[f64; N]; N] {
    let mut a = [[0.0; N]; N];
    for (j, aj) in a.iter_mut().enumerate() {
        *aj = *col_fixed::<N>(m, j);
    }
    a
}

/// Column `j` of a column-major view (unit row stride) as a slice.
#[inline]
pub(crate) fn col_slice(m: MatRef<'_, f64>, j: usize) -> &[f64] {
    m.col(j).try_as_col_major().expect("a column-major view").as_slice()
}

/// Column `j` of a column-major mutable view (unit row stride) as a slice.
#[inline]
pub(crate) fn col_slice_mut(m: MatMut<'_, f64>, j: usize) -> &mut [f64] {
    m.col_mut(j)
        .try_as_col_major_mut()
        .expect("a column-major view")
        .as_slice_mut()
}

/// Column `j` of a column-major matrix with `N` rows as a fixed-size array.
#[inline]
pub(super) fn col_fixed<const N: usize>(m: MatRef<'_, f64>, j: usize) -> &[f64; N] {
    m.col(j)
        .try_as_col_major()
        .expect("checked")
        .as_slice()
        .try_into()
        .expect("N rows")
}

/// Column `j` of a column-major matrix with `N` rows as a fixed-size array.
#[inline]
pub(super) fn col_fixed_mut<'a, const N: usize>(m: MatMut<'a, f64>, j: usize) -> &'a mut [f64; N] {
    m.col_mut(j)
        .try_as_col_major_mut()
        .expect("checked")
        .as_slice_mut()
        .try_into()
        .expect("N rows")
}
