//! Reductions: dot products, norms and finiteness checks.

use faer::MatRef;

/// `aᵀb` with four partial sums (vectorisable).
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
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

/// [`dot`] for slices of a fixed length, with the same partial sums.
#[inline]
pub(super) fn dot_fixed<const M: usize>(a: &[f64; M], b: &[f64; M]) -> f64 {
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

/// Whether an entry of `v` is not zero (signed zeros are zero, NaN is not): the
/// entries' bits without the sign OR-ed together (one branch, vectorised).
#[inline]
pub(crate) fn any_nonzero(v: &[f64]) -> bool {
    v.iter().fold(0u64, |acc, x| acc | (x.to_bits() << 1)) != 0
}

/// `Σ |v_i|` with four partial sums (vectorisable); NaN if `v` holds a NaN.
#[inline]
pub(crate) fn norm_l1(v: &[f64]) -> f64 {
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

/// `max(a, b)` that keeps a NaN of either (`f64::max` drops it): residual norms and
/// violations must not hide a non-finite entry.
pub(crate) fn max_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() { f64::NAN } else { a.max(b) }
}

/// Largest absolute entry of a slice (0 for an empty slice; NaN if an entry is).
pub(crate) fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |a, x| max_nan(a, x.abs()))
}

/// Largest absolute entry of a matrix (0 for an empty matrix; NaN if an entry is).
pub(crate) fn norm_max(m: MatRef<'_, f64>) -> f64 {
    let mut r: f64 = 0.0;
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            r = max_nan(r, m[(i, j)].abs());
        }
    }
    r
}

/// Whether every entry of a matrix is zero (NaN is not): stops at the first other entry.
pub(crate) fn is_zero(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| match m.col(j).try_as_col_major() {
        Some(c) => c.as_slice().iter().all(|&v| v == 0.0),
        None => (0..m.nrows()).all(|i| m[(i, j)] == 0.0),
    })
}

/// Whether every entry of a matrix is finite.
pub(crate) fn all_finite(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

/// Whether the sum of all entries is finite: false if any entry is NaN or infinite (or
/// if the entries are so large that their sum overflows). One pass, no branches per entry.
pub(crate) fn sum_is_finite(m: MatRef<'_, f64>) -> bool {
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

/// Whether the lower triangle (diagonal included) of a square matrix holds only finite
/// values (its sum is finite).
#[inline]
pub(super) fn lower_sum_is_finite(m: MatRef<'_, f64>) -> bool {
    let mut sum = 0.0;
    for j in 0..m.ncols() {
        match m.col(j).try_as_col_major() {
            Some(c) => sum += c.as_slice()[j..].iter().sum::<f64>(),
            None => (j..m.nrows()).for_each(|i| sum += m[(i, j)]),
        }
    }
    sum.is_finite()
}
