//! No solver allocates in `solve` after `setup`, counted with a global allocator: ProxDDP
//! for every rollout and step acceptance, with and without the active-set prediction, on a
//! nonlinear problem with path and terminal constraints; the DDP family on the same
//! problem without constraints (box variants: with its control bounds), from a guess that
//! violates the dynamics, with explicit and implicit dynamics; receding-horizon cycles
//! (solve, shift through stages with other constraints, feedback policy) after
//! `Mpc::new`.

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
#[path = "support/pendulum.rs"]
mod pendulum;

use std::sync::Arc;

use gharial::constraints::{BoxConstraint, EqualityConstraintSet, NegativeOrthant};
use gharial::costs::{QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, ExplicitRungeKutta, ImplicitEuler, Ode};
use gharial::functions::{ControlError, StageFunction, StageFunctionData, StateError, Unary};
use gharial::mpc::{Mpc, MpcOptions};
use gharial::nlp::{KktSolver, ProxNlpOcp, ProxNlpOptions};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::InitialGuess;
use gharial::solvers::Solver;
use gharial::solvers::bcl_ddp::{BclDdp, BclDdpOptions, Multipliers, PenaltyUpdate, Schedule};
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::{HessianApprox, ProxDdp, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::spaces::{Manifold, VectorSpace};
use pendulum::Pendulum;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// `h(x) = θ - 4` (an inequality `θ ≤ 4` on the state).
struct AngleBound;

impl StageFunction for AngleBound {
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
        d.value[0] = x[0] - 4.0;
    }
    fn jacobians(&self, _x: &[f64], _u: &[f64], d: &mut StageFunctionData) {
        d.jx.fill(0.0);
        d.jx[(0, 0)] = 1.0;
        d.ju.fill(0.0);
    }
}

/// The pendulum swing-up; `constraints`: 0 none, 1 the control bounds, 2 all.
fn problem(implicit: bool, constraints: usize) -> Problem {
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let ode: Arc<dyn Ode> = Arc::new(Pendulum { space: space.clone() });
    let dynamics = if implicit {
        Dynamics::Implicit(Arc::new(ImplicitEuler::new(ode, 0.05).unwrap()))
    } else {
        Dynamics::Explicit(Arc::new(ExplicitRungeKutta::rk4(ode, 0.05).unwrap()))
    };
    let target = [std::f64::consts::PI, 0.0];
    let cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[0.01, 0.01], 1).unwrap());
    let ucost = Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[0.1]).unwrap());
    let stack = gharial::costs::CostStack::new(space.as_ref(), 1)
        .with("x", cost, 1.0)
        .unwrap()
        .with("u", ucost, 1.0)
        .unwrap();
    let mut stage = StageModel::new(Arc::new(stack), dynamics).unwrap();
    if constraints >= 1 {
        stage
            .add_constraint(StageConstraint::new(
                "u_box",
                Arc::new(ControlError::new(space.as_ref(), &[0.0]).unwrap()),
                Arc::new(BoxConstraint::new(&[-1.5], &[1.5]).unwrap()),
            ))
            .unwrap();
    }
    if constraints >= 2 {
        stage
            .add_constraint(StageConstraint::new(
                "angle",
                Arc::new(AngleBound),
                Arc::new(NegativeOrthant),
            ))
            .unwrap();
    }
    let term = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[1.0, 1.0], 0).unwrap());
    let mut p = Problem::new(&[0.0, 0.0], vec![stage; 30], term).unwrap();
    if constraints >= 2 {
        let f = Arc::new(Unary::new(Arc::new(StateError::new(space, &target).unwrap()), 0));
        p.add_terminal_constraint(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))
            .unwrap();
    }
    p
}

#[test]
fn ddp_family_solve_does_not_allocate_after_setup() {
    for implicit in [false, true] {
        for variant in DdpVariant::ALL {
            let p = problem(implicit, usize::from(variant.control_bounds()));
            let (xs, us) = pendulum::interpolated_guess(&p);
            let mut opts = DdpOptions::new(variant);
            opts.max_iters = 30;
            let mut solver = Ddp::new(opts);
            solver.setup(&p).unwrap();
            let mut iterations = 0;
            let count = counting_alloc::allocations(|| {
                iterations = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().iterations;
            });
            assert!(iterations > 3, "{}: the solves must do real work", variant.name());
            assert_eq!(count, 0, "implicit {implicit} {}", variant.name());
        }
    }
}

