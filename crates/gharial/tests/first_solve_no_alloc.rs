//! The first solve after `setup` allocates nothing, on one thread and on two, where the
//! products are large enough for faer's packed kernels (whose per-thread packing buffer
//! the workspace and the team's threads make when they are built): a random LQ with
//! nx = 36, nu = 12, from a fresh process (allocations of every thread counted, hence the
//! single test in this binary).

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
#[path = "support/lq_ocp.rs"]
mod lq_ocp;

use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solver};

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

#[test]
fn the_first_solve_after_setup_allocates_nothing() {
    let lq = lq_ocp::random_lq(36, 12, 32, 7);
    let p = lq_ocp::ocp(&lq, None, None);
    let (xs, us) = lq_ocp::zero_guess(&p);
    for threads in [1, 2] {
        let mut solver = ProxDdp::new(ProxDdpOptions::default().with(|o| o.num_threads = threads));
        solver.setup(&p).unwrap();
        let n = counting_alloc::allocations_during(|| {
            solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        });
        assert!(
            solver.solution().iterations > 0,
            "{threads} threads: the solve must do real work"
        );
        assert_eq!(n, 0, "{threads} threads: allocations in the first solve");
    }
}
