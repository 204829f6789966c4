//! The receding horizon against fresh solves: after any number of shifts through a queue
//! of stages with other constraints, the rotated problem and workspace give the solution
//! a new solver finds on a problem built from scratch with the same stages; the policy
//! of an unconstrained LQ is the exact optimal control of a perturbed state; threads do
//! not change the cycles; bad input is refused.

use std::collections::VecDeque;
use std::sync::Arc;

#[path = "support/pendulum.rs"]
mod pendulum;

use gharial::constraints::{BoxConstraint, NegativeOrthant};
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta, LinearDiscreteDynamics, Ode};
use gharial::functions::{ControlError, StageFunction, StageFunctionData};
use gharial::mpc::{ClosedLoop, DiscretePlant, Mpc, MpcOptions, Push, simulate};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solution, Solver};
use gharial::spaces::{Manifold, VectorSpace};
use pendulum::Pendulum;

/// `h(x) = θ' - 2` (the inequality `θ' ≤ 2`).
struct SpeedBound;

impl StageFunction for SpeedBound {
    fn nx(&self) -> usize {
        2
    }
    fn ndx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        1
    }
    fn nr(&self) -> usize {
        1
    }
    fn evaluate(&self, x: &[f64], _u: &[f64], d: &mut StageFunctionData) {
        d.value[0] = x[1] - 2.0;
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], d: &mut StageFunctionData) {
        d.jx.fill(0.0);
        d.jx[(0, 1)] = 1.0;
        d.ju.fill(0.0);
    }
}

fn space() -> Arc<dyn Manifold> {
    Arc::new(VectorSpace::new(2))
}

/// A pendulum stage (swing-up cost) with `bounds`: 0 none, 1 `|u| ≤ umax`, 2 also
/// `θ' ≤ 2`.
fn stage(bounds: usize, umax: f64) -> StageModel {
    let space = space();
    let ode: Arc<dyn Ode> = Arc::new(Pendulum { space: space.clone() });
    let dynamics = Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk4(ode, 0.05).unwrap()));
    let target = [std::f64::consts::PI, 0.0];
    let cost = CostStack::new(space.as_ref(), 1)
        .with(
            "x",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[1.0, 0.1], 1).unwrap()),
            1.0,
        )
        .unwrap()
        .with(
            "u",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[0.1]).unwrap()),
            1.0,
        )
        .unwrap();
    let mut s = StageModel::new(Arc::new(cost), dynamics).unwrap();
    if bounds >= 1 {
        let f = Arc::new(ControlError::new(space.as_ref(), &[0.0]).unwrap());
        let set = Arc::new(BoxConstraint::new(&[-umax], &[umax]).unwrap());
        s.add_constraint(StageConstraint::new("u", f, set)).unwrap();
    }
    if bounds >= 2 {
        s.add_constraint(StageConstraint::new(
            "speed",
            Arc::new(SpeedBound),
            Arc::new(NegativeOrthant),
        ))
        .unwrap();
    }
    s
}

fn terminal() -> Arc<dyn gharial::costs::Cost> {
    Arc::new(QuadraticStateCost::diagonal(space(), &[std::f64::consts::PI, 0.0], &[10.0, 1.0], 0).unwrap())
}

/// Every stage object by number: the horizon's `0..N`, then the queue's.
struct Schedule {
    horizon: Vec<StageModel>,
    queue: Vec<StageModel>,
}

impl Schedule {
    fn new(horizon_kinds: &[usize], queue_kinds: &[usize], umax: f64) -> Self {
        Self {
            horizon: horizon_kinds.iter().map(|&k| stage(k, umax)).collect(),
            queue: queue_kinds.iter().map(|&k| stage(k, umax)).collect(),
        }
    }

    fn object(&self, id: usize) -> StageModel {
        let n = self.horizon.len();
        if id < n {
            self.horizon[id].clone()
        } else {
            self.queue[id - n].clone()
        }
    }

    /// A problem built from scratch with the stage objects `ids`.
    fn problem(&self, ids: &[usize], x0: &[f64]) -> Problem {
        Problem::new(x0, ids.iter().map(|&i| self.object(i)).collect(), terminal()).unwrap()
    }
}