#[test]
fn exact_hessian_ddp_solve_does_not_allocate_after_setup() {
    let p = pendulum::euler_swing_up(30, [0.0, 0.0]);
    let (xs, us) = pendulum::interpolated_guess(&p);
    for variant in DdpVariant::ALL.into_iter().filter(|v| *v != DdpVariant::Sqp) {
        let mut opts = DdpOptions::new(variant);
        opts.hessian = HessianApprox::Exact;
        opts.max_iters = 30;
        let mut solver = Ddp::new(opts);
        solver.setup(&p).unwrap();
        let mut iterations = 0;
        let count = counting_alloc::allocations(|| {
            iterations = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().iterations;
        });
        assert!(iterations > 3, "{}: the solves must do real work", variant.name());
        assert_eq!(count, 0, "exact Hessian {}", variant.name());
    }
}

#[test]
fn proxddp_solve_does_not_allocate_after_setup() {
    for implicit in [false, true] {
        let p = problem(implicit, 2);
        let (xs, us) = pendulum::interpolated_guess(&p);
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            for step_acceptance in [
                StepAcceptance::Linesearch,
                StepAcceptance::NonmonotoneLinesearch,
                StepAcceptance::Filter,
            ] {
                for (hessian, active_set_iters) in [
                    (HessianApprox::GaussNewton, 0),
                    (HessianApprox::Exact, 0),
                    (HessianApprox::GaussNewton, 10),
                ] {
                    let opts = ProxDdpOptions::default().with(|o| {
                        o.rollout = rollout;
                        o.step_acceptance = step_acceptance;
                        o.hessian = hessian;
                        o.active_set_iters = active_set_iters;
                        o.max_iters = 20;
                    });
                    let mut solver = ProxDdp::new(opts);
                    solver.setup(&p).unwrap();
                    let mut iterations = 0;
                    let count = counting_alloc::allocations(|| {
                        let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
                        iterations = sol.iterations;
                    });
                    assert!(iterations > 3, "the solves must do real work");
                    assert_eq!(
                        count, 0,
                        "implicit {implicit} {rollout:?} {step_acceptance:?} {hessian:?} K {active_set_iters}"
                    );
                }
            }
        }
    }
}

/// BCL-DDP on the swing-up with its terminal equality and a path equality on the
/// controls of the first stages (`u = 0.1`), for every multiplier, penalty and schedule
/// and both inner solvers.
#[test]
fn bcl_ddp_solve_does_not_allocate_after_setup() {
    for implicit in [false, true] {
        let mut p = problem(implicit, 0);
        let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
        let target = [std::f64::consts::PI, 0.0];
        let f = Arc::new(Unary::new(
            Arc::new(StateError::new(space.clone(), &target).unwrap()),
            0,
        ));
        p.add_terminal_constraint(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))
            .unwrap();
        let u_pin = StageConstraint::new(
            "u_pin",
            Arc::new(ControlError::new(space.as_ref(), &[0.1]).unwrap()),
            Arc::new(EqualityConstraintSet),
        );
        let stages: Vec<StageModel> = p
            .stages()
            .iter()
            .enumerate()
            .map(|(t, s)| {
                if t < 3 {
                    s.clone().with_constraint(u_pin.clone()).unwrap()
                } else {
                    s.clone()
                }
            })
            .collect();
        let mut q = Problem::new(p.x0().unwrap(), stages, p.terminal_cost().clone()).unwrap();
        for c in p.terminal_constraints() {
            q.add_terminal_constraint(c.clone()).unwrap();
        }
        let (xs, us) = pendulum::interpolated_guess(&q);
        for multipliers in [Multipliers::Constant, Multipliers::Affine] {
            for penalty in [PenaltyUpdate::Factor, PenaltyUpdate::Adaptive] {
                for schedule in [Schedule::Bcl, Schedule::EveryIteration] {
                    for variant in [DdpVariant::Ddp, DdpVariant::Fddp] {
                        let opts = BclDdpOptions::default().with(|o| {
                            o.multipliers = multipliers;
                            o.penalty = penalty;
                            o.schedule = schedule;
                            o.ddp = DdpOptions::new(variant);
                            o.max_iters = 30;
                        });
                        let mut solver = BclDdp::new(opts);
                        solver.setup(&q).unwrap();
                        let mut iterations = 0;
                        let count = counting_alloc::allocations(|| {
                            iterations = solver.solve(&q, InitialGuess::primal(&xs, &us)).unwrap().iterations;
                        });
                        let what = format!("implicit {implicit} {multipliers:?} {penalty:?} {schedule:?} {variant:?}");
                        assert!(iterations > 3, "{what}: the solves must do real work");
                        assert_eq!(count, 0, "{what}");
                    }
                }
            }
        }
    }
}

