//! Small dense and tree-sparse kernels on column-major slices.
//!
//! The mass matrix of a kinematic tree factors as `M = Lᵀ D L` without fill-in, `L` unit
//! lower triangular with `L[k][i] ≠ 0` only when dof `i` is an ancestor of dof `k`
//! (Featherstone, *Rigid Body Dynamics Algorithms*, §6.5). `L` is stored by compressed
//! rows: row k holds `L[k][a]` for the ancestors `a` of k, nearest first, so that the
//! ancestors of an ancestor are a suffix of the row. The solves act on "rows stored as
//! columns": a right-hand side matrix `B` (n × m) is passed transposed, column-major.

use crate::error::{Error, Result};
use crate::model::NONE;

/// The tree of degrees of freedom: parent of each dof (`NONE` at a root), for each dof
/// `k` the end of a range `k..end` containing all its descendants, and the offsets of
/// the rows of a compressed `L` (one entry per ancestor). Ancestors are walked through
/// `parent`, so the tree takes O(n) memory whatever its depth.
#[derive(Clone, Copy)]
pub(crate) struct DofTree<'a> {
    pub(crate) parent: &'a [usize],
    pub(crate) subtree_end: &'a [usize],
    pub(crate) anc_start: &'a [usize],
}

/// The ancestors of a dof, nearest first.
#[derive(Clone)]
pub(crate) struct Ancestors<'a> {
    parent: &'a [usize],
    k: usize,
}

impl Iterator for Ancestors<'_> {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        let p = self.parent[self.k];
        if p == NONE {
            None
        } else {
            self.k = p;
            Some(p)
        }
    }
}

impl<'a> DofTree<'a> {
    /// Number of dofs.
    #[inline]
    pub(crate) fn n(&self) -> usize {
        self.parent.len()
    }

    /// Range of row k of a compressed `L` (one entry per ancestor of dof `k`).
    #[inline]
    pub(crate) fn anc_range(&self, k: usize) -> core::ops::Range<usize> {
        self.anc_start[k]..self.anc_start[k + 1]
    }

    /// Ancestors of dof `k`, nearest first.
    #[inline]
    pub(crate) fn ancestors(&self, k: usize) -> Ancestors<'a> {
        Ancestors { parent: self.parent, k }
    }

    /// Whether the dofs form one chain (dof `k`'s parent is `k − 1`): a serial arm, whose
    /// tree-sparse products are dense.
    #[inline]
    pub(crate) fn is_chain(&self) -> bool {
        self.parent
            .iter()
            .enumerate()
            .all(|(k, &p)| p == k.checked_sub(1).unwrap_or(NONE))
    }
}

/// `out = alpha a b` (or `out += alpha a b` with `accumulate`) for column-major slices,
/// `a` of `m × k`, `b` of `k × n`, `out` of `m × n`: faer's product, whose kernels (FMA,
/// the widest vectors of the CPU, chosen at run time) win over loops for the dense blocks
/// of the KKT inverse.
pub(crate) fn gemm(
    out: &mut [f64],
    a: &[f64],
    b: &[f64],
    (m, k, n): (usize, usize, usize),
    accumulate: bool,
    alpha: f64,
) {
    let dst = faer::MatMut::from_column_major_slice_mut(&mut out[..m * n], m, n);
    let lhs = faer::MatRef::from_column_major_slice(&a[..m * k], m, k);
    let rhs = faer::MatRef::from_column_major_slice(&b[..k * n], k, n);
    let accum = if accumulate {
        faer::Accum::Add
    } else {
        faer::Accum::Replace
    };
    faer::linalg::matmul::matmul(dst, accum, lhs, rhs, alpha, faer::Par::Seq);
}

/// Makes faer's packing buffer of the calling thread: faer keeps the packed operands of
/// its larger products in one buffer per thread, allocated at the thread's first such
/// product. One product of the given size on the given (zero) buffers, when a workspace
/// is created, keeps that allocation out of the algorithms on this thread (another
/// thread's first product allocates its own once).
pub(crate) fn reserve_packing_buffer(out: &mut [f64], a: &[f64], b: &[f64], dims: (usize, usize, usize)) {
    gemm(out, a, b, dims, false, 1.0);
}

