//! Every catalogue example converges with ProxDDP at its recommended settings (the
//! paper's `mu_init`, rollout and AL scales where the paper gives them), with every
//! rollout that applies, and the KKT residuals of the returned primal-dual point,
//! recomputed by `gharial::problem::kkt_residuals` independently of the solver, are
//! below the tolerance.

use gharial::problem::kkt_residuals;
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, Rollout};
use gharial::solvers::{InitialGuess, Solution, Status};
use gharial_problems::Example;

fn solve(ex: &Example, rollout: Rollout) -> Solution {
    let mut opts = ex.proxddp.clone();
    opts.rollout = rollout;
    let mut solver = ProxDdp::new(opts);
    solver.setup(&ex.problem).unwrap();
    solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

/// Solves `name` with each of `rollouts`; checks convergence and the independent KKT
/// residuals; returns the solutions.
fn converges(name: &str, rollouts: &[Rollout]) -> Vec<Solution> {
    let ex = gharial_problems::build(name).unwrap();
    let tol = ex.proxddp.tol;
    rollouts
        .iter()
        .map(|&rollout| {
            let sol = solve(&ex, rollout);
            assert_eq!(
                sol.status,
                Status::Converged,
                "{name} {rollout:?}: {} after {} iterations (prim {:e}, dual {:e})",
                sol.status,
                sol.iterations,
                sol.prim_err,
                sol.dual_err
            );
            let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            eprintln!(
                "{name} {rollout:?}: {} iterations, {} AL iterations, cost {:.10}, KKT {:.1e}",
                sol.iterations,
                sol.al_iterations,
                sol.cost,
                kkt.max()
            );
            assert!(kkt.max() < tol, "{name} {rollout:?}: {kkt:?}");
            sol
        })
        .collect()
}

const BOTH: &[Rollout] = &[Rollout::Linear, Rollout::Nonlinear];

#[test]
fn lqr_family_converges() {
    for name in ["lqr", "lqr-bounds", "lqr-term", "lqr-bounds-term", "clqr"] {
        let sols = converges(name, BOTH);
        // On linear dynamics both rollouts reach the same point.
        assert!((sols[0].cost - sols[1].cost).abs() < 1e-9, "{name}");
    }
}

#[test]
fn lqr_bounds_are_active_at_the_solution() {
    for (name, umax) in [("lqr-bounds", 0.15), ("lqr-bounds-term", 0.15), ("clqr", 0.3)] {
        let sol = &converges(name, &[Rollout::Nonlinear])[0];
        let active = sol
            .us
            .iter()
            .flatten()
            .filter(|u| (u.abs() - umax).abs() < 1e-6)
            .count();
        assert!(active > 0, "{name}: no control at its bound");
        assert!(sol.us.iter().flatten().all(|u| u.abs() <= umax + 1e-6), "{name}");
    }
}

#[test]
fn pendulum_swings_up() {
    let sols = converges("pendulum", BOTH);
    for sol in &sols {
        let x = sol.xs.last().unwrap();
        // Upright: cos θ = 1 at the end (the terminal constraint on the tip).
        assert!((x[0] - 1.0).abs() < 1e-5 && x[1].abs() < 1e-5, "{x:?}");
        assert!(sol.us.iter().all(|u| u[0].abs() <= 20.0 + 1e-6));
    }
}

#[test]
fn cartpole_swings_up() {
    let sols = converges("cartpole", &[Rollout::Nonlinear]);
    let x = sols[0].xs.last().unwrap();
    // Tip at (0, 1): y - sin θ = 0 and cos θ = 1.
    assert!(
        (x[0] - x[1].sin()).abs() < 1e-5 && (x[1].cos() - 1.0).abs() < 1e-5,
        "{x:?}"
    );
}

#[test]
fn acrobot_swings_up() {
    let sols = converges("acrobot", &[Rollout::Nonlinear]);
    let x = sols[0].xs.last().unwrap();
    let target = [1.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    assert!(x.iter().zip(target).all(|(a, b)| (a - b).abs() < 1e-5), "{x:?}");
}

#[test]
fn acrobot_with_torque_limits_converges_with_active_limits() {
    let sols = converges("acrobot-bounds", &[Rollout::Nonlinear]);
    let tau = gharial_problems::acrobot::TAU_MAX;
    let us = &sols[0].us;
    assert!(
        us.iter().any(|u| (u[0].abs() - tau).abs() < 1e-6),
        "the limits are active"
    );
    assert!(us.iter().all(|u| u[0].abs() <= tau + 1e-6));
}

#[test]
fn se2_car_parks() {
    let sols = converges("se2-car", BOTH);
    assert!((sols[0].cost - sols[1].cost).abs() < 1e-6 * sols[0].cost.abs().max(1.0));
}

#[test]
fn quadrotor_reaches_its_targets_within_thrust_limits() {
    let max = gharial_problems::quadrotor::THRUST_MAX;
    for sol in converges("quadrotor", BOTH) {
        assert!(sol.us.iter().flatten().all(|u| u.abs() <= max + 1e-6));
        assert!(
            sol.us.iter().flatten().any(|u| (u.abs() - max).abs() < 1e-6),
            "the thrust limits are active"
        );
    }
}

#[test]
fn quadrotor_slalom_clears_the_cylinders() {
    let sols = converges("quadrotor-slalom", BOTH);
    let clearance = gharial_problems::quadrotor::CYLINDER_RADIUS + gharial_problems::quadrotor::QUAD_RADIUS;
    let mut closest = f64::INFINITY;
    for x in &sols[0].xs[1..] {
        for c in gharial_problems::quadrotor::CYLINDERS {
            let d = ((x[0] - c[0]).powi(2) + (x[1] - c[1]).powi(2)).sqrt();
            closest = closest.min(d - clearance);
        }
    }
    assert!(closest > -1e-6, "penetration {closest:e}");
    assert!(closest < 1e-4, "an obstacle constraint is active");
}

/// The pendulum's Newton steps are cut short by the curvature of the merit function (the
/// Maratos effect: step lengths near 0.03 for 30 iterations when the dynamics carry the
/// full penalty); the watchdog takes full steps tentatively and keeps them once the merit
/// has decreased enough.
#[test]
fn the_watchdog_takes_the_pendulums_full_newton_steps() {
    // From mu_init = 1e-2 with the linear rollout, dynamics AL scale 1 and no active-set
    // prediction.
    let mut ex = gharial_problems::build("pendulum").unwrap();
    ex.proxddp.mu_init = 1e-2;
    ex.proxddp.dyn_al_scale = 1.0;
    ex.proxddp.active_set_iters = 0;
    let with = solve(&ex, Rollout::Linear);
    assert_eq!(with.status, Status::Converged);
    ex.proxddp.watchdog_trigger = 0;
    let without = solve(&ex, Rollout::Linear);
    assert_eq!(without.status, Status::Converged);
    // Measured: 22 iterations with the watchdog, 44 without.
    assert!(
        2 * with.iterations <= without.iterations + 2,
        "{} iterations with the watchdog, {} without",
        with.iterations,
        without.iterations
    );
}

/// Solves `name` with its recommended settings but `mu_init` and `rollout` replaced.
fn solve_with(name: &str, mu_init: f64, rollout: Rollout) -> Solution {
    let mut ex = gharial_problems::build(name).unwrap();
    ex.proxddp.mu_init = mu_init;
    solve(&ex, rollout)
}

/// Solves `name` with `mu_init` and `rollout` and checks convergence and the independent
/// KKT residuals.
fn converges_with(name: &str, mu_init: f64, rollout: Rollout) {
    let ex = gharial_problems::build(name).unwrap();
    let sol = solve_with(name, mu_init, rollout);
    assert_eq!(sol.status, Status::Converged, "{name} from mu_init = {mu_init:e}");
    let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
    assert!(kkt.max() < ex.proxddp.tol, "{name}: {kkt:?}");
}

/// The quadrotor's recommended `mu_init` is the paper's 0.1 (Fig. 10); a ten times
/// smaller penalty converges with the other rollout too.
#[test]
fn quadrotor_from_a_smaller_mu_init() {
    converges_with("quadrotor", 1e-2, Rollout::Linear);
}

/// The paper's `mu_init = 1e-3` with the torque limits: the nonmonotone line search on
/// the primal merit (the problem's recommended acceptance) crosses the limits' kinks.
#[test]
fn acrobot_bounds_from_the_papers_mu_init() {
    converges_with("acrobot-bounds", 1e-3, Rollout::Nonlinear);
}
