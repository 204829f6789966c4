//! An optimal control problem as one NLP ([`OcpNlp`]) and ProxNLP as a
//! [`Solver`](crate::solvers::Solver) of optimal control problems ([`ProxNlpOcp`]).
//!
//! The variable is `z = (x_0, .., x_N, u_0, .., u_{N-1})` on the product of the state
//! manifolds and the control spaces. The constraint blocks, in order: the initial
//! condition `r_0(x_0) = 0`, the dynamics `f_t(x_t, u_t, x_{t+1}) = 0` of every stage
//! (explicit `φ(x, u) ⊖ y` or implicit), then the path constraints of every stage and the
//! terminal constraints with their sets. Everything is evaluated through
//! [`ProblemData`], as every solver of the library does, so the multipliers are those of
//! [`Solution`]: `λ_0`, `λ_{t+1}`, `ν_t`, `ν_N`.

use std::ops::Range;
use std::sync::Arc;
use std::time::Duration;

use faer::{Mat, MatRef};

use super::options::ProxNlpOptions;
use super::problem::{Columns, ConstraintBlock, Nlp, NlpData, NlpSparsity};
use super::solver::ProxNlp;
use crate::constraints::EqualityConstraintSet;
use crate::error::{Error, Result};
use crate::problem::{DynamicsData, Problem, ProblemData, StageModel};
use crate::solvers::log::Table;
use crate::solvers::proxddp::TABLE;
use crate::solvers::skeleton::{Signature, solution_for};
use crate::solvers::{Callback, InitialGuess, Solution};
use crate::spaces::{CartesianProduct, Manifold, VectorSpace};

/// The set of the initial-condition and dynamics blocks.
static EQUALITY: EqualityConstraintSet = EqualityConstraintSet;

/// What a constraint block of an [`OcpNlp`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Init,
    Dynamics(usize),
    /// Constraint `k` of knot `t` (`t = N`: terminal).
    Path(usize, usize),
}

/// The layout of an optimal control problem as an NLP: the product space, where each
/// state and control sits in `z` and its tangent, and the constraint blocks. Made once
/// (it allocates) for problems of the same dimensions.
#[derive(Debug, Clone)]
pub struct OcpLayout {
    space: CartesianProduct,
    /// Representation and tangent ranges of `x_t` (`t = 0..=N`) and `u_t` (`t < N`).
    x_rep: Vec<Range<usize>>,
    x_tan: Vec<Range<usize>>,
    u_rep: Vec<Range<usize>>,
    u_tan: Vec<Range<usize>>,
    /// The blocks, their rows and scales.
    blocks: Vec<(Kind, Range<usize>, f64)>,
    /// Rows of `λ_0`, `λ_{t+1}` (index `t + 1`), and of `ν_t` (`t = 0..=N`).
    lambda_rows: Vec<Range<usize>>,
    nu_rows: Vec<Range<usize>>,
    /// The columns of each block's Jacobian and of the Hessian terms: term `t < N` on
    /// `(x_t, u_t, x_{t+1})` (stage cost and dynamics), term `N` on `x_N`.
    sparsity: NlpSparsity,
}

