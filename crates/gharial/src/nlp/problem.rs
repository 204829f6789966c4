//! What ProxNLP solves: the [`Nlp`] trait (a variable manifold, a cost, constraint
//! blocks `c_k(x) ∈ C_k`), the data it writes ([`NlpData`]), and [`NlpProblem`], an NLP
//! assembled from the library's models (a [`Cost`] of the variable alone, a
//! [`UnaryFunction`] and a [`ConstraintSet`] per constraint).

use std::ops::Range;
use std::sync::Arc;

use faer::{Accum, Mat};

use crate::constraints::ConstraintSet;
use crate::costs::{Cost, CostData};
use crate::error::{Error, Result, check_dim};
use crate::functions::{StageFunctionData, UnaryFunction, Workspace};
use crate::linalg::{copy, slice};
use crate::spaces::Manifold;

/// One constraint block `c_k(x) ∈ C_k` of an [`Nlp`]: its rows, its set and its penalty
/// scale (the block's penalty is `scale · mu`).
#[derive(Debug, Clone, Copy)]
pub struct ConstraintBlock<'a> {
    /// Number of rows of `c_k`.
    pub nr: usize,
    /// The set `C_k`.
    pub set: &'a dyn ConstraintSet,
    /// Penalty scale of the block (ProxDDP appendix C; 1 by default).
    pub scale: f64,
}

/// A set of tangent columns, as sorted disjoint ranges: where a dense block of an NLP's
/// derivatives sits. A block on `Columns` stores its columns contiguously, range after
/// range (its local column `k` is the `k`-th column of the set).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Columns {
    ranges: Vec<Range<usize>>,
    len: usize,
}

impl Columns {
    /// The union of `ranges` (in any order, overlapping or adjacent ones merged).
    pub fn new(ranges: impl IntoIterator<Item = Range<usize>>) -> Self {
        let mut r: Vec<Range<usize>> = ranges.into_iter().filter(|r| !r.is_empty()).collect();
        r.sort_unstable_by_key(|r| r.start);
        let mut merged: Vec<Range<usize>> = Vec::with_capacity(r.len());
        for x in r {
            match merged.last_mut() {
                Some(last) if x.start <= last.end => last.end = last.end.max(x.end),
                _ => merged.push(x),
            }
        }
        let len = merged.iter().map(|r| r.len()).sum();
        Self { ranges: merged, len }
    }

    /// All columns `0..n`.
    pub fn all(n: usize) -> Self {
        Self::new(std::iter::once(0..n))
    }

    /// Number of columns.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The ranges with the local column of their first element: `(local, global range)`.
    pub fn blocks(&self) -> impl Iterator<Item = (usize, Range<usize>)> + '_ {
        self.ranges.iter().scan(0, |off, r| {
            let local = *off;
            *off += r.len();
            Some((local, r.clone()))
        })
    }

    /// The global columns, in local order.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.ranges.iter().flat_map(Clone::clone)
    }

    /// The local column of global column `j`, `None` if `j` is not in the set.
    pub fn local(&self, j: usize) -> Option<usize> {
        self.blocks()
            .find(|(_, r)| r.contains(&j))
            .map(|(l, r)| l + j - r.start)
    }
}

/// Where the derivatives of an [`Nlp`] may be nonzero: the Jacobian of each constraint
/// block on a set of columns, and the cost Hessian and `Σ_k ∇²(ν_kᵀ c_k)` as sums of
/// dense symmetric terms, each on a set of columns. A dense NLP has every block and one
/// term on all columns ([`NlpSparsity::dense`]); an optimal control problem has blocks and
/// terms on the states and controls of one stage, which the sparse KKT solve exploits.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NlpSparsity {
    /// Per constraint block: the columns of its Jacobian.
    pub jacobian: Vec<Columns>,
    /// The columns of each Hessian term.
    pub hessian: Vec<Columns>,
}

impl NlpSparsity {
    /// Every one of `num_blocks` blocks and one Hessian term on all `ndx` columns.
    pub fn dense(ndx: usize, num_blocks: usize) -> Self {
        Self {
            jacobian: vec![Columns::all(ndx); num_blocks],
            hessian: vec![Columns::all(ndx)],
        }
    }
}

