//! ProxDDP with two threads (the parallel Riccati solver for linear rollouts, stage-wise
//! evaluation on a pool) against one thread, on long horizons.

use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, Rollout};
use gharial::solvers::{InitialGuess, Solution, Status};
use gharial_problems::peers::{PeersLqrParams, PeersVariant};

fn solve(ex: &gharial_problems::Example, threads: usize, rollout: Rollout) -> Solution {
    let mut o = ex.proxddp.clone();
    o.num_threads = threads;
    o.rollout = rollout;
    let mut s = ProxDdp::new(o);
    s.setup(&ex.problem).unwrap();
    s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

fn max_diff(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The parallel Riccati solver changes only the rounding: the same iterations, the same
/// solution to round-off, and the same feedback gains (computed serially at the end).
#[test]
fn two_threads_take_the_same_iterations_on_a_long_horizon() {
    let params = PeersLqrParams {
        horizon: 300,
        ..Default::default()
    };
    for variant in [PeersVariant::Lqr, PeersVariant::Box, PeersVariant::BoxTerminal] {
        let ex = gharial_problems::peers::build(&params, variant).unwrap();
        let serial = solve(&ex, 1, Rollout::Linear);
        let parallel = solve(&ex, 2, Rollout::Linear);
        assert_eq!(serial.status, Status::Converged, "{variant:?}");
        assert_eq!(parallel.status, Status::Converged, "{variant:?}");
        assert_eq!(serial.iterations, parallel.iterations, "{variant:?}");
        assert_eq!(serial.al_iterations, parallel.al_iterations, "{variant:?}");
        assert!(max_diff(&serial.xs, &parallel.xs) < 1e-9, "{variant:?}");
        assert!(max_diff(&serial.us, &parallel.us) < 1e-9, "{variant:?}");
        assert!(
            (serial.cost - parallel.cost).abs() < 1e-12 * serial.cost.abs(),
            "{variant:?}"
        );
        for (a, b) in serial.feedback.iter().zip(&parallel.feedback) {
            let d = (a - b).norm_max();
            assert!(d < 1e-8 * a.norm_max().max(1.0), "{variant:?}: gains differ by {d:e}");
        }
    }
}

/// With the nonlinear rollout the gains are needed at every step, so the serial Riccati
/// solver runs and only the evaluation is parallel, which is exact: bit for bit the same.
#[test]
fn two_threads_with_the_nonlinear_rollout_are_bit_identical() {
    let ex = gharial_problems::build("double-pendulum-box").unwrap();
    let serial = solve(&ex, 1, Rollout::Nonlinear);
    let parallel = solve(&ex, 2, Rollout::Nonlinear);
    assert_eq!(serial.iterations, parallel.iterations);
    assert_eq!(serial.xs, parallel.xs);
    assert_eq!(serial.us, parallel.us);
    assert_eq!(serial.cost.to_bits(), parallel.cost.to_bits());
}