impl OcpLayout {
    /// The layout of `problem`; the initial-condition and dynamics blocks get the penalty
    /// scale `dyn_scale` (ProxDDP's `dyn_al_scale`), the path and terminal constraints
    /// their own [`scale`](crate::problem::StageConstraint::scale).
    pub fn new(problem: &Problem, dyn_scale: f64) -> Self {
        let n = problem.horizon();
        let mut parts: Vec<Arc<dyn Manifold>> = (0..=n).map(|t| problem.space(t).clone()).collect();
        parts.extend((0..n).map(|t| Arc::new(VectorSpace::new(problem.nu(t))) as Arc<dyn Manifold>));
        let space = CartesianProduct::new(parts);
        let ranges = |sizes: &mut dyn Iterator<Item = usize>, start: usize| {
            let mut off = start;
            sizes
                .map(|s| {
                    off += s;
                    off - s..off
                })
                .collect::<Vec<_>>()
        };
        let x_rep = ranges(&mut (0..=n).map(|t| problem.space(t).nx()), 0);
        let x_tan = ranges(&mut (0..=n).map(|t| problem.space(t).ndx()), 0);
        let u_rep = ranges(&mut (0..n).map(|t| problem.nu(t)), x_rep[n].end);
        let u_tan = ranges(&mut (0..n).map(|t| problem.nu(t)), x_tan[n].end);
        let mut blocks = vec![(Kind::Init, 0..problem.nc0(), dyn_scale)];
        let mut off = problem.nc0();
        for t in 0..n {
            let nr = problem.space(t + 1).ndx();
            blocks.push((Kind::Dynamics(t), off..off + nr, dyn_scale));
            off += nr;
        }
        let mut nu_rows = Vec::with_capacity(n + 1);
        for t in 0..=n {
            let start = off;
            for (k, c) in problem.constraints(t).iter().enumerate() {
                blocks.push((Kind::Path(t, k), off..off + c.nr(), c.scale));
                off += c.nr();
            }
            nu_rows.push(start..off);
        }
        let lambda_rows = blocks[..=n].iter().map(|b| b.1.clone()).collect();
        let stage = |t: usize| Columns::new([x_tan[t].clone(), u_tan[t].clone(), x_tan[t + 1].clone()]);
        let knot = |t: usize| match t < n {
            true => Columns::new([x_tan[t].clone(), u_tan[t].clone()]),
            false => Columns::new([x_tan[t].clone()]),
        };
        let sparsity = NlpSparsity {
            jacobian: blocks
                .iter()
                .map(|(kind, _, _)| match *kind {
                    Kind::Init => Columns::new([x_tan[0].clone()]),
                    Kind::Dynamics(t) => stage(t),
                    Kind::Path(t, _) => knot(t),
                })
                .collect(),
            hessian: (0..n).map(stage).chain([knot(n)]).collect(),
        };
        Self {
            space,
            x_rep,
            x_tan,
            u_rep,
            u_tan,
            blocks,
            lambda_rows,
            nu_rows,
            sparsity,
        }
    }

    /// The variable space: states `x_0..x_N`, then controls `u_0..u_{N-1}`.
    pub fn space(&self) -> &CartesianProduct {
        &self.space
    }

    /// Whether `problem` has the constraint blocks of this layout (same constraints per
    /// knot, same rows), without allocating.
    pub fn matches(&self, problem: &Problem) -> bool {
        let n = problem.horizon();
        n + 1 == self.x_tan.len()
            && (0..=n).all(|t| self.nu_rows[t].len() == problem.constraints(t).iter().map(|c| c.nr()).sum())
            && self.blocks.iter().all(|(kind, rows, _)| match *kind {
                Kind::Init => rows.len() == problem.nc0(),
                Kind::Dynamics(t) => t < n && rows.len() == problem.space(t + 1).ndx(),
                Kind::Path(t, c) => t <= n && problem.constraints(t).get(c).is_some_and(|k| k.nr() == rows.len()),
            })
    }

    /// Packs a trajectory into a variable `z` (sizes as the problem's).
    pub fn pack(&self, xs: &[Vec<f64>], us: &[Vec<f64>], z: &mut [f64]) {
        for (r, x) in self.x_rep.iter().zip(xs) {
            z[r.clone()].copy_from_slice(x);
        }
        for (r, u) in self.u_rep.iter().zip(us) {
            z[r.clone()].copy_from_slice(u);
        }
    }

    /// Unpacks a variable `z` into a trajectory.
    pub fn unpack(&self, z: &[f64], xs: &mut [Vec<f64>], us: &mut [Vec<f64>]) {
        for (r, x) in self.x_rep.iter().zip(xs) {
            x.copy_from_slice(&z[r.clone()]);
        }
        for (r, u) in self.u_rep.iter().zip(us) {
            u.copy_from_slice(&z[r.clone()]);
        }
    }