/// `out[j] += Σ_(k, b) b · src[k·stride + j]` for every `j < out.len()`: a linear
/// combination of columns of `src` (column k starts at `k·stride`), accumulated in
/// registers sixteen entries at a time.
#[inline]
pub(crate) fn add_combination(out: &mut [f64], src: &[f64], stride: usize, terms: &[(usize, f64)]) {
    let n = out.len();
    let mut j = 0;
    while j + 16 <= n {
        add_combination_chunk::<16>(out, src, stride, terms, j);
        j += 16;
    }
    if j + 8 <= n {
        add_combination_chunk::<8>(out, src, stride, terms, j);
        j += 8;
    }
    if j + 4 <= n {
        add_combination_chunk::<4>(out, src, stride, terms, j);
        j += 4;
    }
    if j + 2 <= n {
        add_combination_chunk::<2>(out, src, stride, terms, j);
        j += 2;
    }
    if j < n {
        add_combination_chunk::<1>(out, src, stride, terms, j);
    }
}

/// Entries `j..j + W` of [`add_combination`].
#[inline(always)]
fn add_combination_chunk<const W: usize>(
    out: &mut [f64],
    src: &[f64],
    stride: usize,
    terms: &[(usize, f64)],
    j: usize,
) {
    let chunk: &mut [f64; W] = (&mut out[j..j + W]).try_into().expect("chunk of W entries");
    let mut acc = *chunk;
    for &(k, b) in terms {
        let o = k * stride + j;
        let s: &[f64; W] = src[o..o + W].try_into().expect("chunk of W entries");
        for t in 0..W {
            acc[t] += b * s[t];
        }
    }
    *chunk = acc;
}

/// `M⁻¹` (n × n, full symmetric) into `out` from the factorization `M = Lᵀ D L` left by
/// [`ltdl_factor`] in `l`, `d`: the rows of `Y = L⁻ᵀ` (row k lives on the subtree of k),
/// scaled by `D⁻¹`, then `X = L⁻¹ Y` root first (row k of X from the rows of its
/// ancestors).
pub(crate) fn ltdl_inverse(tree: &DofTree<'_>, l: &[f64], d: &[f64], out: &mut [f64], terms: &mut Vec<(usize, f64)>) {
    let n = tree.n();
    out.fill(0.0);
    for k in 0..n {
        out[k * n + k] = 1.0;
    }
    for k in (0..n).rev() {
        let end = tree.subtree_end[k];
        let (left, right) = out.split_at_mut(k * n);
        let yk = &right[k..end];
        for (i, &lki) in tree.ancestors(k).zip(&l[tree.anc_range(k)]) {
            axpy(-lki, yk, &mut left[i * n + k..i * n + end]);
        }
    }
    for k in 0..n {
        let s = 1.0 / d[k];
        out[k * n + k..k * n + tree.subtree_end[k]]
            .iter_mut()
            .for_each(|x| *x *= s);
    }
    for k in 0..n {
        terms.clear();
        terms.extend(tree.ancestors(k).zip(&l[tree.anc_range(k)]).map(|(i, &lki)| (i, -lki)));
        let (left, right) = out.split_at_mut(k * n);
        add_combination(&mut right[..n], left, n, terms);
    }
}

/// Least dofs of a branched tree whose [`minv_times_tree_sparse`] runs as one dense
/// product (faer's), whose kernels beat the column combinations that skip the zeros on
/// the quadruped (18 dofs) and the humanoid (35) measured.
pub(crate) const DENSE_TREE_PRODUCT: usize = 12;

