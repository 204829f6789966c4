//! The peer harness's robot problems: their initial costs equal the harness's reference
//! values (printed identically by aligator and crocoddyl) to 1e-12 relative, the guess
//! is the documented gravity compensation, and ProxDDP reaches the harness's reference
//! optima with KKT residuals recomputed independently.

use gharial::problem::kkt_residuals;
use gharial::solvers::Solver;
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Status};

/// `(problem, initial cost, optimal cost, its precision)` from the harness's README.
const REFERENCES: [(&str, f64, f64, f64); 5] = [
    ("ur5", 119.39574497820068, 0.338866186487, 1e-9),
    ("ur5-box", 119.39574497820068, 0.35494324600, 1e-9),
    ("double-pendulum", 493.52956807647496, 0.0842906371, 1e-8),
    ("double-pendulum-box", 493.52956807647496, 0.0848427549, 1e-8),
    ("double-pendulum-box-term", 493.52956807647496, 0.08484701, 1e-6),
];

#[test]
fn initial_costs_equal_the_harness_reference() {
    for (name, init, _, _) in REFERENCES {
        let ex = gharial_problems::build(name).unwrap();
        let cost = gharial_problems::total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap();
        let rel = (cost - init).abs() / init;
        assert!(
            rel <= 1e-12,
            "{name}: initial cost {cost:.17} vs {init:.17} (relative {rel:e})"
        );
    }
}

#[test]
fn the_guess_is_gravity_compensation_at_x0() {
    // The harness's numbers for g(q0).
    let ur5 = gharial_problems::build("ur5").unwrap();
    let g = [
        9.65e-16,
        -39.263583040101196,
        -15.767473022644886,
        -0.08364453489488113,
        0.0,
        0.0,
    ];
    for (a, b) in ur5.us0[0].iter().zip(g) {
        assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{:?}", ur5.us0[0]);
    }
    let pendulum = gharial_problems::build("double-pendulum").unwrap();
    let g = [-5.692158974787103e-06, -6.316201256208154e-10];
    for (a, b) in pendulum.us0[0].iter().zip(g) {
        assert!((a - b).abs() <= 1e-15, "{:?}", pendulum.us0[0]);
    }
    // The rollout stays at x0 to round-off for the UR5.
    let drift = ur5
        .xs0
        .iter()
        .flat_map(|x| x.iter().zip(&ur5.xs0[0]).map(|(a, b)| (a - b).abs()))
        .fold(0.0, f64::max);
    assert!(drift < 1e-12, "{drift:e}");
}

#[test]
fn proxddp_reaches_the_reference_optima() {
    for (name, _, optimum, precision) in REFERENCES {
        let ex = gharial_problems::build(name).unwrap();
        let mut solver = ProxDdp::new(ex.proxddp.clone());
        solver.setup(&ex.problem).unwrap();
        let sol = solver
            .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
            .unwrap();
        assert_eq!(
            sol.status,
            Status::Converged,
            "{name}: {} after {} iterations",
            sol.status,
            sol.iterations
        );
        let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < ex.proxddp.tol, "{name}: {kkt:?}");
        eprintln!("{name}: {} iterations, cost {:.12}", sol.iterations, sol.cost);
        assert!(
            (sol.cost - optimum).abs() <= precision.max(1e-6 * optimum),
            "{name}: cost {:.12} vs the reference {optimum}",
            sol.cost
        );
    }
}
