//! Control bounds of the box variants, recognised among a problem's path constraints.
//!
//! A path constraint bounds the controls when its Jacobians are constant, its state
//! Jacobian is zero, each of its rows involves one control (`h_i = s_i u_j + c_i`) and its
//! set is a box ([`crate::constraints::ConstraintSet::box_bounds`]): then
//! `lo_i ≤ s_i u_j + c_i ≤ hi_i` is an interval of `u_j`, and the intervals of all rows
//! on `u_j` intersect into `lb_j ≤ u_j ≤ ub_j`. Bounds and offsets are read again at every
//! solve, so that sets and references moved between solves (MPC) are followed.

use crate::error::{Error, Result};
use crate::problem::{Problem, ProblemData, StageModel};

/// A constraint row that bounds one control: `lo ≤ s u_j + c ≤ hi`.
#[derive(Debug, Clone, Copy)]
struct BoundRow {
    /// Index of the constraint in its stage.
    constraint: usize,
    /// Row within the constraint.
    row: usize,
    /// Row within the stage's stacked constraint rows.
    stacked: usize,
    /// The control it bounds.
    control: usize,
    /// Its coefficient `s` (nonzero).
    scale: f64,
    /// Implied bounds on the control, from the last [`ControlBounds::refresh`].
    lo: f64,
    hi: f64,
}

/// The control bounds `lb_t ≤ u_t ≤ ub_t` of every stage.
#[derive(Debug)]
pub(super) struct ControlBounds {
    rows: Vec<Vec<BoundRow>>,
    /// The bound rows of the stages queued to enter a receding horizon.
    spare: Vec<Vec<BoundRow>>,
    /// Lower bounds per stage (`-∞` where none).
    pub lb: Vec<Vec<f64>>,
    /// Upper bounds per stage (`+∞` where none).
    pub ub: Vec<Vec<f64>>,
    set_lo: Vec<f64>,
    set_hi: Vec<f64>,
    assigned: Vec<bool>,
}

/// The bound rows of `stage` (`what` names it in errors), or the first constraint that
/// is not a control bound; raises `max_nr` to the largest constraint's rows.
fn stage_rows(stage: &StageModel, what: &str, solver: &str, max_nr: &mut usize) -> Result<Vec<BoundRow>> {
    let mut stage_rows = Vec::new();
    let mut stacked = 0;
    let mut x = vec![0.0; stage.space().nx()];
    stage.space().neutral(&mut x);
    let u = vec![0.0; stage.nu()];
    for (k, c) in stage.constraints().iter().enumerate() {
        let nr = c.nr();
        *max_nr = (*max_nr).max(nr);
        let not_a_bound = |why: &str| {
            Error::InvalidModel(format!(
                "{solver} handles bounds on the controls only: constraint `{}` of {what} {why} \
                 (use proxddp for general constraints)",
                c.name
            ))
        };
        if !c.func.jacobians_are_constant() {
            return Err(not_a_bound("does not declare constant Jacobians"));
        }
        let mut lo = vec![0.0; nr];
        let mut hi = vec![0.0; nr];
        if !c.set.box_bounds(&mut lo, &mut hi) {
            return Err(not_a_bound("has a set that is not a box"));
        }
        let mut d = c.func.create_data();
        c.func.jacobians(&x, &u, &mut d);
        if crate::linalg::norm_max(d.jx.as_ref()) != 0.0 {
            return Err(not_a_bound("depends on the state"));
        }
        for i in 0..nr {
            let nonzero: Vec<usize> = (0..stage.nu()).filter(|&j| d.ju[(i, j)] != 0.0).collect();
            let [j] = nonzero[..] else {
                return Err(not_a_bound(&format!(
                    "has row {i} on {} controls, not one",
                    nonzero.len()
                )));
            };
            stage_rows.push(BoundRow {
                constraint: k,
                row: i,
                stacked: stacked + i,
                control: j,
                scale: d.ju[(i, j)],
                lo: f64::NEG_INFINITY,
                hi: f64::INFINITY,
            });
        }
        stacked += nr;
    }
    Ok(stage_rows)
}

