//! What ProxNLP solves: the [`Nlp`] trait (a variable manifold, a cost, constraint
//! blocks `c_k(x) ∈ C_k`), the data it writes ([`NlpData`]), and [`NlpProblem`], an NLP
//! assembled from the library's models (a [`Cost`] of the variable alone, a
//! [`UnaryFunction`] and a [`ConstraintSet`] per constraint).

use std::sync::Arc;

use faer::Mat;

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

/// Everything an evaluation of an [`Nlp`] writes, allocated once by
/// [`Nlp::create_data`]. Constraint rows are stacked block after block.
#[derive(Debug)]
pub struct NlpData {
    /// Cost `f(x)`.
    pub cost: f64,
    /// Stacked constraint values `c(x)` (`nc`).
    pub values: Vec<f64>,
    /// Cost gradient (`ndx`, tangent at `x`).
    pub grad: Vec<f64>,
    /// Cost Hessian (`ndx x ndx`).
    pub hess: Mat<f64>,
    /// Constraint Jacobian (`nc x ndx`).
    pub jac: Mat<f64>,
    /// `Σ_k ∇²(ν_kᵀ c_k)` (`ndx x ndx`) for the multipliers of the last
    /// [`Nlp::second_order`] (zero for blocks without second derivatives).
    pub vhp: Mat<f64>,
    /// The NLP's own scratch memory (model data of its parts).
    pub ws: Workspace,
}

impl NlpData {
    /// Zero-filled data of a problem with tangent size `ndx` and `nc` constraint rows.
    pub fn new(ndx: usize, nc: usize, ws: Workspace) -> Self {
        Self {
            cost: 0.0,
            values: vec![0.0; nc],
            grad: vec![0.0; ndx],
            hess: Mat::zeros(ndx, ndx),
            jac: Mat::zeros(nc, ndx),
            vhp: Mat::zeros(ndx, ndx),
            ws,
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
    /// Allocates the data of an evaluation.
    fn create_data(&self) -> NlpData;
    /// Writes `f(x)` into `data.cost` and the stacked `c(x)` into `data.values`.
    fn evaluate(&self, x: &[f64], data: &mut NlpData);
    /// Writes the cost gradient and Hessian and the constraint Jacobian; `evaluate` has
    /// been called at the same point before.
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
        NlpData::new(self.space.ndx(), num_rows(self), Box::new(ws))
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
        copy(data.hess.as_mut(), ws.cost.lxx.as_ref());
        let mut off = 0;
        for (c, cd) in self.constraints.iter().zip(&mut ws.cons) {
            c.func.jacobian(x, cd);
            let nr = c.func.nr();
            copy(data.jac.as_mut().subrows_mut(off, nr), cd.jx.as_ref());
            off += nr;
        }
    }
    fn second_order(&self, x: &[f64], nu: &[f64], data: &mut NlpData) {
        let ws: &mut ProblemWs = data.ws.downcast_mut().expect("data of another NLP");
        data.vhp.fill(0.0);
        let mut off = 0;
        for (c, cd) in self.constraints.iter().zip(&mut ws.cons) {
            let nr = c.func.nr();
            if c.func.has_vhp() {
                c.func.vhp(x, &nu[off..off + nr], cd);
                data.vhp += &cd.vhp_xx;
            }
            off += nr;
        }
    }
}