#[test]
fn altro_solve_does_not_allocate_after_setup() {
    use gharial::solvers::altro::{Altro, AltroOptions};
    // Explicit dynamics only with the square-root pass (it needs E = -I).
    // The infeasible start (slack controls) with explicit dynamics only as well.
    for (implicit, square_root, infeasible) in [
        (false, false, false),
        (false, true, false),
        (true, false, false),
        (false, false, true),
    ] {
        let p = problem(implicit, 2);
        let (xs, us) = pendulum::interpolated_guess(&p);
        let mut solver = Altro::new(AltroOptions::default().with(|o| {
            o.infeasible_start = infeasible;
            o.square_root = square_root;
            o.iterations_outer = 6;
            o.iterations_inner = 30;
        }));
        solver.setup(&p).unwrap();
        let mut iterations = 0;
        let count = counting_alloc::allocations(|| {
            iterations = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().iterations;
        });
        assert!(iterations > 3, "the solves must do real work");
        assert_eq!(
            count, 0,
            "altro implicit {implicit} square root {square_root} infeasible {infeasible}"
        );
    }
}

#[test]
fn proxnlp_solve_does_not_allocate_after_setup() {
    for implicit in [false, true] {
        let p = problem(implicit, 2);
        let (xs, us) = pendulum::interpolated_guess(&p);
        for (hessian, kkt) in [HessianApprox::GaussNewton, HessianApprox::Exact]
            .into_iter()
            .flat_map(|h| [KktSolver::Dense, KktSolver::Sparse].map(|k| (h, k)))
        {
            let opts = ProxNlpOptions::default().with(|o| {
                o.hessian = hessian;
                o.max_iters = 20;
                o.kkt = kkt;
            });
            let mut solver = ProxNlpOcp::new(opts);
            solver.setup(&p).unwrap();
            assert_eq!(solver.kkt_stats().unwrap().sparse, kkt == KktSolver::Sparse);
            let mut iterations = 0;
            let mut status = gharial::solvers::Status::NotStarted;
            let count = counting_alloc::allocations(|| {
                let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
                (iterations, status) = (sol.iterations, sol.status);
            });
            assert!(iterations > 3, "the solves must do real work: {iterations} {status:?}");
            assert_eq!(count, 0, "proxnlp implicit {implicit} {hessian:?} {kkt:?}");
        }
    }
}

/// A horizon mixing stages with 0, 1 and 3 constraint rows, and a queue of them.
fn mixed_horizon(implicit: bool, box_only: bool) -> (Problem, Vec<StageModel>) {
    let kinds: Vec<usize> = if box_only { vec![0, 1] } else { vec![0, 1, 2] };
    let models: Vec<StageModel> = kinds
        .iter()
        .map(|&k| problem(implicit, k).stages()[0].clone())
        .collect();
    let pick = |i: usize| models[(i * 7 + i / 3) % models.len()].clone();
    let free = problem(implicit, 0);
    let p = Problem::new(&[0.0, 0.0], (0..30).map(pick).collect(), free.terminal_cost().clone()).unwrap();
    (p, (0..11).map(|i| pick(i + 5)).collect())
}

/// Allocations of `cycles` receding-horizon cycles after `Mpc::new` (and a warm-up
/// cycle).
fn mpc_allocations<S: Solver>(mut mpc: Mpc<S>, cycles: usize) -> usize {
    let mut x = vec![0.0, 0.0];
    let mut u = vec![0.0];
    let mut cycle = |mpc: &mut Mpc<S>, x: &mut Vec<f64>| {
        let sol = mpc.solve(x).unwrap();
        x.copy_from_slice(&sol.xs[1]);
        mpc.shift().unwrap();
        mpc.control(x, &mut u).unwrap();
    };
    cycle(&mut mpc, &mut x);
    counting_alloc::local_allocations_during(|| {
        for _ in 0..cycles {
            cycle(&mut mpc, &mut x);
        }
    })
}