/// `out = −S B` for a symmetric `S` and a `B` whose column `c` is zero outside the
/// ancestors of dof `c` and the range `c..subtree_end[c]` (n × n, column-major): each
/// output column combines only the columns of `S` selected by the nonzeros of `B`.
pub(crate) fn minv_times_tree_sparse(
    tree: &DofTree<'_>,
    s: &[f64],
    b: &[f64],
    out: &mut [f64],
    terms: &mut Vec<(usize, f64)>,
) {
    let n = tree.n();
    if n > 0 && tree.is_chain() {
        minus_dense_product(n, s, b, out);
        return;
    }
    if n >= DENSE_TREE_PRODUCT {
        // B's zeros are exact: the dense product gives the same sums with faer's kernels.
        gemm(out, s, b, (n, n, n), false, -1.0);
        return;
    }
    for c in 0..n {
        let col = &b[c * n..(c + 1) * n];
        terms.clear();
        terms.extend(tree.ancestors(c).map(|r| (r, -col[r])));
        terms.extend((c..tree.subtree_end[c]).map(|r| (r, -col[r])));
        let o = &mut out[c * n..(c + 1) * n];
        o.fill(0.0);
        add_combination(o, s, n, terms);
    }
}

/// `out = −S B` for dense n × n column-major `S`, `B` (a chain's tree-sparse product has
/// no zeros to skip): each output column accumulated in registers, the sizes of serial
/// arms (up to 8 dofs) unrolled.
fn minus_dense_product(n: usize, s: &[f64], b: &[f64], out: &mut [f64]) {
    match n {
        1 => minus_dense_product_fixed::<1>(s, b, out),
        2 => minus_dense_product_fixed::<2>(s, b, out),
        3 => minus_dense_product_fixed::<3>(s, b, out),
        4 => minus_dense_product_fixed::<4>(s, b, out),
        5 => minus_dense_product_fixed::<5>(s, b, out),
        6 => minus_dense_product_fixed::<6>(s, b, out),
        7 => minus_dense_product_fixed::<7>(s, b, out),
        8 => minus_dense_product_fixed::<8>(s, b, out),
        _ => {
            for (o, col) in out.chunks_exact_mut(n).zip(b.chunks_exact(n)) {
                o.fill(0.0);
                for (s_r, &b_r) in s.chunks_exact(n).zip(col) {
                    axpy(-b_r, s_r, o);
                }
            }
        }
    }
}

/// [`minus_dense_product`] for `n = N`.
fn minus_dense_product_fixed<const N: usize>(s: &[f64], b: &[f64], out: &mut [f64]) {
    for (o, col) in out.chunks_exact_mut(N).zip(b.chunks_exact(N)) {
        let mut acc = [0.0; N];
        for (s_r, &b_r) in s.chunks_exact(N).zip(col) {
            let s_r: &[f64; N] = s_r.try_into().expect("a column of N entries");
            for (a, x) in acc.iter_mut().zip(s_r) {
                *a -= b_r * x;
            }
        }
        o.copy_from_slice(&acc);
    }
}

/// `M = Lᵀ D L` for the full symmetric `m` (n × n, column-major): `L` by compressed rows
/// into `l` (row k: `L[k][a]` for the ancestors `a` of k), `D` into `d`. Leaves first,
/// each row k updates the rows of its ancestors with contiguous AXPYs (the ancestors of
/// the ancestor at position p are the row's suffix after p).
pub(crate) fn ltdl_factor(tree: &DofTree<'_>, m: &[f64], l: &mut [f64], d: &mut [f64]) -> Result<()> {
    let n = tree.n();
    for k in 0..n {
        d[k] = m[k * n + k];
        for (x, a) in l[tree.anc_range(k)].iter_mut().zip(tree.ancestors(k)) {
            *x = m[a * n + k];
        }
    }
    for k in (0..n).rev() {
        let dk = d[k];
        check_pivot("mass matrix", k, dk)?;
        let inv = 1.0 / dk;
        let rk = tree.anc_range(k);
        let (left, right) = l.split_at_mut(rk.start);
        let row = &mut right[..rk.len()];
        for (p, i) in tree.ancestors(k).enumerate() {
            let w = row[p];
            let a = w * inv;
            d[i] -= a * w;
            let ri = tree.anc_range(i);
            axpy(-a, &row[p + 1..], &mut left[ri]);
            row[p] = a;
        }
    }
    Ok(())
}

