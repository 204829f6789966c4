//! ALTRO's Table I problems (`altro_table`) solved by ProxDDP to the paper's constraint
//! tolerance 1e-8: the goal reached, the bounds and discs respected at every node, the
//! KKT residuals recomputed independently of the solver.

use gharial::problem::kkt_residuals;
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver, Status};

fn solve(name: &str) -> (gharial_problems::Example, Solution) {
    let ex = gharial_problems::build(name).unwrap();
    let mut solver = ProxDdp::new(ex.proxddp.clone());
    solver.setup(&ex.problem).unwrap();
    let sol = solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone();
    assert_eq!(sol.status, Status::Converged, "{name}");
    let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
    assert!(kkt.max() < 1e-7, "{name}: {kkt:?}");
    eprintln!("{name}: {} iterations, cost {}", sol.iterations, sol.cost);
    (ex, sol)
}

/// Largest violation of `goal` by the last state.
fn goal_error(sol: &Solution, goal: &[f64]) -> f64 {
    sol.xs
        .last()
        .unwrap()
        .iter()
        .zip(goal)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

#[test]
fn block_move_reaches_its_goal_within_the_control_limits() {
    let (_, sol) = solve("block-move");
    assert!(goal_error(&sol, &[1.0, 0.0]) < 1e-8);
    let umax = sol.us.iter().map(|u| u[0].abs()).fold(0.0, f64::max);
    assert!(umax <= 1.5 + 1e-8, "{umax}");
    // The bound is active: the unconstrained move would push harder.
    assert!(umax > 1.5 - 1e-6, "{umax}");
}

#[test]
fn parallel_park_stays_in_its_box() {
    let (_, sol) = solve("car-parallel-park");
    assert!(goal_error(&sol, &[0.0, 1.0, 0.0]) < 1e-8);
    for x in &sol.xs {
        assert!(
            x[0].abs() <= 0.25 + 1e-8 && (-0.001 - 1e-8..=1.001 + 1e-8).contains(&x[1]),
            "{x:?}"
        );
    }
    for u in &sol.us {
        assert!(u.iter().all(|v| v.abs() <= 2.0 + 1e-8), "{u:?}");
    }
}

#[test]
fn car_avoids_the_three_discs() {
    let (_, sol) = solve("car-3-obstacles");
    assert!(goal_error(&sol, &[1.0, 1.0, 0.0]) < 1e-8);
    let mut closest = f64::INFINITY;
    for x in &sol.xs {
        for c in [0.25, 0.5, 0.75] {
            closest = closest.min(((x[0] - c).powi(2) + (x[1] - c).powi(2)).sqrt() - 0.1);
        }
    }
    // Outside every disc (the optimal S-curve, which starts and ends heading along x,
    // passes them at a distance).
    assert!(closest > -1e-8, "{closest:e}");
    eprintln!("car-3-obstacles: closest approach {closest:.4} outside a disc");
}