/// Everything an evaluation of an [`Nlp`] writes, allocated once by
/// [`Nlp::create_data`]. Constraint rows are stacked block after block; derivative
/// blocks are dense on the columns of the [`NlpSparsity`] the data was made with.
#[derive(Debug)]
pub struct NlpData {
    /// Cost `f(x)`.
    pub cost: f64,
    /// Stacked constraint values `c(x)` (`nc`).
    pub values: Vec<f64>,
    /// Cost gradient (`ndx`, tangent at `x`).
    pub grad: Vec<f64>,
    /// The cost Hessian, term by term: term `h` is `s_h x s_h` on the columns
    /// `sparsity.hessian[h]` (terms on shared columns add up).
    pub hess: Vec<Mat<f64>>,
    /// The constraint Jacobian, block by block: block `k` is `nr_k x s_k` on the columns
    /// `sparsity.jacobian[k]`.
    pub jac: Vec<Mat<f64>>,
    /// `Σ_k ∇²(ν_kᵀ c_k)` for the multipliers of the last [`Nlp::second_order`] (zero for
    /// blocks without second derivatives), term by term as `hess`.
    pub vhp: Vec<Mat<f64>>,
    /// Where the derivative blocks sit.
    pub sparsity: NlpSparsity,
    /// The NLP's own scratch memory (model data of its parts).
    pub ws: Workspace,
}

impl NlpData {
    /// Zero-filled data of a problem with tangent size `ndx`, constraint blocks of
    /// `block_rows` rows and derivative blocks on `sparsity` (one Jacobian column set
    /// per block).
    pub fn new(ndx: usize, block_rows: &[usize], sparsity: NlpSparsity, ws: Workspace) -> Self {
        debug_assert_eq!(block_rows.len(), sparsity.jacobian.len());
        let nc = block_rows.iter().sum();
        let square = |c: &Columns| Mat::zeros(c.len(), c.len());
        Self {
            cost: 0.0,
            values: vec![0.0; nc],
            grad: vec![0.0; ndx],
            hess: sparsity.hessian.iter().map(square).collect(),
            jac: block_rows
                .iter()
                .zip(&sparsity.jacobian)
                .map(|(&nr, c)| Mat::zeros(nr, c.len()))
                .collect(),
            vhp: sparsity.hessian.iter().map(square).collect(),
            sparsity,
            ws,
        }
    }

    /// `out = J_k dx` for constraint block `k` (`out` of the block's rows).
    pub fn jacobian_mul(&self, k: usize, dx: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        let jac = self.jac[k].as_ref();
        for (l, r) in self.sparsity.jacobian[k].blocks() {
            crate::linalg::matvec(out, Accum::Add, jac.subcols(l, r.len()), &dx[r], 1.0);
        }
    }

    /// `out += J_kᵀ v` for constraint block `k` (`v` of the block's rows, `out` of tangent
    /// size).
    pub fn jacobian_t_mul_add(&self, k: usize, v: &[f64], out: &mut [f64]) {
        let jac = self.jac[k].as_ref();
        for (l, r) in self.sparsity.jacobian[k].blocks() {
            crate::linalg::matvec_t(&mut out[r.clone()], Accum::Add, jac.subcols(l, r.len()), v, 1.0);
        }
    }
}