/// Solves `M X = B` in place for `X`, with `xt = Bᵀ` on entry and `Xᵀ` on return
/// (column-major, n columns of length m), from the factorization of [`ltdl_factor`].
pub(crate) fn ltdl_solve_rows(tree: &DofTree<'_>, m: usize, l: &[f64], d: &[f64], xt: &mut [f64]) {
    let n = tree.n();
    // Lᵀ y = b, leaves first.
    for k in (0..n).rev() {
        let (left, right) = xt.split_at_mut(k * m);
        let yk = &right[..m];
        for (i, &lki) in tree.ancestors(k).zip(&l[tree.anc_range(k)]) {
            axpy(-lki, yk, &mut left[i * m..(i + 1) * m]);
        }
    }
    for k in 0..n {
        let s = 1.0 / d[k];
        xt[k * m..(k + 1) * m].iter_mut().for_each(|x| *x *= s);
    }
    // L x = z, root first.
    for k in 0..n {
        let (left, right) = xt.split_at_mut(k * m);
        let xk = &mut right[..m];
        for (i, &lki) in tree.ancestors(k).zip(&l[tree.anc_range(k)]) {
            axpy(-lki, &left[i * m..(i + 1) * m], xk);
        }
    }
}

/// Checks a pivot of a factorization of `what`: a non-finite pivot comes from an
/// overflow ([`Error::NonFiniteResult`]), a pivot ≤ 0 from a matrix that is not positive
/// definite ([`Error::NotPositiveDefinite`]).
pub(crate) fn check_pivot(what: &str, index: usize, value: f64) -> Result<()> {
    if !value.is_finite() {
        Err(Error::NonFiniteResult {
            what: format!("{what} (factorization pivot)"),
            index,
        })
    } else if value <= 0.0 {
        Err(Error::NotPositiveDefinite {
            what: what.into(),
            index,
            value,
        })
    } else {
        Ok(())
    }
}

/// Zeroes a `6 × n` block column by column with inline stores (faer's `fill` calls
/// `memset` per column, dearer than six stores).
pub(crate) fn zero_6xn(mut m: faer::MatMut<'_, f64>) {
    for j in 0..m.ncols() {
        let mut c = m.as_mut().col_mut(j);
        match c.as_mut().try_as_col_major_mut() {
            Some(c) => *<&mut [f64; 6]>::try_from(c.as_slice_mut()).expect("6 rows") = [0.0; 6],
            None => c.fill(0.0),
        }
    }
}

/// `y += a x`.
#[inline]
pub(crate) fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