    /// Packs multipliers in the convention of [`Solution`] into the stacked `ν` of the NLP.
    pub fn pack_multipliers(&self, lambdas: &[Vec<f64>], nus: &[Vec<f64>], out: &mut [f64]) {
        for (r, l) in self.lambda_rows.iter().zip(lambdas) {
            out[r.clone()].copy_from_slice(l);
        }
        for (r, v) in self.nu_rows.iter().zip(nus) {
            out[r.clone()].copy_from_slice(v);
        }
    }

    /// Unpacks the stacked `ν` of the NLP into the multipliers of [`Solution`].
    pub fn unpack_multipliers(&self, nu: &[f64], lambdas: &mut [Vec<f64>], nus: &mut [Vec<f64>]) {
        for (r, l) in self.lambda_rows.iter().zip(lambdas) {
            l.copy_from_slice(&nu[r.clone()]);
        }
        for (r, v) in self.nu_rows.iter().zip(nus) {
            v.copy_from_slice(&nu[r.clone()]);
        }
    }
}

/// An optimal control problem viewed as an [`Nlp`] through its [`OcpLayout`] (which must
/// have been made for a problem of the same dimensions).
#[derive(Clone, Copy)]
pub struct OcpNlp<'a> {
    /// The problem.
    pub problem: &'a Problem,
    /// Its layout.
    pub layout: &'a OcpLayout,
}

/// Scratch of an [`OcpNlp`] evaluation: the problem's data and the trajectory and
/// multipliers unpacked from `z` and `ν`.
struct OcpWs {
    pd: ProblemData,
    xs: Vec<Vec<f64>>,
    us: Vec<Vec<f64>>,
    lams: Vec<Vec<f64>>,
    nus: Vec<Vec<f64>>,
}

impl OcpNlp<'_> {
    fn ws<'d>(&self, ws: &'d mut crate::functions::Workspace, z: &[f64]) -> &'d mut OcpWs {
        let ws: &mut OcpWs = ws.downcast_mut().expect("data of another NLP");
        self.layout.unpack(z, &mut ws.xs, &mut ws.us);
        ws
    }

    /// The stages' dynamics Jacobians, cost gradients and Hessians, and the terminal
    /// cost's, into the (zeroed) blocks of the data.
    fn stage_blocks(&self, pd: &ProblemData, jac: &mut [Mat<f64>], hess: &mut [Mat<f64>], grad: &mut [f64]) {
        let (l, n) = (self.layout, self.problem.horizon());
        let sp = &l.sparsity;
        for t in 0..n {
            let sd = &pd.stages[t];
            let (xt, ut, yt) = (&l.x_tan[t], &l.u_tan[t], &l.x_tan[t + 1]);
            let (j, cols) = (&mut jac[1 + t], &sp.jacobian[1 + t]);
            put(j, (None, cols), xt, sd.dyn_jx.as_ref());
            put(j, (None, cols), ut, sd.dyn_ju.as_ref());
            put(j, (None, cols), yt, sd.dyn_jy.as_ref());
            grad[xt.clone()].copy_from_slice(sd.cost.lx());
            grad[ut.clone()].copy_from_slice(sd.cost.lu());
            put_symmetric(
                &mut hess[t],
                &sp.hessian[t],
                (xt, ut),
                sd.cost.lxx.as_ref(),
                sd.cost.lxu.as_ref(),
                sd.cost.luu.as_ref(),
            );
        }
        let xn = &l.x_tan[n];
        grad[xn.clone()].copy_from_slice(pd.terminal_cost.lx());
        put(
            &mut hess[n],
            (Some(xn), &sp.hessian[n]),
            xn,
            pd.terminal_cost.lxx.as_ref(),
        );
    }
}

/// `m[rows, cols] += b` for a block `m` on the columns `set` (`rows`: global columns of a
/// Hessian term; `None`: all rows of a Jacobian block), `cols` global.
fn put(m: &mut Mat<f64>, (rows, set): (Option<&Range<usize>>, &Columns), cols: &Range<usize>, b: MatRef<'_, f64>) {
    let local = |r: &Range<usize>| set.local(r.start).expect("columns of the block");
    let (i0, nr) = rows.map_or((0, m.nrows()), |r| (local(r), r.len()));
    let mut dst = m.as_mut().submatrix_mut(i0, local(cols), nr, cols.len());
    dst += b;
}

