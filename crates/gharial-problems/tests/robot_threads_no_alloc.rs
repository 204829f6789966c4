//! Solves of the UR5 on two threads allocate nothing after `setup` on any thread (the
//! count is the process's, hence one test in this binary): FDDP and SQP (stage-wise
//! derivatives on the team), ProxDDP with the linear rollout (the parallel Riccati legs
//! on the same team) and with the nonlinear one, box-FDDP and CSQP on the torque-limited
//! reach; each reaches the serial solve's cost.

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

use gharial::solvers::csqp::{Csqp, CsqpOptions};
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::{ProxDdp, Rollout};
use gharial::solvers::{InitialGuess, Solver};
use gharial_problems::Example;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// Allocations of every thread in three solves after a warm-up one; the final cost.
fn count(solver: &mut dyn Solver, ex: &Example) -> (usize, f64) {
    solver.setup(&ex.problem).unwrap();
    let guess = || InitialGuess::primal(&ex.xs0, &ex.us0);
    solver.solve(&ex.problem, guess()).unwrap();
    let n = counting_alloc::allocations_during(|| {
        for _ in 0..3 {
            solver.solve(&ex.problem, guess()).unwrap();
        }
    });
    let sol = solver.solution();
    assert!(sol.iterations >= 2, "{}: the solves must do real work", solver.name());
    (n, sol.cost)
}

#[test]
fn two_thread_robot_solves_do_not_allocate() {
    let ur5 = gharial_problems::build("ur5").unwrap();
    let ur5_box = gharial_problems::build("ur5-box").unwrap();
    for (ex, variant) in [
        (&ur5, DdpVariant::Fddp),
        (&ur5, DdpVariant::Sqp),
        (&ur5_box, DdpVariant::BoxFddp),
    ] {
        let ddp = |threads| {
            let mut o = DdpOptions::new(variant);
            o.max_iters = 20;
            o.num_threads = threads;
            Ddp::new(o)
        };
        let (n, cost) = count(&mut ddp(2), ex);
        assert_eq!(n, 0, "{}", variant.name());
        assert_eq!(cost.to_bits(), count(&mut ddp(1), ex).1.to_bits(), "{}", variant.name());
    }
    let csqp = |threads| {
        Csqp::new(CsqpOptions::default().with(|o| {
            o.max_iters = 20;
            o.num_threads = threads;
        }))
    };
    let (n, cost) = count(&mut csqp(2), &ur5_box);
    assert_eq!(n, 0, "CSQP");
    assert_eq!(cost.to_bits(), count(&mut csqp(1), &ur5_box).1.to_bits(), "CSQP");
    for rollout in [Rollout::Linear, Rollout::Nonlinear] {
        let proxddp = |threads| {
            let mut o = ur5.proxddp.clone();
            o.rollout = rollout;
            o.max_iters = 20;
            o.num_threads = threads;
            ProxDdp::new(o)
        };
        let (n, cost) = count(&mut proxddp(2), &ur5);
        assert_eq!(n, 0, "ProxDDP {rollout:?}");
        let serial = count(&mut proxddp(1), &ur5).1;
        assert!(
            (cost - serial).abs() <= 1e-10 * serial,
            "ProxDDP {rollout:?}: {cost} against {serial}"
        );
    }
}