/// Dense Cholesky `A = L Lᵀ` in place (column-major n × n, lower triangle used and
/// overwritten).
pub(crate) fn cholesky_factor(n: usize, a: &mut [f64], what: &str) -> Result<()> {
    for j in 0..n {
        let mut djj = a[j * n + j];
        for k in 0..j {
            djj -= a[k * n + j] * a[k * n + j];
        }
        check_pivot(what, j, djj)?;
        let ljj = djj.sqrt();
        a[j * n + j] = ljj;
        for i in j + 1..n {
            let mut s = a[j * n + i];
            for k in 0..j {
                s -= a[k * n + i] * a[k * n + j];
            }
            a[j * n + i] = s / ljj;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ x = b` in place for one vector.
pub(crate) fn cholesky_solve(n: usize, l: &[f64], x: &mut [f64]) {
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= l[i * n + k] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
}

/// Inverse of a small symmetric positive-definite matrix (n ≤ 6) in place, by Cholesky.
pub(crate) fn small_spd_inverse(n: usize, a: &mut [[f64; 6]; 6]) -> Result<()> {
    let mut l = [[0.0; 6]; 6];
    for j in 0..n {
        let mut djj = a[j][j];
        for k in 0..j {
            djj -= l[j][k] * l[j][k];
        }
        check_pivot("joint-space articulated inertia", j, djj)?;
        l[j][j] = djj.sqrt();
        for i in j + 1..n {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s / l[j][j];
        }
    }
    // Columns of the inverse: solve L Lᵀ x = e_c.
    for c in 0..n {
        let mut x = [0.0; 6];
        x[c] = 1.0;
        for i in 0..n {
            let mut s = x[i];
            for k in 0..i {
                s -= l[i][k] * x[k];
            }
            x[i] = s / l[i][i];
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            for k in i + 1..n {
                s -= l[k][i] * x[k];
            }
            x[i] = s / l[i][i];
        }
        for r in 0..n {
            a[r][c] = x[r];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{DofTree, NONE, minv_times_tree_sparse};

    /// `−S B` by the definition, for column-major n × n slices.
    fn naive(n: usize, s: &[f64], b: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; n * n];
        for c in 0..n {
            for i in 0..n {
                out[c * n + i] = -(0..n).map(|r| s[r * n + i] * b[c * n + r]).sum::<f64>();
            }
        }
        out
    }

    /// The tree of `parent` (dofs numbered depth first), with its subtree ends and
    /// compressed-row offsets.
    fn tree_data(parent: &[usize]) -> (Vec<usize>, Vec<usize>) {
        let n = parent.len();
        let mut end: Vec<usize> = (1..=n).collect();
        for k in (0..n).rev() {
            if parent[k] != NONE {
                end[parent[k]] = end[parent[k]].max(end[k]);
            }
        }
        let mut anc = vec![0];
        for k in 0..n {
            let depth = std::iter::successors(Some(k), |&i| Some(parent[i]).filter(|&p| p != NONE)).count() - 1;
            anc.push(anc[k] + depth);
        }
        (end, anc)
    }

    /// The chain's dense path and the general tree-sparse path both give `−S B` (B with
    /// the tree's sparsity), to round-off.
    #[test]
    fn minv_times_tree_sparse_is_the_product() {
        let chain = [NONE, 0, 1, 2, 3, 4];
        let long_chain = [NONE, 0, 1, 2, 3, 4, 5, 6, 7, 8];
        let branched = [NONE, 0, 1, 0, 3, NONE, 5];
        for parent in [&chain[..], &long_chain[..], &branched[..]] {
            let n = parent.len();
            let (end, anc) = tree_data(parent);
            let tree = DofTree {
                parent,
                subtree_end: &end,
                anc_start: &anc,
            };
            assert_eq!(tree.is_chain(), parent != branched);
            let value = |i: usize, j: usize| ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0;
            let s: Vec<f64> = (0..n * n).map(|k| value(k % n, k / n) + value(k / n, k % n)).collect();
            let mut b = vec![0.0; n * n];
            for c in 0..n {
                for r in tree.ancestors(c).chain(c..end[c]) {
                    b[c * n + r] = value(r, c + 1);
                }
            }
            let mut out = vec![f64::NAN; n * n];
            minv_times_tree_sparse(&tree, &s, &b, &mut out, &mut Vec::new());
            for (x, y) in out.iter().zip(naive(n, &s, &b)) {
                assert!((x - y).abs() <= 1e-14, "{x} vs {y}");
            }
        }
    }

    /// `zero_6xn` zeroes its `6 × n` view and nothing else, with unit and non-unit row
    /// strides.
    #[test]
    fn zero_6xn_zeroes_its_view_only() {
        let mut m = faer::Mat::from_fn(8, 5, |i, j| (1 + i + 8 * j) as f64);
        super::zero_6xn(m.as_mut().subrows_mut(1, 6));
        let mut t = faer::Mat::from_fn(5, 8, |i, j| (1 + i + 5 * j) as f64);
        super::zero_6xn(t.as_mut().transpose_mut().subrows_mut(1, 6));
        for i in 0..8 {
            for j in 0..5 {
                let inside = (1..7).contains(&i);
                assert_eq!(m[(i, j)] == 0.0, inside, "({i}, {j})");
                assert_eq!(t[(j, i)] == 0.0, inside, "transposed ({i}, {j})");
            }
        }
    }
}
