//! `solo_stance`: the Solo-12 shifting its base 2 cm sideways on four feet with friction
//! cones of `μ = 0.1`, which bind. ProxDDP (with the active-set prediction of its step)
//! and CSQP (with tight QP tolerances) reach the same optimum, whose contact forces,
//! recomputed by the contact dynamics, lie in their cones; without the cones the optimum
//! leaves them.

#[path = "support/cones.rs"]
mod cones;

use gharial::solvers::csqp::{Csqp, CsqpOptions};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solution, Solver, Status};
use gharial_problems::solo_stance::{self, HORIZON, StanceSetup};

/// Sideways shift of the base target (m).
const DY: f64 = 0.02;
/// Friction coefficient of the cones.
const MU: f64 = 0.1;

fn guess(s: &StanceSetup) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    (vec![s.x0.clone(); HORIZON + 1], vec![s.u_grav.clone(); HORIZON])
}

fn proxddp(s: &StanceSetup, opts: ProxDdpOptions) -> Solution {
    let (xs, us) = guess(s);
    let mut solver = ProxDdp::new(opts);
    solver.setup(&s.problem).unwrap();
    solver
        .solve(&s.problem, InitialGuess::primal(&xs, &us))
        .unwrap()
        .clone()
}

/// CSQP with QPs solved to 1e-8: with the default ADMM tolerances (1e-4, absolute, on a
/// problem whose optimal cost is 4.4e-4), CSQP stops at a dual residual of 1e-5, 6 %
/// above the optimal cost.
fn csqp_tight(s: &StanceSetup) -> Solution {
    let (xs, us) = guess(s);
    let mut solver = Csqp::new(CsqpOptions::default().with(|o| {
        o.tol = 1e-6;
        o.max_iters = 50;
        o.admm.eps_abs = 1e-8;
        o.admm.eps_rel = 1e-8;
        o.admm.max_iters = 20_000;
    }));
    solver.setup(&s.problem).unwrap();
    solver
        .solve(&s.problem, InitialGuess::primal(&xs, &us))
        .unwrap()
        .clone()
}

/// The cone margins of `sol` on the setup's contact dynamics.
fn cone_margins(s: &StanceSetup, sol: &Solution) -> Vec<[f64; 4]> {
    cones::cone_margins(&s.dynamics, MU, sol)
}

#[test]
fn proxddp_with_prediction_and_csqp_reach_the_same_optimum_on_the_cones() {
    let s = solo_stance::setup(DY, Some(MU)).unwrap();
    let reference = csqp_tight(&s);
    assert_eq!(reference.status, Status::Converged, "CSQP: {:?}", reference.status);
    let sol = proxddp(
        &s,
        ProxDdpOptions::default().with(|o| {
            o.active_set_iters = 1;
            o.max_iters = 200;
        }),
    );
    assert_eq!(sol.status, Status::Converged, "ProxDDP: {:?}", sol.status);
    let rel = (sol.cost - reference.cost).abs() / reference.cost;
    println!(
        "ProxDDP {} iterations, cost {:.10e}; CSQP {} iterations, cost {:.10e}",
        sol.iterations, sol.cost, reference.iterations, reference.cost
    );
    assert!(
        rel < 1e-6,
        "costs {} (ProxDDP) vs {} (CSQP): {rel:e}",
        sol.cost,
        reference.cost
    );
    for (name, margins) in [
        ("ProxDDP", cone_margins(&s, &sol)),
        ("CSQP", cone_margins(&s, &reference)),
    ] {
        let worst = margins.iter().flatten().fold(f64::NEG_INFINITY, |a, &m| a.max(m));
        assert!(worst < 1e-5, "{name}: a force leaves its cone by {worst:e} N");
        // The cones bind: forces on the boundary (to 1e-5 N) at most stages.
        let on = margins.iter().filter(|m| m.iter().any(|&v| v > -1e-5)).count();
        println!("{name}: largest cone margin {worst:.2e} N, cones binding at {on} stages");
        assert!(on >= HORIZON / 2, "{name}: cones bind at {on} stages");
    }
}

#[test]
fn without_the_cones_the_optimum_leaves_them_at_a_lower_cost() {
    let free = solo_stance::setup(DY, None).unwrap();
    let sol = proxddp(&free, ProxDdpOptions::default());
    assert_eq!(sol.status, Status::Converged, "{:?}", sol.status);
    let worst = cone_margins(&free, &sol)
        .iter()
        .flatten()
        .fold(f64::NEG_INFINITY, |a, &m| a.max(m));
    println!(
        "without cones: cost {:.10e}, largest cone margin {worst:.3} N",
        sol.cost
    );
    assert!(
        worst > 0.1,
        "unconstrained forces within 0.1 N of the cones ({worst:e})"
    );
    let coned = solo_stance::setup(DY, Some(MU)).unwrap();
    let reference = csqp_tight(&coned);
    assert!(sol.cost < reference.cost, "{} vs {}", sol.cost, reference.cost);
}
