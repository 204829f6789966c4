//! ProxNLP's primal-dual Newton system
//!
//! ```text
//! [ -mu I    C       ] [δν]   [r_ν]
//! [ Cᵀ       H + δ I ] [δx] = [r_x]
//! ```
//!
//! (the multiplier rows first) and its solution by LDLᵀ without pivoting, the inertia
//! read off `D`: densely ([`KktSolver::Dense`], the whole matrix) or sparsely
//! ([`KktSolver::Sparse`], faer's sparse Cholesky on the upper triangle, the symbolic
//! factorization made once). Both eliminate every multiplier before any primal variable,
//! so that their pivots are `-mu` and then those of the reduced Hessian
//! `H + δI + Cᵀ C / mu` (the sparse solve orders the primal variables by AMD on the
//! pattern of that matrix): the inertia is `(ndx, nc, 0)` exactly when the reduced Hessian
//! is positive definite, for either.

use std::ops::Range;

use faer::{Accum, Mat, MatRef};

use super::options::KktSolver;
use super::problem::{Columns, NlpSparsity};
use crate::error::{Error, Result};
use crate::linalg::{Inertia, Ldlt, SparseLdlt, SymmetricCsc, as_mat, as_mat_mut, matmul};

/// The largest dense Newton system (`ndx + nc` rows) ProxNLP allocates: three matrices of
/// this dimension (the system, its regularised copy, the factorization) take 216 MB.
pub const MAX_KKT_DIM: usize = 3000;

/// [`KktSolver::Auto`] solves systems of more rows than this sparsely (when their
/// derivative blocks fill at most a tenth of the system). Measured (release, `proxnlp_kkt` example):
/// on the catalogue's `lqr` (186 rows) the sparse solve takes 0.29 of the dense one's
/// time, on `pendulum` (1206 rows) 0.04.
pub const AUTO_SPARSE_DIM: usize = 100;

/// [`KktSolver::Auto`] solves sparsely only when the derivative blocks fill at most this
/// fraction of the lower triangle of the system.
const SPARSE_DENSITY: f64 = 0.1;

/// How ProxNLP solves its Newton system, as chosen at `setup`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KktStats {
    /// Whether it is solved sparsely.
    pub sparse: bool,
    /// Its dimension `ndx + nc`.
    pub dim: usize,
    /// Stored entries of its lower triangle.
    pub nnz: usize,
    /// Stored entries of its factor `L` (`D` included).
    pub factor_nnz: usize,
}

/// A non-finite value in the Newton system or its step.
pub(super) struct NonFiniteStep;

/// The Newton system and its factorization, dense or sparse.
pub(super) enum Kkt {
    Dense(Box<DenseKkt>),
    Sparse(Box<SparseKkt>),
}

/// The dense system: the whole matrix, without and with the primal regularisation.
pub(super) struct DenseKkt {
    nc: usize,
    base: Mat<f64>,
    kkt: Mat<f64>,
    factor: Ldlt,
    resid: Vec<f64>,
}

/// The sparse system: the upper triangle in the elimination order (multipliers in their
/// order, then the primal variables in AMD order), with the positions of every block's
/// entries computed once.
pub(super) struct SparseKkt {
    nc: usize,
    base: SymmetricCsc,
    kkt: SymmetricCsc,
    factor: SparseLdlt,
    /// Row of primal variable `j` in the system: `nc + pinv[j]`.
    pinv: Vec<usize>,
    /// Positions of the diagonals of the multiplier rows and of the primal rows (by `j`).
    mdiag: Vec<usize>,
    pdiag: Vec<usize>,
    /// Per constraint block, the positions of its `m x s` entries of `C` (row-major).
    cpos: Vec<Vec<usize>>,
    /// Per Hessian term, the positions of its entries `(a, b)`, `a >= b` (column by
    /// column).
    hpos: Vec<Vec<usize>>,
    /// Right-hand side in the elimination order, solution, refinement residual.
    b: Vec<f64>,
    x: Vec<f64>,
    resid: Vec<f64>,
}

/// Whether `choice` means the sparse solve for a system of these blocks.
fn use_sparse(choice: KktSolver, n: usize, rows: &[Range<usize>], sp: &NlpSparsity) -> bool {
    match choice {
        KktSolver::Dense => false,
        KktSolver::Sparse => true,
        KktSolver::Auto => {
            let jac: usize = rows.iter().zip(&sp.jacobian).map(|(r, c)| r.len() * c.len()).sum();
            let hess: usize = sp.hessian.iter().map(|c| c.len() * c.len()).sum();
            let nnz = (jac + hess / 2 + n) as f64;
            n > AUTO_SPARSE_DIM && nnz <= SPARSE_DENSITY * (n * n) as f64 / 2.0
        }
    }
}

