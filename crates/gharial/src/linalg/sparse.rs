//! Sparse symmetric matrices: [`SymmetricCsc`] (the upper triangle in compressed columns,
//! with its product), [`SparseLdlt`] (`A = L D Lᵀ` without pivoting in the given order, by
//! faer's simplicial or supernodal Cholesky, the inertia read off `D`) and [`amd_order`]
//! (faer's approximate minimum degree ordering).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::ldlt::factor::{LdltError, LdltRegularization};
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LdltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky, supernodal::SupernodalLdltRef,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::{FactorError, Inertia};

/// A symmetric `n x n` matrix by its upper triangle in compressed sparse columns (row
/// indices sorted within each column, every diagonal entry stored): the form faer's
/// symbolic Cholesky analyses.
#[derive(Debug, Clone)]
pub(crate) struct SymmetricCsc {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// The stored values, column after column.
    pub values: Vec<f64>,
}

impl SymmetricCsc {
    /// The `n x n` matrix with the entries `(i, j)` and `(j, i)` of `entries` (duplicates
    /// allowed) and the diagonal, values zero.
    pub fn from_entries(n: usize, entries: impl IntoIterator<Item = (usize, usize)>) -> Self {
        let mut rows = vec![Vec::new(); n];
        for (i, j) in entries {
            rows[i.max(j)].push(i.min(j));
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for (j, r) in rows.iter().enumerate() {
            let start = row_idx.len();
            row_idx.extend_from_slice(r);
            row_idx.push(j);
            sort_unique_tail(&mut row_idx, start);
            col_ptr.push(row_idx.len());
        }
        let nnz = row_idx.len();
        Self {
            n,
            col_ptr,
            row_idx,
            values: vec![0.0; nnz],
        }
    }

    /// Dimension.
    pub fn dim(&self) -> usize {
        self.n
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// The index in [`values`](Self::values) of entry `(i, j)` or `(j, i)`, if stored.
    pub fn position(&self, i: usize, j: usize) -> Option<usize> {
        let (i, j) = (i.min(j), i.max(j));
        let col = &self.row_idx[self.col_ptr[j]..self.col_ptr[j + 1]];
        col.binary_search(&i).ok().map(|k| self.col_ptr[j] + k)
    }

    /// `y += alpha A x` (both triangles from the stored one).
    pub fn mul_add(&self, y: &mut [f64], x: &[f64], alpha: f64) {
        for j in 0..self.n {
            let (mut yj, xj) = (0.0, alpha * x[j]);
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let (i, v) = (self.row_idx[k], self.values[k]);
                y[i] += v * xj;
                if i != j {
                    yj += v * x[i];
                }
            }
            y[j] += alpha * yj;
        }
    }

    fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx)
    }
}

/// `A = L D Lᵀ` of a sparse symmetric matrix without pivoting, in the order of its rows
/// (for quasi-definite matrices, such as primal-dual systems with the multiplier rows
/// first). The symbolic factorization and all memory are made in `new`; `factor` and
/// `solve_in_place` do not allocate.
pub(crate) struct SparseLdlt {
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    buf: MemBuffer,
}

impl std::fmt::Debug for SparseLdlt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseLdlt")
            .field("dim", &self.symbolic.nrows())
            .field("nnz_l", &self.l_values.len())
            .finish()
    }
}

impl SparseLdlt {
    /// The symbolic factorization of matrices with the pattern of `a`; `None` if faer
    /// cannot allocate it.
    pub fn new(a: &SymmetricCsc) -> Option<Self> {
        let symbolic = factorize_symbolic_cholesky(
            a.symbolic(),
            Side::Upper,
            SymmetricOrdering::Identity,
            CholeskySymbolicParams::default(),
        )
        .ok()?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_ldlt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        Some(Self {
            l_values: vec![0.0; symbolic.len_val()],
            buf: MemBuffer::try_new(req).ok()?,
            symbolic,
        })
    }

    /// Whether faer chose its supernodal factorization (else the simplicial one).
    #[cfg(test)]
    pub fn is_supernodal(&self) -> bool {
        matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// Number of stored entries of the factor.
    pub fn factor_nnz(&self) -> usize {
        self.l_values.len()
    }

    /// Factors `a` (the pattern given to `new`) and returns the inertia read off `D`.
    pub fn factor(&mut self, a: &SymmetricCsc) -> Result<Inertia, FactorError> {
        if !a.values.iter().all(|v| v.is_finite()) {
            return Err(FactorError::NonFinite);
        }
        let mat = SparseColMatRef::new(a.symbolic(), &a.values);
        let stack = MemStack::new(&mut self.buf);
        let no_regularization = LdltRegularization::default();
        match self.symbolic.factorize_numeric_ldlt(
            &mut self.l_values,
            mat,
            Side::Upper,
            no_regularization,
            Par::Seq,
            stack,
            Default::default(),
        ) {
            Ok(_) => {}
            Err(LdltError::ZeroPivot { index }) => return Err(FactorError::Singular { index }),
        }
        let mut inertia = Inertia::default();
        let mut count = |d: f64| {
            if !d.is_finite() {
                return false;
            }
            if d > 0.0 {
                inertia.positive += 1;
            } else if d < 0.0 {
                inertia.negative += 1;
            } else {
                inertia.zero += 1;
            }
            true
        };
        let all_finite = match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => s.col_ptr()[..s.ncols()].iter().all(|&k| count(self.l_values[k])),
            SymbolicCholeskyRaw::Supernodal(s) => {
                let l = SupernodalLdltRef::new(s, &self.l_values);
                (0..s.n_supernodes()).all(|k| {
                    let block = l.supernode(k).val();
                    (0..block.ncols()).all(|j| count(block[(j, j)]))
                })
            }
        };
        if all_finite {
            Ok(inertia)
        } else {
            Err(FactorError::NonFinite)
        }
    }

    /// Solves `A x = b` in place with the last factorization (`rhs` holds `b` on entry).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let stack = MemStack::new(&mut self.buf);
        let n = rhs.len();
        LdltRef::new(&self.symbolic, &self.l_values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            Par::Seq,
            stack,
        );
    }
}

/// A fill-reducing order of the symmetric pattern `rows[j]` (rows of column `j`, both
/// triangles or either): `order[k]` is the index placed at position `k`. `None` if faer
/// cannot allocate its workspace.
pub(crate) fn amd_order(rows: &[Vec<usize>]) -> Option<Vec<usize>> {
    let n = rows.len();
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for r in rows {
        let start = row_idx.len();
        row_idx.extend_from_slice(r);
        sort_unique_tail(&mut row_idx, start);
        col_ptr.push(row_idx.len());
    }
    let a = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
    let (mut fwd, mut inv) = (vec![0usize; n], vec![0usize; n]);
    let mut buf = MemBuffer::try_new(amd::order_maybe_unsorted_scratch::<usize>(n, row_idx.len())).ok()?;
    amd::order_maybe_unsorted(&mut fwd, &mut inv, a, amd::Control::default(), MemStack::new(&mut buf)).ok()?;
    Some(fwd)
}

/// Sorts `v[start..]` and removes its duplicates.
fn sort_unique_tail(v: &mut Vec<usize>, start: usize) {
    v[start..].sort_unstable();
    let mut w = start;
    for k in start..v.len() {
        if w == start || v[k] != v[w - 1] {
            v[w] = v[k];
            w += 1;
        }
    }
    v.truncate(w);
}