/// A nonlinear program `min f(x) s.t. c_k(x) ∈ C_k` over a manifold `x ∈ M`.
///
/// Derivatives are with respect to tangent perturbations of `x` (`x ⊕ δ`), as everywhere
/// in the library. Model / data: the NLP is immutable, everything an evaluation writes
/// lives in the [`NlpData`] it creates once.
pub trait Nlp: Send + Sync {
    /// The variable space.
    fn space(&self) -> &dyn Manifold;
    /// Number of constraint blocks.
    fn num_blocks(&self) -> usize;
    /// Constraint block `k < num_blocks()`.
    fn block(&self, k: usize) -> ConstraintBlock<'_>;
    /// A name for block `k` in error messages (allocates).
    fn block_name(&self, k: usize) -> String {
        format!("constraint {k}")
    }
    /// Allocates the data of an evaluation, with the [`NlpSparsity`] of the problem's
    /// derivatives ([`NlpSparsity::dense`] unless the problem knows better).
    fn create_data(&self) -> NlpData;
    /// Writes `f(x)` into `data.cost` and the stacked `c(x)` into `data.values`.
    fn evaluate(&self, x: &[f64], data: &mut NlpData);
    /// Writes the cost gradient and Hessian and the constraint Jacobian (the blocks of
    /// the data's [`NlpSparsity`]); `evaluate` has been called at the same point before.
    fn derivatives(&self, x: &[f64], data: &mut NlpData);
    /// Writes `Σ_k ∇²(ν_kᵀ c_k)(x)` into `data.vhp` (`nu` stacked like the values);
    /// `derivatives` has been called at the same point before.
    fn second_order(&self, x: &[f64], nu: &[f64], data: &mut NlpData);
}

/// Total number of constraint rows of `nlp`.
pub fn num_rows(nlp: &dyn Nlp) -> usize {
    (0..nlp.num_blocks()).map(|k| nlp.block(k).nr).sum()
}

/// A named constraint `c(x) ∈ C` of an [`NlpProblem`].
#[derive(Clone)]
pub struct NlpConstraint {
    /// Name used in error messages.
    pub name: String,
    /// The function `c`.
    pub func: Arc<dyn UnaryFunction>,
    /// The set `C`.
    pub set: Arc<dyn ConstraintSet>,
    /// Penalty scale (default 1).
    pub scale: f64,
}

impl NlpConstraint {
    /// The constraint `func(x) ∈ set` with penalty scale 1.
    pub fn new(name: impl Into<String>, func: Arc<dyn UnaryFunction>, set: Arc<dyn ConstraintSet>) -> Self {
        Self {
            name: name.into(),
            func,
            set,
            scale: 1.0,
        }
    }

    /// The same constraint with penalty scale `scale` (checked when added to a problem).
    pub fn with_scale(mut self, scale: f64) -> Self {
        self.scale = scale;
        self
    }
}

/// An NLP built from the library's models: a variable [`Manifold`], a [`Cost`] of the
/// variable alone (`nu = 0`, as a terminal cost) and constraints
/// `func_k(x) ∈ set_k` with [`UnaryFunction`]s (whose optional vector-Hessian products
/// give the exact Hessian).
#[derive(Clone)]
pub struct NlpProblem {
    space: Arc<dyn Manifold>,
    cost: Arc<dyn Cost>,
    constraints: Vec<NlpConstraint>,
}

impl std::fmt::Debug for NlpProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NlpProblem")
            .field("space", &self.space)
            .field(
                "constraints",
                &self.constraints.iter().map(|c| &c.name).collect::<Vec<_>>(),
            )
            .finish_non_exhaustive()
    }
}

/// Scratch of an [`NlpProblem`] evaluation: the models' data.
struct ProblemWs {
    cost: CostData,
    cons: Vec<StageFunctionData>,
}

impl NlpProblem {
    /// The unconstrained problem `min cost(x)` over `space`.
    ///
    /// # Errors
    /// If the cost's state sizes differ from the space's or it has controls.
    pub fn new(space: Arc<dyn Manifold>, cost: Arc<dyn Cost>) -> Result<Self> {
        check_dim("NlpProblem: cost nx", space.nx(), cost.nx())?;
        check_dim("NlpProblem: cost ndx", space.ndx(), cost.ndx())?;
        check_dim("NlpProblem: cost nu (a cost of the variable alone)", 0, cost.nu())?;
        Ok(Self {
            space,
            cost,
            constraints: Vec::new(),
        })
    }

