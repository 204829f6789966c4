//! Products with a residual Jacobian `a` (`nr × n`, unit row stride): the Gram product
//! `aᵀ W a` (lower triangle, added to the destination) with a diagonal weight folded into
//! the rows or a full one given as the product `b = W a`, and `aᵀ g`.
//!
//! Residual Jacobians are often sparse by rows (a state error's identity part, a foot's
//! leg, a frame position that depends on the configuration only): [`GramScratch::load`]
//! finds the span of columns where each row can be nonzero and copies those rows, and
//! the products run as axpys over the spans. Dense Jacobians with enough rows (stacked
//! contact forces) go to faer's lower-triangular product, whose vectorised kernels win
//! there, and to the matrix-vector product.

use std::ops::Range;

use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef};

use super::matmul::matmul_lower;
use super::matvec::matvec_t;

/// The weight `W` of a Gram product `aᵀ W a`.
#[derive(Debug, Clone, Copy)]
pub(crate) enum GramWeight<'a> {
    /// `W = diag(s)` (`nr` entries): `Σ_r s_r a_rᵀ a_r`.
    Diagonal(&'a [f64]),
    /// `alpha aᵀ b`, with `b = W a` (`nr × n`, unit row stride) given.
    Product(MatRef<'a, f64>, f64),
}

/// Least rows of a Jacobian for faer's product: with fewer, its kernels run short
/// (measured: a dense `2 × 36` takes the same time both ways, a `3 × 36` half in faer).
const DENSE_MIN_ROWS: usize = 3;

/// Least multiply-adds of the rank-one kernel for faer's product (below, its fixed cost
/// per call and the full diagonal blocks it computes dominate; measured: a dense
/// `6 × 12`, 468 multiply-adds, is faster in the loops, a `12 × 12`, 936, three times
/// faster in faer).
const DENSE_MIN_WORK: usize = 768;

/// Most rows of a Jacobian whose spans are searched row by row (fewer than an AVX2
/// vector per column for the column-wise search).
const ROW_SCAN_MAX_ROWS: usize = 3;

/// The rows of a loaded Jacobian: the span of each, and their entries (copied only when
/// the rank-one kernels will read them).
#[derive(Debug, Clone)]
struct Rows {
    /// Row `r`'s entries over its span, at `r * n + c` (`nr × n`, row-major).
    at: Vec<f64>,
    /// Per row, the columns from its first to its last nonzero (or non-finite) entry.
    span: Vec<Range<usize>>,
    /// Scratch of the span search: per row, the first nonzero column and one past the
    /// last.
    first: Vec<usize>,
    last: Vec<usize>,
    /// Whether `at` holds the rows (the Jacobian was sparse).
    copied: bool,
    /// Whether every row is zero.
    zero: bool,
    /// `Some(c)` when the rows are those of the identity shifted by `c` columns (row `r`
    /// is `e_{c + r}ᵀ`: a state or control error).
    unit: Option<usize>,
    /// The loaded shape.
    nr: usize,
    n: usize,
}

impl Rows {
    fn new(nr: usize, n: usize) -> Self {
        Self {
            at: vec![0.0; nr * n],
            span: vec![0..0; nr],
            first: vec![0; nr],
            last: vec![0; nr],
            copied: false,
            zero: true,
            unit: None,
            nr: 0,
            n: 0,
        }
    }

    /// Reads the spans of the rows of `a`, and copies the rows when `copy(work)` says so
    /// for the rank-one kernel's `work` (multiply-adds of `aᵀ a`).
    fn load(&mut self, a: MatRef<'_, f64>, copy: impl FnOnce(usize) -> bool) {
        let (nr, n) = (a.nrows(), a.ncols());
        (self.nr, self.n) = (nr, n);
        // Every row nonzero in the first and last columns (a dense Jacobian) spans all
        // of them: nothing to search.
        let dense = n > 1 && {
            let (head, tail) = (contiguous(a, 0), contiguous(a, n - 1));
            head.iter().zip(tail).all(|(&h, &t)| h != 0.0 && t != 0.0)
        };
        if dense {
            self.span[..nr].fill(0..n);
        } else {
            self.find_spans(a);
        }
        let span = &self.span[..nr];
        self.zero = span.iter().all(|s| s.is_empty());
        self.unit = span.first().map(|s| s.start).filter(|&c| {
            span.iter()
                .enumerate()
                .all(|(r, s)| *s == (c + r..c + r + 1) && a[(r, c + r)] == 1.0)
        });
        self.copied = copy(span.iter().map(|s| triangle(s.len())).sum());
        if self.copied {
            for (r, s) in span.iter().enumerate() {
                for c in s.clone() {
                    self.at[r * n + c] = a[(r, c)];
                }
            }
        }
    }

    /// Per row of `a`, the first and one past the last nonzero column (a row without one
    /// gets the empty span): from columns in increasing order (branch-free, so that the
    /// loop over a column's rows is vectorised), or row by row for a few rows.
    fn find_spans(&mut self, a: MatRef<'_, f64>) {
        if a.nrows() <= ROW_SCAN_MAX_ROWS {
            self.find_spans_by_rows(a);
        } else {
            self.find_spans_by_columns(a);
        }
    }

    /// [`find_spans`](Self::find_spans) by columns from both ends (the updates of a
    /// column branch-free, vectorised over the rows): from the left until every row has
    /// its first nonzero, from the right until every row that has one has its last. A
    /// dense-looking Jacobian stops after a few columns each way, a sparse one reads about
    /// all of them once.
    fn find_spans_by_columns(&mut self, a: MatRef<'_, f64>) {
        let (nr, n) = (a.nrows(), a.ncols());
        let (first, last) = (&mut self.first[..nr], &mut self.last[..nr]);
        first.fill(usize::MAX);
        last.fill(0);
        for c in 0..n {
            for (f, &v) in first.iter_mut().zip(contiguous(a, c)) {
                *f = if v != 0.0 && *f == usize::MAX { c } else { *f };
            }
            if first.iter().all(|&f| f != usize::MAX) {
                break;
            }
        }
        for c in (0..n).rev() {
            for (l, &v) in last.iter_mut().zip(contiguous(a, c)) {
                *l = if v != 0.0 && *l == 0 { c + 1 } else { *l };
            }
            if last.iter().zip(&*first).all(|(&l, &f)| l != 0 || f == usize::MAX) {
                break;
            }
        }
        for ((s, &f), &l) in self.span[..nr].iter_mut().zip(&*first).zip(&*last) {
            *s = if f == usize::MAX { 0..0 } else { f..l };
        }
    }

    /// [`find_spans`](Self::find_spans) for a few rows, where a column holds less than a
    /// vector: each row read from its ends inwards up to its first and last nonzero
    /// entries (a foot's frame Jacobian: a few columns from each end instead of all).
    fn find_spans_by_rows(&mut self, a: MatRef<'_, f64>) {
        let n = a.ncols();
        for (r, s) in self.span[..a.nrows()].iter_mut().enumerate() {
            let nonzero = |c: &usize| a[(r, *c)] != 0.0;
            *s = match (0..n).find(nonzero) {
                Some(f) => f..(f..n).rfind(nonzero).map_or(f + 1, |l| l + 1),
                None => 0..0,
            };
        }
    }

    /// Row `r` (meaningful over its span).
    fn row(&self, r: usize) -> &[f64] {
        &self.at[r * self.n..(r + 1) * self.n]
    }
}

/// A residual Jacobian read for its products, and their scratch memory.
#[derive(Debug, Clone)]
pub(crate) struct GramScratch {
    /// The loaded Jacobian `a`.
    a: Rows,
    /// The rows of `b` (of a sparse [`GramWeight::Product`]).
    b: Rows,
    /// `diag(s) a` for faer's product.
    sa: Mat<f64>,
}

impl GramScratch {
    /// Scratch for Jacobians of at most `nr` rows and `n` columns.
    pub(crate) fn new(nr: usize, n: usize) -> Self {
        Self {
            a: Rows::new(nr, n),
            b: Rows::new(nr, n),
            sa: Mat::zeros(nr, n),
        }
    }

    /// Reads the Jacobian `a` (`nr × n`, unit row stride) for the products below, which
    /// take the same `a` (its values may not change in between).
    pub(crate) fn load(&mut self, a: MatRef<'_, f64>) {
        let (nr, n) = (a.nrows(), a.ncols());
        self.a.load(a, |work| !is_dense(work, nr, n));
    }

    /// Whether the loaded Jacobian is zero.
    pub(crate) fn is_zero(&self) -> bool {
        self.a.zero
    }

    /// `y += alpha aᵀ g` for the loaded `a`.
    pub(crate) fn matvec_t_add(&self, y: &mut [f64], a: MatRef<'_, f64>, g: &[f64], alpha: f64) {
        if !self.a.copied {
            return matvec_t(y, Accum::Add, a, g, alpha);
        }
        if self.a.zero {
            return;
        }
        if let Some(c) = self.a.unit {
            // The loop below with one entry 1.0 per row: the same sums.
            for (yc, gr) in y[c..c + self.a.nr].iter_mut().zip(g) {
                *yc += alpha * gr;
            }
            return;
        }
        for (r, s) in self.a.span[..self.a.nr].iter().enumerate() {
            let h = alpha * g[r];
            for (yc, v) in y[s.clone()].iter_mut().zip(&self.a.row(r)[s.clone()]) {
                *yc += h * v;
            }
        }
    }

    /// Lower triangle (diagonal included) of `dst += aᵀ W a` for the loaded `a` and a
    /// column-major `n × n` `dst`, whose strict upper triangle is not touched. Zero rows
    /// (or rows of zero weight) and the zero columns at either end of each row cost
    /// nothing; a NaN in `W` or in a row of nonzero weight reaches `dst`.
    pub(crate) fn gram_lower_add(&mut self, dst: MatMut<'_, f64>, a: MatRef<'_, f64>, weight: GramWeight<'_>) {
        let (nr, n) = (a.nrows(), a.ncols());
        debug_assert_eq!((self.a.nr, self.a.n, dst.nrows(), dst.ncols()), (nr, n, n, n));
        match (weight, self.a.copied) {
            (GramWeight::Diagonal(s), false) => {
                let mut sa = self.sa.as_mut().submatrix_mut(0, 0, nr, n);
                scale_rows(sa.rb_mut(), s, a);
                matmul_lower(dst, Accum::Add, a.transpose(), sa.as_ref(), 1.0);
            }
            (GramWeight::Product(b, alpha), false) => matmul_lower(dst, Accum::Add, a.transpose(), b, alpha),
            (GramWeight::Diagonal(s), true) => rank_one_updates(dst, &self.a, None, |r| s[r]),
            (GramWeight::Product(b, alpha), true) => {
                self.b.load(b, |_| true);
                rank_one_updates(dst, &self.a, Some(&self.b), |_| alpha);
            }
        }
    }
}

/// `dst = diag(s) a` (`s`: one weight per row of `a`).
pub(crate) fn scale_rows(mut dst: MatMut<'_, f64>, s: &[f64], a: MatRef<'_, f64>) {
    debug_assert_eq!((dst.nrows(), dst.ncols(), s.len()), (a.nrows(), a.ncols(), a.nrows()));
    for c in 0..a.ncols() {
        let pair = (
            dst.rb_mut().col_mut(c).try_as_col_major_mut(),
            a.col(c).try_as_col_major(),
        );
        if let (Some(d), Some(col)) = pair {
            for ((d, &v), &w) in d.as_slice_mut().iter_mut().zip(col.as_slice()).zip(s) {
                *d = w * v;
            }
        } else {
            for (i, &w) in s.iter().enumerate() {
                dst[(i, c)] = w * a[(i, c)];
            }
        }
    }
}

/// Whether the rank-one kernel's `work` multiply-adds on an `nr × n` Jacobian are
/// better left to faer's dense product: enough rows, enough work, and at least half of
/// a dense product's.
fn is_dense(work: usize, nr: usize, n: usize) -> bool {
    nr >= DENSE_MIN_ROWS && work >= DENSE_MIN_WORK && 2 * work >= nr * triangle(n)
}

/// `k (k + 1) / 2`: entries of a `k × k` lower triangle.
fn triangle(k: usize) -> usize {
    k * (k + 1) / 2
}

/// Column `c` of a matrix with unit row stride.
fn contiguous(m: MatRef<'_, f64>, c: usize) -> &[f64] {
    m.col(c).try_as_col_major().expect("unit row stride").as_slice()
}

/// `dst[c.., c] += Σ_r alpha_r b[r, c] a[r, c..]ᵀ` over the rows of `a`, with `b = a`
/// when `b` is `None`: one contiguous axpy per nonzero `b[r, c]` over the span of row `r`
/// of `a` (rows in order, so every entry sums its terms by increasing `r`).
fn rank_one_updates(mut dst: MatMut<'_, f64>, a: &Rows, b: Option<&Rows>, alpha: impl Fn(usize) -> f64) {
    let b = b.unwrap_or(a);
    for r in 0..a.nr {
        let (alpha, span) = (alpha(r), &a.span[r]);
        let (lo, hi) = (span.start, span.end);
        if alpha == 0.0 || lo >= hi {
            continue;
        }
        let (ar, br) = (a.row(r), b.row(r));
        for c in b.span[r].start..b.span[r].end.min(hi) {
            let h = alpha * br[c];
            let from = c.max(lo);
            if h == 0.0 {
                continue;
            }
            let col = dst.rb_mut().col_mut(c).try_as_col_major_mut().expect("unit row stride");
            for (d, v) in col.as_slice_mut()[from..hi].iter_mut().zip(&ar[from..hi]) {
                *d += h * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use super::Rows;

    #[test]
    fn both_span_searches_find_the_first_and_last_nonzero_of_every_row() {
        // Rows with zeros at both ends, in the middle, everywhere, a lone nonzero at
        // either end, NaN (a nonzero entry for the search), a dense block: against the
        // spans read off entry by entry.
        let patterns: [fn(usize, usize) -> f64; 6] = [
            |r, c| {
                if (r + 2..r + 5).contains(&c) {
                    1.0 + c as f64
                } else {
                    0.0
                }
            },
            |r, c| if c % (r + 2) == 1 { -2.0 } else { 0.0 },
            |r, c| {
                if r == 1 {
                    0.0
                } else if c == 0 || c == 3 * r {
                    0.5
                } else {
                    0.0
                }
            },
            |_, _| 0.0,
            |r, c| if c == r + 3 { f64::NAN } else { 0.0 },
            |_, c| if c >= 3 { 1.5 } else { 0.0 },
        ];
        for nr in 1..=8 {
            for n in [1usize, 2, 7, 40] {
                for (p, entry) in patterns.iter().enumerate() {
                    let a = Mat::from_fn(nr, n, entry);
                    let expected: Vec<_> = (0..nr)
                        .map(|r| {
                            let nz: Vec<usize> = (0..n).filter(|&c| a[(r, c)] != 0.0).collect();
                            nz.first().map_or(0..0, |&f| f..nz[nz.len() - 1] + 1)
                        })
                        .collect();
                    let mut rows = Rows::new(nr, n);
                    rows.find_spans_by_columns(a.as_ref());
                    assert_eq!(rows.span[..nr], expected[..], "columns: {nr} x {n}, pattern {p}");
                    if nr <= super::ROW_SCAN_MAX_ROWS {
                        let mut rows = Rows::new(nr, n);
                        rows.find_spans_by_rows(a.as_ref());
                        assert_eq!(rows.span[..nr], expected[..], "rows: {nr} x {n}, pattern {p}");
                    }
                }
            }
        }
    }
}