/// The stage objects of the horizon after each shift, by the rule of the module docs:
/// the first leaves to the back of the queue, the front of the queue enters at the end.
fn expected_ids(n: usize, q: usize, shifts: usize) -> Vec<usize> {
    let mut horizon: VecDeque<usize> = (0..n).collect();
    let mut queue: VecDeque<usize> = (n..n + q).collect();
    for _ in 0..shifts {
        let out = horizon.pop_front().unwrap();
        match queue.pop_front() {
            Some(i) => {
                horizon.push_back(i);
                queue.push_back(out);
            }
            None => horizon.push_back(out),
        }
    }
    horizon.into_iter().collect()
}

fn zero_guess(p: &Problem) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = p.horizon();
    (vec![p.x0().unwrap().to_vec(); n + 1], vec![vec![0.0]; n])
}

fn max_diff(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| {
            assert_eq!(x.len(), y.len());
            x.iter().zip(y).map(|(p, q)| (p - q).abs())
        })
        .fold(0.0, f64::max)
}

fn tight_proxddp() -> ProxDdp {
    ProxDdp::new(ProxDdpOptions::default().with(|o| {
        o.tol = 1e-10;
        o.max_iters = 400;
    }))
}

/// Runs `cycles` cycles of `mpc` (a state that moves along the plan), checking after each
/// solve that the solution equals a fresh solve of the same stages from scratch; returns
/// the largest control of the plans at bounded stages.
fn check_against_fresh<S: Solver>(
    mut mpc: Mpc<S>,
    schedule: &Schedule,
    mut fresh: impl FnMut() -> Box<dyn Solver>,
    cycles: usize,
    tol: f64,
) -> f64 {
    let mut umax: f64 = 0.0;
    let n = schedule.horizon.len();
    let q = schedule.queue.len();
    let mut x = vec![0.3, 0.0];
    for k in 0..cycles {
        assert_eq!(mpc.stage_ids(), &expected_ids(n, q, k)[..], "cycle {k}");
        let sol = mpc.solve(&x).unwrap().clone();
        assert!(sol.status.converged(), "cycle {k}: {}", sol.status);
        let p = schedule.problem(mpc.stage_ids(), &x);
        let mut s = fresh();
        s.setup(&p).unwrap();
        let (xs, us) = zero_guess(&p);
        let reference: Solution = s.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
        assert!(reference.status.converged(), "cycle {k}: fresh {}", reference.status);
        let (dx, du) = (max_diff(&sol.xs, &reference.xs), max_diff(&sol.us, &reference.us));
        assert!(dx < tol && du < tol, "cycle {k}: |Δx| {dx:e}, |Δu| {du:e}");
        assert!(
            (sol.cost - reference.cost).abs() < tol * (1.0 + reference.cost.abs()),
            "cycle {k}"
        );
        let bounded = sol.us.iter().zip(mpc.problem().stages()).filter(|(_, s)| s.nc() > 0);
        umax = bounded.fold(umax, |m, (u, _)| m.max(u[0].abs()));
        x.copy_from_slice(&sol.xs[1]);
        mpc.shift().unwrap();
    }
    umax
}

