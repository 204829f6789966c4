//! Gram products `aᵀ W a` of residual Jacobians ([`gram_lower_add`]): the lower
//! triangle, added to the destination, with a diagonal weight folded into the rows or a
//! full one given as the product `b = W a`.
//!
//! Residual Jacobians are often sparse by rows (a state error's identity part, a foot's
//! leg, a frame position that depends on the configuration only): such products run as
//! rank-one updates over the columns where each row can be nonzero. Dense Jacobians with
//! enough rows (stacked contact forces) go to faer's lower-triangular product, whose
//! vectorised kernels win there.

use std::ops::Range;

use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef};

use super::matmul::matmul_lower;

/// The weight `W` of a Gram product `aᵀ W a`.
#[derive(Debug, Clone, Copy)]
pub(crate) enum GramWeight<'a> {
    /// `W = diag(s)` (`nr` entries): `Σ_r s_r a_rᵀ a_r`.
    Diagonal(&'a [f64]),
    /// `alpha aᵀ b`, with `b = W a` (`nr × n`, unit row stride) given.
    Product(MatRef<'a, f64>, f64),
}

/// Sparse-kernel multiply-adds below which faer's product is never used (its fixed cost
/// per call and the full diagonal blocks it computes dominate there).
const DENSE_MIN_WORK: usize = 768;

/// Scratch of [`gram_lower_add`] for products of `nr × n` matrices.
#[derive(Debug, Clone)]
pub(crate) struct GramScratch {
    /// The rows of `a`, contiguous (`nr × n`, row-major).
    at: Vec<f64>,
    /// The rows of `b` (of a [`GramWeight::Product`]), contiguous.
    bt: Vec<f64>,
    /// Per row of `a`, the columns from its first to its last nonzero entry.
    a_span: Vec<Range<usize>>,
    /// The same for `b`.
    b_span: Vec<Range<usize>>,
    /// `diag(s) a` for the dense kernel.
    b: Mat<f64>,
}

impl GramScratch {
    /// Scratch for `a` of at most `nr` rows and `n` columns.
    pub(crate) fn new(nr: usize, n: usize) -> Self {
        Self {
            at: vec![0.0; nr * n],
            bt: vec![0.0; nr * n],
            a_span: vec![0..0; nr],
            b_span: vec![0..0; nr],
            b: Mat::zeros(nr, n),
        }
    }
}

/// Lower triangle (diagonal included) of `dst += aᵀ W a` for `a` of shape `nr × n` with
/// unit row stride and `dst` column-major `n × n`; the strict upper triangle is not
/// touched. Zero rows (or rows of zero weight), and the zero columns at either end of
/// each row, cost nothing; a NaN in `W` or in a row of nonzero weight reaches `dst`.
pub(crate) fn gram_lower_add(
    dst: MatMut<'_, f64>,
    a: MatRef<'_, f64>,
    weight: GramWeight<'_>,
    scratch: &mut GramScratch,
) {
    let (nr, n) = (a.nrows(), a.ncols());
    debug_assert_eq!((dst.nrows(), dst.ncols()), (n, n));
    let at = &mut scratch.at[..nr * n];
    rows_of(a, at, &mut scratch.a_span[..nr]);
    match weight {
        GramWeight::Diagonal(s) => {
            debug_assert_eq!(s.len(), nr);
            let work: usize = (0..nr)
                .filter(|&r| s[r] != 0.0)
                .map(|r| triangle(scratch.a_span[r].len()))
                .sum();
            if is_dense(work, nr, n) {
                let mut b = scratch.b.as_mut().submatrix_mut(0, 0, nr, n);
                for c in 0..n {
                    let bc = b.rb_mut().col_mut(c).try_as_col_major_mut().expect("owned");
                    for ((d, &v), &w) in bc.as_slice_mut().iter_mut().zip(contiguous(a, c)).zip(s) {
                        *d = w * v;
                    }
                }
                matmul_lower(dst, Accum::Add, a.transpose(), b.as_ref(), 1.0);
            } else {
                let rows = (0..nr).map(|r| (r, s[r]));
                rank_one_updates(dst, at, n, &scratch.a_span, None, rows);
            }
        }
        GramWeight::Product(b, alpha) => {
            debug_assert_eq!((b.nrows(), b.ncols()), (nr, n));
            let bt = &mut scratch.bt[..nr * n];
            rows_of(b, bt, &mut scratch.b_span[..nr]);
            let work: usize = (0..nr)
                .map(|r| scratch.a_span[r].len() * scratch.b_span[r].len() / 2)
                .sum();
            if is_dense(work, nr, n) {
                matmul_lower(dst, Accum::Add, a.transpose(), b, alpha);
            } else {
                let b_rows = Some((&*bt, &scratch.b_span[..]));
                rank_one_updates(dst, at, n, &scratch.a_span, b_rows, (0..nr).map(|r| (r, alpha)));
            }
        }
    }
}

/// Whether `work` multiply-adds of the sparse kernel are better left to faer's dense
/// product: enough of them, and at least half of a dense product's.
fn is_dense(work: usize, nr: usize, n: usize) -> bool {
    work >= DENSE_MIN_WORK && 4 * work >= nr * n * n
}

/// `k (k + 1) / 2`: entries of a `k × k` lower triangle.
fn triangle(k: usize) -> usize {
    k * (k + 1) / 2
}

/// Copies the rows of `m` (unit row stride) into `rows` (row-major) and writes the
/// nonzero span of each.
fn rows_of(m: MatRef<'_, f64>, rows: &mut [f64], span: &mut [Range<usize>]) {
    let n = m.ncols();
    for c in 0..n {
        for (r, &v) in contiguous(m, c).iter().enumerate() {
            rows[r * n + c] = v;
        }
    }
    for (r, s) in span.iter_mut().enumerate() {
        *s = nonzero_span(&rows[r * n..(r + 1) * n]);
    }
}

/// Column `c` of a matrix with unit row stride.
fn contiguous(m: MatRef<'_, f64>, c: usize) -> &[f64] {
    m.col(c).try_as_col_major().expect("unit row stride").as_slice()
}

/// The entries from the first to the last nonzero (or non-finite) one of `v`.
fn nonzero_span(v: &[f64]) -> Range<usize> {
    let start = v.iter().position(|&x| x != 0.0).unwrap_or(v.len());
    let end = v.iter().rposition(|&x| x != 0.0).map_or(start, |p| p + 1);
    start..end
}

/// `dst[c.., c] += Σ_r alpha_r b[r, c] a[r, c..]ᵀ` over the rows `(r, alpha_r)`, with
/// `b = a` when `b_rows` is `None`: one contiguous axpy per nonzero `b[r, c]` over the
/// span of row `r` of `a` (rows in order, so every entry sums its terms by increasing `r`).
fn rank_one_updates(
    mut dst: MatMut<'_, f64>,
    at: &[f64],
    n: usize,
    a_span: &[Range<usize>],
    b_rows: Option<(&[f64], &[Range<usize>])>,
    rows: impl Iterator<Item = (usize, f64)>,
) {
    for (r, alpha) in rows {
        let (lo, hi) = (a_span[r].start, a_span[r].end);
        let (b, b_span) = match b_rows {
            Some((bt, span)) => (&bt[r * n..(r + 1) * n], span[r].clone()),
            None => (&at[r * n..(r + 1) * n], a_span[r].clone()),
        };
        if alpha == 0.0 || lo >= hi {
            continue;
        }
        let a = &at[r * n..(r + 1) * n];
        for c in b_span.start..b_span.end.min(hi) {
            let h = alpha * b[c];
            let from = c.max(lo);
            if h == 0.0 || from >= hi {
                continue;
            }
            let col = dst.rb_mut().col_mut(c).try_as_col_major_mut().expect("unit row stride");
            for (d, v) in col.as_slice_mut()[from..hi].iter_mut().zip(&a[from..hi]) {
                *d += h * v;
            }
        }
    }
}