/// Lower and upper bounds per stage.
pub type StageBounds = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// The bounds `lb_t ≤ u_t ≤ ub_t` (`∓∞` where none) that the path constraints of
/// `problem` put on the controls at the trajectory `(xs, us)`, as the box solvers read
/// them (for plots and reports).
///
/// # Errors
/// If the trajectory does not fit the problem, a constraint is not a bound on the
/// controls (see the module documentation), or the bounds of a control are empty.
pub fn control_bounds(problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Result<StageBounds> {
    problem.check_trajectory(xs, us)?;
    let mut bounds = ControlBounds::new(problem, &[], "control_bounds")?;
    let mut data = ProblemData::new(problem, 1)?;
    data.evaluate(problem, xs, us);
    bounds.refresh(problem, &data, us)?;
    Ok((bounds.lb, bounds.ub))
}

impl ControlBounds {
    /// Recognises every path constraint of `problem` and of the stages `queue`d to enter
    /// its horizon as a control bound, or names the first that is not one. `solver` names
    /// the caller in the error.
    pub fn new(problem: &Problem, queue: &[StageModel], solver: &str) -> Result<Self> {
        let mut max_nr = 0;
        let mut rows = Vec::with_capacity(problem.horizon());
        for (t, stage) in problem.stages().iter().enumerate() {
            rows.push(stage_rows(stage, &format!("stage {t}"), solver, &mut max_nr)?);
        }
        let mut spare = Vec::with_capacity(queue.len());
        for (i, stage) in queue.iter().enumerate() {
            spare.push(stage_rows(stage, &format!("queued stage {i}"), solver, &mut max_nr)?);
        }
        if !problem.terminal_constraints().is_empty() {
            return Err(Error::InvalidModel(format!(
                "{solver} handles bounds on the controls only: the problem has terminal constraints \
                 (use proxddp)"
            )));
        }
        let n = problem.horizon();
        Ok(Self {
            rows,
            spare,
            lb: (0..n).map(|t| vec![f64::NEG_INFINITY; problem.nu(t)]).collect(),
            ub: (0..n).map(|t| vec![f64::INFINITY; problem.nu(t)]).collect(),
            set_lo: vec![0.0; max_nr],
            set_hi: vec![0.0; max_nr],
            assigned: vec![false; (0..n).map(|t| problem.nu(t)).max().unwrap_or(0)],
        })
    }

    /// Receding horizon, after [`Problem::shift`] took the queued stage `slot` (`slot`
    /// checked by the caller; `None`: after [`Problem::rotate`]): the bound rows follow
    /// their stages.
    pub fn shift(&mut self, slot: Option<usize>) {
        match slot {
            Some(s) => crate::problem::shift_in(&mut self.rows, &mut self.spare[s]),
            None => self.rows.rotate_left(1),
        }
    }

    /// Whether stage `t` has a bound.
    pub fn bounded(&self, t: usize) -> bool {
        !self.rows[t].is_empty()
    }

    /// Reads the bounds of the sets and the offsets `c = h - s u` from `data`, which holds
    /// the constraint values at the controls `us` (after an evaluation).
    ///
    /// # Errors
    /// If the bounds of a control are empty (`lb > ub`).
    pub fn refresh(&mut self, problem: &Problem, data: &ProblemData, us: &[Vec<f64>]) -> Result<()> {
        for (t, stage) in problem.stages().iter().enumerate() {
            let (lb, ub) = (&mut self.lb[t], &mut self.ub[t]);
            lb.fill(f64::NEG_INFINITY);
            ub.fill(f64::INFINITY);
            let mut current = usize::MAX;
            for r in self.rows[t].iter_mut() {
                let c = &stage.constraints()[r.constraint];
                if r.constraint != current {
                    current = r.constraint;
                    let nr = c.nr();
                    c.set.box_bounds(&mut self.set_lo[..nr], &mut self.set_hi[..nr]);
                }
                let h = data.stages[t].constraints[r.constraint].value[r.row];
                let offset = h - r.scale * us[t][r.control];
                let (a, b) = (
                    (self.set_lo[r.row] - offset) / r.scale,
                    (self.set_hi[r.row] - offset) / r.scale,
                );
                (r.lo, r.hi) = if r.scale > 0.0 { (a, b) } else { (b, a) };
                lb[r.control] = lb[r.control].max(r.lo);
                ub[r.control] = ub[r.control].min(r.hi);
            }
            for j in 0..lb.len() {
                if lb[j] > ub[j] || lb[j].is_nan() || ub[j].is_nan() {
                    return Err(Error::InvalidModel(format!(
                        "stage {t}: the bounds of control {j} are empty ([{}, {}])",
                        crate::error::Num(lb[j]),
                        crate::error::Num(ub[j])
                    )));
                }
            }
        }
        Ok(())
    }

    /// The multipliers `ν_t` of the bound rows from the box-QP gradient at the clamped
    /// controls (`clamped_gradient(j)`, `None` for a free control): `ν = -g_j / s` on the
    /// first row whose bound is the active one, 0 elsewhere (the convention of
    /// [`crate::solvers::Solution`]: `∇_u L = g + sν = 0`).
    pub fn multipliers(
        &mut self,
        t: usize,
        u: &[f64],
        clamped_gradient: impl Fn(usize) -> Option<f64>,
        nu: &mut [f64],
    ) {
        nu.fill(0.0);
        let assigned = &mut self.assigned[..u.len()];
        assigned.fill(false);
        for r in &self.rows[t] {
            let Some(g) = clamped_gradient(r.control) else {
                continue;
            };
            let at_bound = (g > 0.0 && u[r.control] == r.lo) || (g < 0.0 && u[r.control] == r.hi);
            if at_bound && !assigned[r.control] {
                nu[r.stacked] = -g / r.scale;
                assigned[r.control] = true;
            }
        }
    }
}