/// The symmetric block `[[xx, xu], [xuᵀ, uu]]` added at the global rows and columns
/// `(x, u)` of a Hessian term on the columns `set`.
fn put_symmetric(
    m: &mut Mat<f64>,
    set: &Columns,
    (x, u): (&Range<usize>, &Range<usize>),
    xx: MatRef<'_, f64>,
    xu: MatRef<'_, f64>,
    uu: MatRef<'_, f64>,
) {
    put(m, (Some(x), set), x, xx);
    put(m, (Some(x), set), u, xu);
    put(m, (Some(u), set), x, xu.transpose());
    put(m, (Some(u), set), u, uu);
}

impl Nlp for OcpNlp<'_> {
    fn space(&self) -> &dyn Manifold {
        &self.layout.space
    }
    fn num_blocks(&self) -> usize {
        self.layout.blocks.len()
    }
    fn block(&self, k: usize) -> ConstraintBlock<'_> {
        let (kind, rows, scale) = &self.layout.blocks[k];
        let set = match *kind {
            Kind::Init | Kind::Dynamics(_) => &EQUALITY,
            Kind::Path(t, c) => &*self.problem.constraints(t)[c].set,
        };
        ConstraintBlock {
            nr: rows.len(),
            set,
            scale: *scale,
        }
    }
    fn block_name(&self, k: usize) -> String {
        match self.layout.blocks[k].0 {
            Kind::Init => "initial condition".into(),
            Kind::Dynamics(t) => format!("dynamics of stage {t}"),
            Kind::Path(t, c) => format!("constraint `{}` of knot {t}", self.problem.constraints(t)[c].name),
        }
    }
    fn create_data(&self) -> NlpData {
        let p = self.problem;
        let s = Solution::new(p, 0);
        let ws = OcpWs {
            // One thread is always a valid thread count.
            pd: ProblemData::new(p, 1).expect("one thread"),
            xs: s.xs,
            us: s.us,
            lams: s.lambdas,
            nus: s.nus,
        };
        let l = self.layout;
        let rows: Vec<usize> = l.blocks.iter().map(|b| b.1.len()).collect();
        NlpData::new(l.space.ndx(), &rows, l.sparsity.clone(), Box::new(ws))
    }
    fn evaluate(&self, z: &[f64], data: &mut NlpData) {
        let ws = self.ws(&mut data.ws, z);
        let cost = ws.pd.evaluate(self.problem, &ws.xs, &ws.us);
        let pd = &ws.pd;
        let values = &mut data.values;
        for (kind, rows, _) in &self.layout.blocks {
            let v = match *kind {
                Kind::Init => pd.init.value(),
                Kind::Dynamics(t) => pd.stages[t].dyn_value(),
                Kind::Path(t, c) => pd.constraint_data(t)[c].value(),
            };
            values[rows.clone()].copy_from_slice(v);
        }
        data.cost = cost;
    }
    fn derivatives(&self, z: &[f64], data: &mut NlpData) {
        let ws = self.ws(&mut data.ws, z);
        // The problem's models may change between solves: every block is computed.
        ws.pd.invalidate_constant_derivatives();
        ws.pd.compute_derivatives(self.problem, &ws.xs, &ws.us);
        let (l, pd) = (self.layout, &ws.pd);
        data.jac.iter_mut().chain(&mut data.hess).for_each(|m| m.fill(0.0));
        self.stage_blocks(pd, &mut data.jac, &mut data.hess, &mut data.grad);
        let sp = &l.sparsity;
        put(
            &mut data.jac[0],
            (None, &sp.jacobian[0]),
            &l.x_tan[0],
            pd.init.jx.as_ref(),
        );
        let n = self.problem.horizon();
        for (k, (kind, _, _)) in l.blocks.iter().enumerate() {
            if let Kind::Path(t, c) = *kind {
                let (cd, jac, cols) = (&pd.constraint_data(t)[c], &mut data.jac[k], &sp.jacobian[k]);
                put(jac, (None, cols), &l.x_tan[t], cd.jx.as_ref());
                if t < n {
                    put(jac, (None, cols), &l.u_tan[t], cd.ju.as_ref());
                }
            }
        }
    }
    fn second_order(&self, z: &[f64], nu: &[f64], data: &mut NlpData) {
        let ws = self.ws(&mut data.ws, z);
        let l = self.layout;
        l.unpack_multipliers(nu, &mut ws.lams, &mut ws.nus);
        ws.pd
            .compute_second_order(self.problem, &ws.xs, &ws.us, &ws.lams, &ws.nus);
        let (h, sp) = (&mut data.vhp, &l.sparsity);
        h.iter_mut().for_each(|m| m.fill(0.0));
        let n = self.problem.horizon();
        for t in 0..n {
            let sd = &ws.pd.stages[t];
            let (x, u, y) = (&l.x_tan[t], &l.u_tan[t], &l.x_tan[t + 1]);
            let (m, set) = (&mut h[t], &sp.hessian[t]);
            match &sd.dynamics {
                DynamicsData::Explicit(d) => {
                    put_symmetric(m, set, (x, u), d.vhp_xx.as_ref(), d.vhp_xu.as_ref(), d.vhp_uu.as_ref())
                }
                DynamicsData::Implicit(d) => {
                    put_symmetric(m, set, (x, u), d.vhp_xx.as_ref(), d.vhp_xu.as_ref(), d.vhp_uu.as_ref());
                    put(m, (Some(x), set), y, d.vhp_xy.as_ref());
                    put(m, (Some(y), set), x, d.vhp_xy.transpose());
                    put(m, (Some(y), set), y, d.vhp_yy.as_ref());
                    put(m, (Some(u), set), y, d.vhp_uy.as_ref());
                    put(m, (Some(y), set), u, d.vhp_uy.transpose());
                }
            }
            for cd in &sd.constraints {
                put_symmetric(
                    m,
                    set,
                    (x, u),
                    cd.vhp_xx.as_ref(),
                    cd.vhp_xu.as_ref(),
                    cd.vhp_uu.as_ref(),
                );
            }
        }
        let xn = &l.x_tan[n];
        for cd in &ws.pd.terminal_constraints {
            put(&mut h[n], (Some(xn), &sp.hessian[n]), xn, cd.vhp_xx.as_ref());
        }
        if ws.pd.init.vhp_xx.nrows() > 0 {
            let x0 = &l.x_tan[0];
            put(&mut h[0], (Some(x0), &sp.hessian[0]), x0, ws.pd.init.vhp_xx.as_ref());
        }
    }
}