impl Kkt {
    /// The system of an NLP with `ndx` tangent columns, constraint blocks of rows `rows`
    /// and derivative blocks `sp`, dense or sparse as `choice` says.
    ///
    /// # Errors
    /// If the dense system would have more than [`MAX_KKT_DIM`] rows, or faer cannot
    /// allocate the sparse factorization.
    pub fn new(choice: KktSolver, ndx: usize, rows: &[Range<usize>], sp: &NlpSparsity) -> Result<Self> {
        let nc = rows.last().map_or(0, |r| r.end);
        let n = ndx + nc;
        if use_sparse(choice, n, rows, sp) {
            return Ok(Self::Sparse(Box::new(SparseKkt::new(ndx, rows, sp)?)));
        }
        if n > MAX_KKT_DIM {
            return Err(Error::InvalidModel(format!(
                "ProxNlp: the dense Newton system would have {n} rows (at most {MAX_KKT_DIM}); \
                 solve it with the sparse KKT (kkt: Sparse or Auto) or with proxddp"
            )));
        }
        Ok(Self::Dense(Box::new(DenseKkt {
            nc,
            base: Mat::zeros(n, n),
            kkt: Mat::zeros(n, n),
            factor: Ldlt::new(n),
            resid: vec![0.0; n],
        })))
    }

    /// How the system is solved and its size.
    pub fn stats(&self) -> KktStats {
        match self {
            Self::Dense(d) => {
                let n = d.base.nrows();
                KktStats {
                    sparse: false,
                    dim: n,
                    nnz: n * (n + 1) / 2,
                    factor_nnz: n * (n + 1) / 2,
                }
            }
            Self::Sparse(s) => KktStats {
                sparse: true,
                dim: s.base.dim(),
                nnz: s.base.nnz(),
                factor_nnz: s.factor.factor_nnz(),
            },
        }
    }

    /// Zeroes the system.
    pub fn clear(&mut self) {
        match self {
            Self::Dense(d) => d.base.fill(0.0),
            Self::Sparse(s) => s.base.values.fill(0.0),
        }
    }

    /// Adds Hessian term `h` (`m`, symmetric, on the primal columns `cols`).
    pub fn add_hessian(&mut self, h: usize, cols: &Columns, m: MatRef<'_, f64>) {
        match self {
            Self::Dense(d) => {
                let nc = d.nc;
                for (la, ra) in cols.blocks() {
                    for (lb, rb) in cols.blocks() {
                        let mut dst = d
                            .base
                            .as_mut()
                            .submatrix_mut(nc + ra.start, nc + rb.start, ra.len(), rb.len());
                        dst += m.submatrix(la, lb, ra.len(), rb.len());
                    }
                }
            }
            Self::Sparse(s) => {
                let (pos, v) = (&s.hpos[h], &mut s.base.values);
                let mut k = 0;
                for b in 0..m.ncols() {
                    for a in b..m.nrows() {
                        v[pos[k]] += m[(a, b)];
                        k += 1;
                    }
                }
            }
        }
    }

    /// Writes the rows `rows` of constraint block `b`: `c` (on the primal columns `cols`)
    /// and the diagonal `-mu_k`.
    pub fn set_constraint_rows(
        &mut self,
        b: usize,
        rows: &Range<usize>,
        cols: &Columns,
        c: MatRef<'_, f64>,
        mu_k: f64,
    ) {
        match self {
            Self::Dense(d) => {
                let nc = d.nc;
                for i in rows.clone() {
                    d.base[(i, i)] = -mu_k;
                }
                for (l, r) in cols.blocks() {
                    for (i, row) in rows.clone().enumerate() {
                        for (k, j) in r.clone().enumerate() {
                            d.base[(row, nc + j)] = c[(i, l + k)];
                            d.base[(nc + j, row)] = c[(i, l + k)];
                        }
                    }
                }
            }
            Self::Sparse(s) => {
                for i in rows.clone() {
                    s.base.values[s.mdiag[i]] = -mu_k;
                }
                let (pos, v, sc) = (&s.cpos[b], &mut s.base.values, c.ncols());
                for i in 0..c.nrows() {
                    for k in 0..sc {
                        v[pos[i * sc + k]] = c[(i, k)];
                    }
                }
            }
        }
    }

    /// Solves the system with the primal regularisation `preg` (right-hand side `rhs`,
    /// multipliers first, into `step`), with one step of iterative refinement. Returns
    /// `Ok(false)` when the inertia is not `(ndx, nc, 0)`.
    pub fn solve(&mut self, preg: f64, rhs: &[f64], step: &mut [f64]) -> std::result::Result<bool, NonFiniteStep> {
        match self {
            Self::Dense(d) => d.solve(preg, rhs, step),
            Self::Sparse(s) => s.solve(preg, rhs, step),
        }
    }
}

/// Whether the inertia is that of a positive definite reduced Hessian.
fn right_inertia(inertia: Inertia, nc: usize, n: usize) -> bool {
    inertia.positive == n - nc && inertia.negative == nc && inertia.zero == 0
}

