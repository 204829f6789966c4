//! Solves on two threads: no thread allocates in `solve` after `setup` (counted over
//! every thread of the process, hence the single test in this binary); the DDP family's
//! iterates are those of the serial solve bit for bit (stage-wise results do not depend on
//! the thread that computes them), ProxDDP's, on the parallel Riccati solver, to rounding.

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
#[path = "support/pendulum.rs"]
mod pendulum;

use gharial::problem::Problem;
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solver};

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// Allocations of every thread in five solves after a warm-up one, and the solution's
/// (iterations, cost bits, last control bits).
fn solve_counting(solver: &mut dyn Solver, p: &Problem) -> (usize, (usize, u64, u64)) {
    let (xs, us) = pendulum::interpolated_guess(p);
    solver.setup(p).unwrap();
    solver.solve(p, InitialGuess::primal(&xs, &us)).unwrap();
    let count = counting_alloc::allocations_during(|| {
        for _ in 0..5 {
            solver.solve(p, InitialGuess::primal(&xs, &us)).unwrap();
        }
    });
    let s = solver.solution();
    let last = s.us[p.horizon() - 1][0];
    (count, (s.iterations, s.cost.to_bits(), last.to_bits()))
}

#[test]
fn two_thread_solves_do_not_allocate_and_match_the_serial_ones() {
    let p = pendulum::euler_swing_up(64, [0.0, 0.0]);
    for variant in [DdpVariant::Ddp, DdpVariant::Fddp, DdpVariant::Sqp] {
        let run = |threads| {
            let mut opts = DdpOptions::new(variant);
            opts.max_iters = 30;
            opts.num_threads = threads;
            solve_counting(&mut Ddp::new(opts), &p)
        };
        let (serial, (parallel_count, parallel)) = (run(1).1, run(2));
        assert!(serial.0 > 3, "{}: the solves must do real work", variant.name());
        assert_eq!(parallel_count, 0, "{}", variant.name());
        assert_eq!(parallel, serial, "{}", variant.name());
    }
    let run = |threads| {
        let opts = ProxDdpOptions::default().with(|o| {
            o.max_iters = 30;
            o.num_threads = threads;
        });
        solve_counting(&mut ProxDdp::new(opts), &p)
    };
    let (serial, (parallel_count, parallel)) = (run(1).1, run(2));
    assert!(serial.0 > 3, "ProxDDP: the solves must do real work");
    assert_eq!(parallel_count, 0, "ProxDDP");
    assert_eq!(parallel.0, serial.0, "ProxDDP iterations");
    let (a, b) = (f64::from_bits(parallel.1), f64::from_bits(serial.1));
    assert!((a - b).abs() <= 1e-12 * b.abs(), "ProxDDP cost {a} against {b}");
}