#[test]
fn proxddp_shifts_through_stages_with_other_constraints_like_fresh_solves() {
    // Constraint rows per stage 0, 1 or 2: every shift changes the rows at most knots.
    let schedule = Schedule::new(&[2, 0, 1, 2, 0, 1, 1, 0], &[0, 2, 2, 1, 0], 1.2);
    let p = Problem::new(&[0.3, 0.0], schedule.horizon.clone(), terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    let opts = MpcOptions::default().with(|o| o.max_iters = 400);
    let mut solver = tight_proxddp();
    solver.set_limits(400, None);
    let mpc = Mpc::new(p, solver, schedule.queue.clone(), InitialGuess::primal(&xs, &us), opts).unwrap();
    let umax = check_against_fresh(mpc, &schedule, || Box::new(tight_proxddp()), 14, 1e-7);
    assert!((umax - 1.2).abs() < 1e-6, "the control bound is active: {umax}");
}

#[test]
fn box_fddp_shifts_through_bounded_and_free_stages_like_fresh_solves() {
    let make = || {
        Ddp::new(DdpOptions::new(DdpVariant::BoxFddp).with(|o| {
            // th_stop = tol² N, above the round-off floor of the cost.
            o.tol = 1e-6;
            o.max_iters = 200;
        }))
    };
    let schedule = Schedule::new(&[1, 0, 0, 1, 1, 0, 1], &[0, 1, 1], 3.0);
    let p = Problem::new(&[0.3, 0.0], schedule.horizon.clone(), terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    let opts = MpcOptions::default().with(|o| o.max_iters = 200);
    let mpc = Mpc::new(p, make(), schedule.queue.clone(), InitialGuess::primal(&xs, &us), opts).unwrap();
    let umax = check_against_fresh(mpc, &schedule, || Box::new(make()), 10, 1e-5);
    assert!((umax - 3.0).abs() < 1e-9, "the control bound is active: {umax}");
}

fn tight_csqp() -> gharial::solvers::csqp::Csqp {
    use gharial::solvers::csqp::{Csqp, CsqpOptions};
    Csqp::new(CsqpOptions::default().with(|o| {
        o.tol = 1e-8;
        o.max_iters = 400;
        o.admm = o.admm.with(|a| {
            a.eps_abs = 1e-10;
            a.eps_rel = 0.0;
            a.max_iters = 20_000;
        });
    }))
}

#[test]
fn csqp_shifts_through_stages_with_other_constraints_like_fresh_solves() {
    let schedule = Schedule::new(&[2, 0, 1, 2, 0, 1, 1, 0], &[0, 2, 2, 1, 0], 1.2);
    let p = Problem::new(&[0.3, 0.0], schedule.horizon.clone(), terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    let opts = MpcOptions::default().with(|o| o.max_iters = 400);
    let mpc = Mpc::new(
        p,
        tight_csqp(),
        schedule.queue.clone(),
        InitialGuess::primal(&xs, &us),
        opts,
    )
    .unwrap();
    let umax = check_against_fresh(mpc, &schedule, || Box::new(tight_csqp()), 12, 1e-6);
    assert!((umax - 1.2).abs() < 1e-6, "the control bound is active: {umax}");
}

#[test]
fn an_empty_queue_rotates_the_horizon() {
    let schedule = Schedule::new(&[1, 0, 2, 0, 1], &[], 1.5);
    let p = Problem::new(&[0.3, 0.0], schedule.horizon.clone(), terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    let opts = MpcOptions::default().with(|o| o.max_iters = 400);
    let mpc = Mpc::new(p, tight_proxddp(), vec![], InitialGuess::primal(&xs, &us), opts).unwrap();
    let umax = check_against_fresh(mpc, &schedule, || Box::new(tight_proxddp()), 7, 1e-7);
    assert!((umax - 1.5).abs() < 1e-6, "the control bound is active: {umax}");
}

/// An unconstrained LQ: `x' = A x + B u` with quadratic costs.
fn lq_problem(x0: &[f64]) -> Problem {
    let space = space();
    let a = faer::mat![[1.0, 0.1], [-0.2, 0.95]];
    let b = faer::mat![[0.0], [0.1]];
    let dynamics = Dynamics::Explicit(Arc::new(
        LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0, 0.01]).unwrap(),
    ));
    let cost = CostStack::new(space.as_ref(), 1)
        .with(
            "x",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), &[1.0, 0.0], &[1.0, 0.5], 1).unwrap()),
            1.0,
        )
        .unwrap()
        .with(
            "u",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[0.3]).unwrap()),
            1.0,
        )
        .unwrap();
    let stage = StageModel::new(Arc::new(cost), dynamics).unwrap();
    let term = Arc::new(QuadraticStateCost::diagonal(space, &[1.0, 0.0], &[5.0, 5.0], 0).unwrap());
    Problem::new(x0, vec![stage; 12], term).unwrap()
}