    /// Adds a constraint.
    ///
    /// # Errors
    /// Names the constraint if its function's sizes differ from the space's, the set's
    /// dimension from the function's output, or the scale is not positive and finite.
    pub fn add_constraint(&mut self, c: NlpConstraint) -> Result<()> {
        let name = &c.name;
        check_dim(
            format!("NlpProblem constraint `{name}`: nx"),
            self.space.nx(),
            c.func.nx(),
        )?;
        check_dim(
            format!("NlpProblem constraint `{name}`: ndx"),
            self.space.ndx(),
            c.func.ndx(),
        )?;
        if let Some(d) = c.set.dim() {
            check_dim(format!("NlpProblem constraint `{name}`: set dimension"), c.func.nr(), d)?;
        }
        if !(c.scale.is_finite() && c.scale > 0.0) {
            return Err(Error::InvalidModel(format!(
                "NlpProblem constraint `{name}`: scale must be positive and finite, got {}",
                c.scale
            )));
        }
        self.constraints.push(c);
        Ok(())
    }

    /// As [`NlpProblem::add_constraint`], by value.
    ///
    /// # Errors
    /// As [`NlpProblem::add_constraint`].
    pub fn with_constraint(mut self, c: NlpConstraint) -> Result<Self> {
        self.add_constraint(c)?;
        Ok(self)
    }

    /// The constraints, in order.
    pub fn constraints(&self) -> &[NlpConstraint] {
        &self.constraints
    }
}

impl Nlp for NlpProblem {
    fn space(&self) -> &dyn Manifold {
        &*self.space
    }
    fn num_blocks(&self) -> usize {
        self.constraints.len()
    }
    fn block(&self, k: usize) -> ConstraintBlock<'_> {
        let c = &self.constraints[k];
        ConstraintBlock {
            nr: c.func.nr(),
            set: &*c.set,
            scale: c.scale,
        }
    }
    fn block_name(&self, k: usize) -> String {
        self.constraints[k].name.clone()
    }
    fn create_data(&self) -> NlpData {
        let ws = ProblemWs {
            cost: self.cost.create_data(),
            cons: self
                .constraints
                .iter()
                .map(|c| StageFunctionData::new(c.func.ndx(), 0, c.func.nr(), c.func.create_workspace()))
                .collect(),
        };
        let rows: Vec<usize> = self.constraints.iter().map(|c| c.func.nr()).collect();
        let sparsity = NlpSparsity::dense(self.space.ndx(), rows.len());
        NlpData::new(self.space.ndx(), &rows, sparsity, Box::new(ws))
    }
    fn evaluate(&self, x: &[f64], data: &mut NlpData) {
        let ws: &mut ProblemWs = data.ws.downcast_mut().expect("data of another NLP");
        self.cost.evaluate(x, &[], &mut ws.cost);
        data.cost = ws.cost.value;
        let mut off = 0;
        for (c, cd) in self.constraints.iter().zip(&mut ws.cons) {
            c.func.evaluate(x, cd);
            let nr = c.func.nr();
            data.values[off..off + nr].copy_from_slice(slice(&cd.value));
            off += nr;
        }
    }
    fn derivatives(&self, x: &[f64], data: &mut NlpData) {
        let ws: &mut ProblemWs = data.ws.downcast_mut().expect("data of another NLP");
        self.cost.derivatives(x, &[], &mut ws.cost);
        data.grad.copy_from_slice(ws.cost.lx());
        copy(data.hess[0].as_mut(), ws.cost.lxx.as_ref());
        for ((c, cd), jac) in self.constraints.iter().zip(&mut ws.cons).zip(&mut data.jac) {
            c.func.jacobian(x, cd);
            copy(jac.as_mut(), cd.jx.as_ref());
        }
    }
    fn second_order(&self, x: &[f64], nu: &[f64], data: &mut NlpData) {
        let ws: &mut ProblemWs = data.ws.downcast_mut().expect("data of another NLP");
        let vhp = &mut data.vhp[0];
        vhp.fill(0.0);
        let mut off = 0;
        for (c, cd) in self.constraints.iter().zip(&mut ws.cons) {
            let nr = c.func.nr();
            if c.func.has_vhp() {
                c.func.vhp(x, &nu[off..off + nr], cd);
                *vhp += &cd.vhp_xx;
            }
            off += nr;
        }
    }
}
