//! The peer-harness LQR family is the harness's problem, bit for bit, and ProxDDP
//! reaches the harness's reference optimal costs.

use gharial::problem::kkt_residuals;
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, Rollout};
use gharial::solvers::{InitialGuess, Status};
use gharial_problems::peers::{self, PeersLqrParams, PeersVariant};

#[test]
fn the_random_numbers_are_those_of_the_harness() {
    // First values listed in the harness README.
    let d = peers::data(&PeersLqrParams::default());
    assert_eq!(d.a[(0, 0)], 0.9741564878771822);
    assert_eq!(d.a[(0, 1)], -0.03400896071230799);
    assert_eq!(d.b[(0, 0)], -0.3500875330821578);
    assert_eq!(d.q[0], 1.1720722812694782);
    assert_eq!(d.r[0], 0.12225058085207914);
    assert_eq!(d.x0[0], -0.4872384414141766);
    assert_eq!(d.x0[7], -0.2321861835161636);
}

#[test]
fn the_initial_cost_is_bit_identical() {
    for name in ["peers-lqr", "peers-lqr-box", "peers-lqr-box-term"] {
        let ex = gharial_problems::build(name).unwrap();
        let cost = gharial_problems::total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap();
        assert_eq!(format!("{cost:?}"), "130.19638139597174", "{name}");
    }
}

#[test]
fn optimal_costs_match_the_reference_values() {
    // Reference values of the harness README (aligator, crocoddyl, mim_solvers agree).
    // Solved to tol 1e-10 the cost is accurate to ~1e-9; the box references are given
    // to 11 significant digits.
    for (name, reference, rel) in [
        ("peers-lqr", 6.24858177722514, 1e-9),
        ("peers-lqr-box", 6.9221159366, 1e-9),
        ("peers-lqr-box-term", 6.9224174917, 1e-9),
    ] {
        let ex = gharial_problems::build(name).unwrap();
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            let mut opts = ex.proxddp.clone();
            opts.rollout = rollout;
            opts.tol = 1e-10;
            let mut solver = ProxDdp::new(opts);
            solver.setup(&ex.problem).unwrap();
            let sol = solver
                .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
                .unwrap();
            assert_eq!(sol.status, Status::Converged, "{name} {rollout:?}");
            let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            assert!(kkt.max() < 1e-9, "{name} {rollout:?}: {kkt:?}");
            let err = (sol.cost - reference).abs() / reference;
            eprintln!(
                "{name} {rollout:?}: cost {:.12} vs {reference} (rel {err:.1e}), {} iterations",
                sol.cost, sol.iterations
            );
            assert!(err < rel, "{name} {rollout:?}: {} vs {reference}", sol.cost);
        }
    }
}

#[test]
fn other_instances_of_the_family_build_and_bad_knobs_are_errors() {
    let params = PeersLqrParams {
        nx: 3,
        nu: 2,
        horizon: 15,
        seed: 7,
        umax: 0.1,
    };
    let ex = peers::build(&params, PeersVariant::BoxTerminal).unwrap();
    assert_eq!(ex.problem.horizon(), 15);
    assert_eq!(ex.xs0[0].len(), 3);
    assert_eq!(ex.us0[0].len(), 2);
    assert_eq!(ex.problem.terminal_constraints().len(), 1);
    for bad in [
        PeersLqrParams { nx: 0, ..params },
        PeersLqrParams { horizon: 0, ..params },
        PeersLqrParams { umax: -1.0, ..params },
        PeersLqrParams {
            umax: f64::NAN,
            ..params
        },
    ] {
        let err = peers::build(&bad, PeersVariant::Box).unwrap_err().to_string();
        assert!(err.contains("peers LQR"), "{err}");
    }
}