/// A controller of `p` with the solver named `solver` (ProxDDP and CSQP tight, FDDP at its
/// defaults) from the primal guess.
fn lq_mpc(p: &Problem, solver: &str, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Mpc<Box<dyn Solver>> {
    let boxed: Box<dyn Solver> = match solver {
        "proxddp" => Box::new(tight_proxddp()),
        "fddp" => Box::new(Ddp::new(DdpOptions::new(DdpVariant::Fddp))),
        _ => Box::new(tight_csqp()),
    };
    Mpc::new(
        p.clone(),
        boxed,
        vec![],
        InitialGuess::primal(xs, us),
        MpcOptions::default(),
    )
    .unwrap()
}

#[test]
fn the_policy_of_an_lq_is_the_optimal_control_of_a_perturbed_state() {
    let x = [0.4, -0.3];
    let p = lq_problem(&x);
    let (xs, mut us) = zero_guess(&p);
    us[0][0] = 0.7;
    for solver in ["proxddp", "fddp"] {
        let mut mpc = lq_mpc(&p, solver, &xs, &us);
        // Before the first cycle: the guess's first control, without feedback.
        let mut u0 = [0.0];
        mpc.control(&x, &mut u0).unwrap();
        assert_eq!(u0[0], 0.7, "{solver}");
        assert!(
            mpc.solve(&x).unwrap().status.converged(),
            "{solver}: one iteration solves an LQ"
        );
        let xp = [0.45, -0.2];
        let mut u = [0.0];
        mpc.control(&xp, &mut u).unwrap();
        let mut reference = tight_proxddp();
        let mut q = p.clone();
        q.set_x0(&xp).unwrap();
        reference.setup(&q).unwrap();
        let r = reference.solve(&q, InitialGuess::primal(&xs, &us)).unwrap();
        assert!((u[0] - r.us[0][0]).abs() < 1e-9, "{solver}: {} vs {}", u[0], r.us[0][0]);
        assert!(
            (u[0] - mpc.policy().u0[0]).abs() > 1e-3,
            "{solver}: the perturbation matters"
        );
    }
}

/// A cycle whose time budget is spent before its first iteration keeps the policy's
/// feedback: `K_0` is the last solution's gain of the same knot (`K_1` before the shift;
/// the DDP family returned the last pass's `K_0` unshifted, ProxDDP and CSQP zero).
#[test]
fn a_cycle_without_iterations_keeps_the_shifted_gains() {
    let x = [0.4, -0.3];
    let p = lq_problem(&x);
    let (xs, us) = zero_guess(&p);
    for solver in ["proxddp", "fddp", "csqp"] {
        let mut mpc = lq_mpc(&p, solver, &xs, &us);
        let first = mpc.solve(&x).unwrap().clone();
        assert!(first.status.converged(), "{solver}");
        let (k0, k1) = (&first.feedback[0], &first.feedback[1]);
        assert!(
            (k0 - k1).norm_max() > 1e-6 && k1.norm_max() > 0.1,
            "{solver}: {k0:?} {k1:?}"
        );
        mpc.shift().unwrap();
        mpc.set_budget(1, Some(std::time::Duration::ZERO)).unwrap();
        let second = mpc.solve(&[0.41, -0.29]).unwrap();
        assert_eq!(
            (second.iterations, second.status),
            (0, gharial::solvers::Status::TimeBudget),
            "{solver}"
        );
        assert_eq!(mpc.policy().k0, *k1, "{solver}");
        assert!(mpc.set_budget(0, None).is_err());
    }
}

/// An MPC started at a converged solution with its multipliers converges at its first
/// cycle without an iteration; its policy still has the solution's feedback (a pass at
/// the guess; it had none: `K_0 = 0`), equal to the converged solve's gains (taken one
/// iterate earlier) to 1e-5.
#[test]
fn a_first_cycle_at_a_solution_has_feedback() {
    let x = [0.3, 0.0];
    let p = Problem::new(&x, vec![stage(1, 1.2); 16], terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    for solver in ["proxddp", "csqp"] {
        let make = || -> Box<dyn Solver> {
            match solver {
                "proxddp" => Box::new(tight_proxddp()),
                _ => Box::new(tight_csqp()),
            }
        };
        let mut s = make();
        s.setup(&p).unwrap();
        let sol = s.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
        assert!(sol.status.converged(), "{solver}");
        let guess = InitialGuess {
            xs: &sol.xs,
            us: &sol.us,
            lambdas: Some(&sol.lambdas),
            nus: Some(&sol.nus),
        };
        let mut mpc = Mpc::new(p.clone(), make(), vec![], guess, MpcOptions::default()).unwrap();
        let first = mpc.solve(&x).unwrap();
        assert_eq!((first.iterations, first.status.converged()), (0, true), "{solver}");
        let (k, reference) = (&mpc.policy().k0, &sol.feedback[0]);
        let diff = (k - reference).norm_max() / reference.norm_max();
        // (The first control is at its bound: small gains, CSQP's about 4e-10; the zero
        // gains of no pass fail the relative test.)
        assert!(
            reference.norm_max() > 0.0 && diff < 1e-5,
            "{solver}: {k:?} vs {reference:?}"
        );
    }
}

/// One-iteration cycles along the plan; returns the first controls and states.
/// Per cycle: the first control, the next state, the cost and the first feedback gain.
fn run_cycles(threads: usize, cycles: usize, final_residuals: bool) -> Vec<Vec<f64>> {
    let schedule = Schedule::new(&[2, 0, 1, 2, 0, 1, 1, 0, 2, 1, 0, 1, 2, 2, 0, 1], &[0, 2, 2, 1, 0], 1.2);
    let p = Problem::new(&[0.3, 0.0], schedule.horizon.clone(), terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    let solver = ProxDdp::new(ProxDdpOptions::default().with(|o| o.num_threads = threads));
    let mut mpc = Mpc::new(
        p,
        solver,
        schedule.queue.clone(),
        InitialGuess::primal(&xs, &us),
        MpcOptions::default().with(|o| o.final_residuals = final_residuals),
    )
    .unwrap();
    let mut x = vec![0.3, 0.0];
    let mut out = Vec::new();
    for _ in 0..cycles {
        let sol = mpc.solve(&x).unwrap();
        out.push(sol.us[0].clone());
        out.push(sol.xs[1].clone());
        out.push(vec![sol.cost]);
        let k = &sol.feedback[0];
        out.push(
            (0..k.ncols())
                .flat_map(|j| (0..k.nrows()).map(move |i| k[(i, j)]))
                .collect(),
        );
        x.copy_from_slice(&sol.xs[1]);
        mpc.shift().unwrap();
    }
    out
}

#[test]
fn the_parallel_riccati_gives_the_serial_cycles() {
    let (serial, parallel) = (run_cycles(1, 25, false), run_cycles(2, 25, false));
    let scale = serial.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    let diff = max_diff(&serial, &parallel);
    assert!(diff <= 1e-9 * scale, "{diff:e}");
}

/// Skipping the derivatives at the end of a cycle changes no plan, cost or gain: the
/// next cycle evaluates the shifted problem from scratch.
#[test]
fn cycles_without_final_residuals_give_the_same_plans() {
    let (with, without) = (run_cycles(1, 25, true), run_cycles(1, 25, false));
    assert_eq!(with, without);
}

#[test]
fn bad_input_is_refused_with_an_error() {
    let x = [0.3, 0.0];
    let p = Problem::new(&x, vec![stage(1, 1.0); 4], terminal()).unwrap();
    let (xs, us) = zero_guess(&p);
    // A queued stage of another control size.
    let other = {
        let space = space();
        let a = faer::mat![[1.0, 0.1], [0.0, 1.0]];
        let b = faer::mat![[0.0, 0.0], [0.1, 0.1]];
        let dynamics = Dynamics::Explicit(Arc::new(
            LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0, 0.0]).unwrap(),
        ));
        let cost = QuadraticStateCost::diagonal(space, &[0.0, 0.0], &[1.0, 1.0], 2).unwrap();
        StageModel::new(Arc::new(cost), dynamics).unwrap()
    };
    let g = InitialGuess::primal(&xs, &us);
    let e = Mpc::new(p.clone(), tight_proxddp(), vec![other], g, MpcOptions::default()).unwrap_err();
    assert!(e.to_string().contains("queued stage 0"), "{e}");
    // DDP refuses a queued stage with a constraint it does not handle.
    let fddp = Ddp::new(DdpOptions::new(DdpVariant::Fddp));
    let free = Problem::new(&x, vec![stage(0, 1.0); 4], terminal()).unwrap();
    let e = Mpc::new(free, fddp, vec![stage(1, 1.0)], g, MpcOptions::default()).unwrap_err();
    assert!(e.to_string().contains("queued stage 0"), "{e}");
    let zero = MpcOptions::default().with(|o| o.max_iters = 0);
    assert!(Mpc::new(p.clone(), tight_proxddp(), vec![], g, zero).is_err());
    let mut mpc = Mpc::new(p, tight_proxddp(), vec![], g, MpcOptions::default()).unwrap();
    assert!(mpc.solve(&[0.0]).is_err());
    assert!(mpc.solve(&[f64::NAN, 0.0]).is_err());
    mpc.solve(&x).unwrap();
    let mut u = [0.0; 2];
    assert!(mpc.control(&x, &mut u).is_err());
    assert!(mpc.control(&[f64::INFINITY, 0.0], &mut u[..1]).is_err());
    // A solver without setup_receding cannot shift.
    let mut s = tight_proxddp();
    let q = Problem::new(&x, vec![stage(1, 1.0); 4], terminal()).unwrap();
    s.setup(&q).unwrap();
    assert!(Solver::shift(&mut s, &q, Some(0)).is_err());
}

/// The plant of [`lq_problem`] with `A` scaled by `1 + mismatch` in its coupling terms.
fn lq_plant(mismatch: f64) -> DiscretePlant {
    let a = faer::mat![[1.0, 0.1 * (1.0 + mismatch)], [-0.2 * (1.0 + mismatch), 0.95]];
    let b = faer::mat![[0.0], [0.1]];
    DiscretePlant::new(Arc::new(
        LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0, 0.01]).unwrap(),
    ))
}