#[test]
fn mpc_cycles_do_not_allocate_after_construction() {
    for implicit in [false, true] {
        let (p, queue) = mixed_horizon(implicit, false);
        let (xs, us) = pendulum::interpolated_guess(&p);
        // Serial: a thread pool's job queue takes a block from the heap every few dozen
        // jobs handed to it (README, "Parallel stages").
        let solver = ProxDdp::new(ProxDdpOptions::default());
        let opts = MpcOptions::default().with(|o| o.max_iters = 3);
        let mpc = Mpc::new(p.clone(), solver, queue.clone(), InitialGuess::primal(&xs, &us), opts).unwrap();
        assert_eq!(mpc_allocations(mpc, 200), 0, "proxddp implicit {implicit}");
        let csqp = gharial::solvers::csqp::Csqp::new(Default::default());
        let opts = MpcOptions::default().with(|o| o.max_iters = 3);
        let mpc = Mpc::new(p.clone(), csqp, queue.clone(), InitialGuess::primal(&xs, &us), opts).unwrap();
        assert_eq!(mpc_allocations(mpc, 200), 0, "csqp implicit {implicit}");
        let (p, queue) = mixed_horizon(implicit, true);
        for variant in [DdpVariant::BoxFddp, DdpVariant::BoxDdp] {
            let solver = Ddp::new(DdpOptions::new(variant));
            let opts = MpcOptions::default().with(|o| o.max_iters = 3);
            let mpc = Mpc::new(p.clone(), solver, queue.clone(), InitialGuess::primal(&xs, &us), opts).unwrap();
            assert_eq!(mpc_allocations(mpc, 200), 0, "{} implicit {implicit}", variant.name());
        }
    }
}

/// A minimum-time problem (`MinimumTime`: the step a control, equal steps, step bounds,
/// time-weighted costs) solved by ProxDDP and ALTRO without allocating after `setup`.
#[test]
fn minimum_time_solves_do_not_allocate_after_setup() {
    use gharial::dynamics::RkMethod;
    use gharial::problem::{ContinuousStage, MinimumTime};
    use gharial::solvers::altro::{Altro, AltroOptions};
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let target = [std::f64::consts::PI, 0.0];
    let stage = ContinuousStage {
        ode: Arc::new(Pendulum { space: space.clone() }),
        cost: Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0], &[0.1]).unwrap()),
        constraints: vec![StageConstraint::new(
            "u_box",
            Arc::new(ControlError::new(space.as_ref(), &[0.0]).unwrap()),
            Arc::new(BoxConstraint::new(&[-1.5], &[1.5]).unwrap()),
        )],
    };
    let goal = StageConstraint::new(
        "x_N",
        Arc::new(Unary::new(
            Arc::new(StateError::new(space.clone(), &target).unwrap()),
            0,
        )),
        Arc::new(EqualityConstraintSet),
    );
    let term = Arc::new(QuadraticStateCost::diagonal(space.clone(), &target, &[1.0, 1.0], 0).unwrap());
    let mt = MinimumTime::new(1e-3, 0.2, 1.0, RkMethod::Rk4).unwrap();
    let p = mt.problem(&[0.0, 0.0], &vec![stage; 30], term, &[goal]).unwrap();
    let us = MinimumTime::controls(&vec![vec![0.0]; 30], 0.05);
    let xs: Vec<Vec<f64>> = (0..=30)
        .map(|t| {
            let delta = if t == 0 { 0.0 } else { 0.05_f64.sqrt() };
            vec![std::f64::consts::PI * t as f64 / 30.0, 0.0, delta]
        })
        .collect();
    let solvers: Vec<Box<dyn Solver>> = vec![
        Box::new(ProxDdp::new(ProxDdpOptions::default().with(|o| o.max_iters = 20))),
        Box::new(Altro::new(AltroOptions::default().with(|o| {
            o.iterations_outer = 4;
            o.iterations_inner = 20;
        }))),
    ];
    for mut solver in solvers {
        solver.setup(&p).unwrap();
        let mut iterations = 0;
        let count = counting_alloc::allocations(|| {
            iterations = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().iterations;
        });
        assert!(iterations > 3, "the solves must do real work");
        assert_eq!(count, 0, "{}", solver.name());
    }
}