impl DenseKkt {
    fn solve(&mut self, preg: f64, rhs: &[f64], step: &mut [f64]) -> std::result::Result<bool, NonFiniteStep> {
        let n = self.base.nrows();
        crate::linalg::copy(self.kkt.as_mut(), self.base.as_ref());
        for i in self.nc..n {
            self.kkt[(i, i)] += preg;
        }
        if !crate::linalg::all_finite(self.kkt.as_ref()) {
            return Err(NonFiniteStep);
        }
        crate::linalg::copy(self.factor.matrix_mut(), self.kkt.as_ref());
        match self.factor.factor_filled() {
            Ok(inertia) if right_inertia(inertia, self.nc, n) => {}
            _ => return Ok(false),
        }
        step.copy_from_slice(rhs);
        self.factor.solve_in_place(as_mat_mut(step));
        // One refinement step: δ += K⁻¹ (rhs - K δ).
        self.resid.copy_from_slice(rhs);
        matmul(
            as_mat_mut(&mut self.resid),
            Accum::Add,
            self.kkt.as_ref(),
            as_mat(step),
            -1.0,
        );
        self.factor.solve_in_place(as_mat_mut(&mut self.resid));
        for (s, r) in step.iter_mut().zip(&self.resid) {
            *s += r;
        }
        Ok(true)
    }
}

impl SparseKkt {
    fn new(ndx: usize, rows: &[Range<usize>], sp: &NlpSparsity) -> Result<Self> {
        let nc = rows.last().map_or(0, |r| r.end);
        let n = ndx + nc;
        let fail = || Error::InvalidModel(format!("ProxNlp: cannot allocate the sparse factorization of {n} rows"));
        // The pattern of the reduced Hessian H + Cᵀ C / mu: the Hessian terms and the
        // columns of every constraint block, each a clique.
        let mut adj = vec![Vec::new(); ndx];
        for cols in sp.hessian.iter().chain(&sp.jacobian) {
            for j in cols.iter() {
                adj[j].extend(cols.iter());
            }
        }
        let order = crate::linalg::amd_order(&adj).ok_or_else(fail)?;
        let mut pinv = vec![0; ndx];
        for (k, &j) in order.iter().enumerate() {
            pinv[j] = k;
        }
        let row_of = |j: usize| nc + pinv[j];
        // The entries of C and of the Hessian terms.
        let c_entries = rows
            .iter()
            .zip(&sp.jacobian)
            .flat_map(|(r, cols)| r.clone().flat_map(move |i| cols.iter().map(move |j| (i, row_of(j)))));
        let h_entries = sp.hessian.iter().flat_map(|cols| {
            cols.iter()
                .flat_map(move |a| cols.iter().map(move |b| (row_of(a), row_of(b))))
        });
        let base = SymmetricCsc::from_entries(n, c_entries.chain(h_entries));
        let pos = |i: usize, j: usize| base.position(i, j).expect("in the pattern");
        let cpos = rows
            .iter()
            .zip(&sp.jacobian)
            .map(|(r, cols)| {
                r.clone()
                    .flat_map(|i| cols.iter().map(move |j| (i, j)))
                    .map(|(i, j)| pos(i, row_of(j)))
                    .collect()
            })
            .collect();
        let hpos = sp
            .hessian
            .iter()
            .map(|cols| {
                let c: Vec<usize> = cols.iter().collect();
                (0..c.len())
                    .flat_map(|b| (b..c.len()).map(move |a| (a, b)))
                    .map(|(a, b)| pos(row_of(c[a]), row_of(c[b])))
                    .collect()
            })
            .collect();
        let factor = SparseLdlt::new(&base).ok_or_else(fail)?;
        Ok(Self {
            nc,
            mdiag: (0..nc).map(|i| pos(i, i)).collect(),
            pdiag: (0..ndx).map(|j| pos(row_of(j), row_of(j))).collect(),
            kkt: base.clone(),
            base,
            factor,
            pinv,
            cpos,
            hpos,
            b: vec![0.0; n],
            x: vec![0.0; n],
            resid: vec![0.0; n],
        })
    }

    fn solve(&mut self, preg: f64, rhs: &[f64], step: &mut [f64]) -> std::result::Result<bool, NonFiniteStep> {
        let (nc, n) = (self.nc, self.base.dim());
        self.kkt.values.copy_from_slice(&self.base.values);
        for &p in &self.pdiag {
            self.kkt.values[p] += preg;
        }
        if !self.kkt.values.iter().all(|v| v.is_finite()) {
            return Err(NonFiniteStep);
        }
        match self.factor.factor(&self.kkt) {
            Ok(inertia) if right_inertia(inertia, nc, n) => {}
            _ => return Ok(false),
        }
        self.b[..nc].copy_from_slice(&rhs[..nc]);
        for (j, &p) in self.pinv.iter().enumerate() {
            self.b[nc + p] = rhs[nc + j];
        }
        self.x.copy_from_slice(&self.b);
        self.factor.solve_in_place(&mut self.x);
        // One refinement step: δ += K⁻¹ (rhs - K δ).
        self.resid.copy_from_slice(&self.b);
        self.kkt.mul_add(&mut self.resid, &self.x, -1.0);
        self.factor.solve_in_place(&mut self.resid);
        step[..nc]
            .iter_mut()
            .zip(&self.x[..nc])
            .zip(&self.resid[..nc])
            .for_each(|((s, x), r)| *s = x + r);
        for (j, &p) in self.pinv.iter().enumerate() {
            step[nc + j] = self.x[nc + p] + self.resid[nc + p];
        }
        Ok(true)
    }
}