#[test]
fn closed_loop_with_the_exact_model_follows_each_plan_and_pushes_kick_the_state() {
    let x = [0.4, -0.3];
    let p = lq_problem(&x);
    let (xs, us) = zero_guess(&p);
    let mpc_of = |p: &Problem| {
        Mpc::new(
            p.clone(),
            tight_proxddp(),
            vec![],
            InitialGuess::primal(&xs, &us),
            MpcOptions::default(),
        )
        .unwrap()
    };
    let mut mpc = mpc_of(&p);
    let mut plant = lq_plant(0.0);
    let mut shifts = Vec::new();
    let rec = simulate(&mut mpc, &mut plant, &x, &ClosedLoop::new(30, 1), |c, id, _| {
        shifts.push((c, id));
        Ok(())
    })
    .unwrap();
    assert_eq!(rec.cycles.len(), 30);
    assert_eq!(shifts.len(), 29);
    assert!(
        shifts.iter().all(|&(c, id)| id == (c - 1) % 12),
        "the stage that left re-enters"
    );
    // Each plan's first transition is the plant's step: replay the cycles one by one.
    let mut replay = mpc_of(&p);
    for k in 0..30 {
        let plan = replay.solve(&rec.xs[k]).unwrap();
        assert!(plan.status.converged());
        assert!(max_diff(&plan.xs[1..2], &rec.xs[k + 1..k + 2]) < 1e-12, "step {k}");
        assert!((plan.us[0][0] - rec.us[k][0]).abs() < 1e-12, "step {k}");
        replay.shift().unwrap();
    }
    // A push moves the state by dx before the step; the policy reacts with K dx.
    let mut pushed = ClosedLoop::new(30, 2);
    pushed.pushes.push(Push {
        step: 5,
        dx: vec![0.0, 0.5],
    });
    let mut mpc = mpc_of(&p);
    let kicked = simulate(&mut mpc, &mut plant, &x, &pushed, |_, _, _| Ok(())).unwrap();
    let mut mpc = mpc_of(&p);
    let calm = simulate(&mut mpc, &mut plant, &x, &ClosedLoop::new(30, 2), |_, _, _| Ok(())).unwrap();
    // The record holds the state after the push, at which the control was computed.
    assert!(max_diff(&kicked.xs[..5], &calm.xs[..5]) < 1e-14);
    assert!((kicked.xs[5][1] - calm.xs[5][1] - 0.5).abs() < 1e-14);
    // Between cycles the policy is linear: the push changes u by K_0 dx exactly (every
    // cycle solves the same rotated stages, so K_0 is the last cycle's).
    let du = kicked.us[5][0] - calm.us[5][0];
    let k0 = mpc.policy().k0[(0, 1)];
    assert!(
        du.abs() > 1e-3 && (du - 0.5 * k0).abs() < 1e-9,
        "{du} vs K dx {}",
        0.5 * k0
    );
    let dv = kicked.xs[6][1] - calm.xs[6][1];
    assert!((dv - 0.5 * 0.95 - 0.1 * du).abs() < 1e-12, "{dv}");
}