/// ProxNLP as a [`Solver`](crate::solvers::Solver) of optimal control problems (name
/// `proxnlp`): the whole problem as one [`OcpNlp`], whose KKT system is block-banded by
/// stage and solved sparsely above [`AUTO_SPARSE_DIM`](super::AUTO_SPARSE_DIM) rows (by
/// default, [`ProxNlpOptions::kkt`]). For cross-checking the optimum of the structured
/// solvers. The solution's feedback gains stay zero (the whole-problem solve has no
/// Riccati gains); receding horizons are refused.
pub struct ProxNlpOcp {
    /// Options; changes take effect at the next `setup`.
    pub options: ProxNlpOptions,
    inner: ProxNlp,
    layout: Option<OcpLayout>,
    signature: Signature,
    solution: Solution,
    z0: Vec<f64>,
    nu0: Vec<f64>,
}

impl std::fmt::Debug for ProxNlpOcp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProxNlpOcp")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl ProxNlpOcp {
    /// A solver with the given options (nothing allocated until `setup`).
    pub fn new(options: ProxNlpOptions) -> Self {
        Self {
            inner: ProxNlp::new(options.clone()),
            options,
            layout: None,
            signature: Signature::default(),
            solution: Solution::default(),
            z0: Vec::new(),
            nu0: Vec::new(),
        }
    }

    /// How the Newton system is solved (dense or sparse, its size), `None` before `setup`.
    pub fn kkt_stats(&self) -> Option<super::KktStats> {
        self.inner.kkt_stats()
    }

    /// The NLP solution of the last solve (the variable `z` and stacked multipliers).
    pub fn nlp_solution(&self) -> &super::NlpSolution {
        self.inner.solution()
    }

    fn setup_problem(&mut self, problem: &Problem) -> Result<()> {
        self.options.validate()?;
        self.signature = Signature::default();
        let layout = OcpLayout::new(problem, self.options.dyn_al_scale);
        self.inner = ProxNlp::new(self.options.clone());
        let nlp = OcpNlp {
            problem,
            layout: &layout,
        };
        self.inner.setup(&nlp)?;
        self.z0 = vec![0.0; layout.space.nx()];
        self.nu0 = vec![0.0; super::num_rows(&nlp)];
        self.solution = solution_for(problem, self.options.max_iters, None)?;
        self.layout = Some(layout);
        self.signature = Signature::of(problem);
        Ok(())
    }

    fn run(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.signature.check(problem, "proxnlp")?;
        guess.check(problem)?;
        let layout = self.layout.as_ref().expect("checked by the signature");
        if !layout.matches(problem) {
            return Err(Error::InvalidModel(
                "proxnlp::solve: the problem's constraints differ from those given to setup".into(),
            ));
        }
        layout.pack(guess.xs, guess.us, &mut self.z0);
        self.nu0.fill(0.0);
        if let Some(l) = guess.lambdas {
            for (r, v) in layout.lambda_rows.iter().zip(l) {
                self.nu0[r.clone()].copy_from_slice(v);
            }
        }
        if let Some(n) = guess.nus {
            for (r, v) in layout.nu_rows.iter().zip(n) {
                self.nu0[r.clone()].copy_from_slice(v);
            }
        }
        let nlp = OcpNlp { problem, layout };
        let r = self.inner.solve_with(&nlp, &self.z0, Some(&self.nu0), callback)?;
        let sol = &mut self.solution;
        layout.unpack(&r.x, &mut sol.xs, &mut sol.us);
        layout.unpack_multipliers(&r.multipliers, &mut sol.lambdas, &mut sol.nus);
        sol.history.clear();
        let room = sol.history.capacity();
        sol.history.extend(r.history.iter().take(room).copied());
        sol.status = r.status;
        sol.iterations = r.iterations;
        sol.al_iterations = r.al_iterations;
        sol.prim_err = r.prim_err;
        sol.dual_err = r.dual_err;
        sol.cost = r.cost;
        sol.mu = r.mu;
        sol.solve_time = r.solve_time;
        Ok(&self.solution)
    }
}

fn no_receding() -> Error {
    Error::InvalidModel("proxnlp: receding horizons are not supported (use proxddp)".into())
}

impl crate::solvers::Solver for ProxNlpOcp {
    fn name(&self) -> &'static str {
        "proxnlp"
    }
    fn setup(&mut self, problem: &Problem) -> Result<()> {
        self.setup_problem(problem)
    }
    fn solve_with(
        &mut self,
        problem: &Problem,
        guess: InitialGuess<'_>,
        callback: Option<&mut dyn Callback>,
    ) -> Result<&Solution> {
        self.run(problem, guess, callback)
    }
    fn solution(&self) -> &Solution {
        &self.solution
    }
    fn table(&self) -> Table {
        TABLE
    }
    fn set_limits(&mut self, max_iters: usize, max_time: Option<Duration>) {
        self.options.max_iters = max_iters;
        self.options.max_time = max_time;
    }
    fn setup_receding(&mut self, _problem: &Problem, _queue: &[StageModel]) -> Result<()> {
        Err(no_receding())
    }
    fn shift(&mut self, _problem: &Problem, _slot: Option<usize>) -> Result<()> {
        Err(no_receding())
    }
}