#[test]
fn closed_loop_regulates_a_mismatched_plant_and_refuses_bad_input() {
    let x = [0.4, -0.3];
    let p = lq_problem(&x);
    let (xs, us) = zero_guess(&p);
    let mut mpc = Mpc::new(
        p.clone(),
        tight_proxddp(),
        vec![],
        InitialGuess::primal(&xs, &us),
        MpcOptions::default(),
    )
    .unwrap();
    let rec = simulate(&mut mpc, &mut lq_plant(0.2), &x, &ClosedLoop::new(400, 1), |_, _, _| {
        Ok(())
    })
    .unwrap();
    let mut exact = Mpc::new(
        p.clone(),
        tight_proxddp(),
        vec![],
        InitialGuess::primal(&xs, &us),
        MpcOptions::default(),
    )
    .unwrap();
    let nominal = simulate(
        &mut exact,
        &mut lq_plant(0.0),
        &x,
        &ClosedLoop::new(400, 1),
        |_, _, _| Ok(()),
    )
    .unwrap();
    // Both loops settle (the horizon is time invariant), the mismatched one near the
    // nominal steady state, from a start far from it.
    let (last, goal) = (&rec.xs[400], &nominal.xs[400]);
    assert!(max_diff(&rec.xs[399..400], &rec.xs[400..]) < 1e-9, "{last:?}");
    assert!(max_diff(&nominal.xs[399..400], &nominal.xs[400..]) < 1e-9, "{goal:?}");
    assert!(
        (last[0] - goal[0]).abs() < 0.1 && (last[0] - goal[0]).abs() > 1e-6,
        "{last:?} vs {goal:?}"
    );
    assert!((x[0] - goal[0]).abs() > 0.09);
    assert!(
        simulate(
            &mut mpc,
            &mut lq_plant(0.0),
            &[0.0],
            &ClosedLoop::new(4, 1),
            |_, _, _| Ok(())
        )
        .is_err()
    );
    assert!(
        simulate(&mut mpc, &mut lq_plant(0.0), &x, &ClosedLoop::new(4, 0), |_, _, _| Ok(
            ()
        ))
        .is_err()
    );
    let mut bad = ClosedLoop::new(4, 1);
    bad.pushes.push(Push {
        step: 1,
        dx: vec![f64::NAN, 0.0],
    });
    assert!(simulate(&mut mpc, &mut lq_plant(0.0), &x, &bad, |_, _, _| Ok(())).is_err());
    // A failure during the loop stops it with the steps done and the reason.
    let rec = simulate(&mut mpc, &mut lq_plant(0.0), &x, &ClosedLoop::new(4, 1), |_, _, _| {
        Err(gharial::Error::InvalidModel("stop".into()))
    })
    .unwrap();
    let stopped = rec.stopped.as_ref().unwrap();
    assert_eq!(
        (stopped.step, rec.xs.len(), rec.us.len(), rec.cycles.len()),
        (1, 2, 1, 1)
    );
    assert!(stopped.reason.contains("stop"), "{}", stopped.reason);
    // A plant that blows up: its state overflows at the fourth step (1e300 = 1e100³).
    let a = faer::mat![[1e100, 0.0], [0.0, 1e100]];
    let b = faer::mat![[0.0], [0.0]];
    let mut blow_up = DiscretePlant::new(Arc::new(
        LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0, 0.0]).unwrap(),
    ));
    let rec = simulate(&mut mpc, &mut blow_up, &x, &ClosedLoop::new(10, 2), |_, _, _| Ok(())).unwrap();
    let stopped = rec.stopped.as_ref().unwrap();
    assert_eq!((stopped.step, rec.xs.len(), rec.us.len()), (3, 4, 3), "{stopped:?}");
    assert!(
        stopped.reason.contains("non-finite") && stopped.reason.contains("step 3"),
        "{}",
        stopped.reason
    );
    assert!(rec.xs.iter().all(|x| x.iter().all(|v| v.is_finite())));
    assert!(nominal.stopped.is_none());
}
