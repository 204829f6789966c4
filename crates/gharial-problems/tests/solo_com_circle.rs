//! `solo-com-circle` on its first 80 nodes (1.6 s, a third of the turn): CSQP and
//! ProxDDP converge to the same optimum, whose contact forces (recomputed by the
//! contact dynamics) lie in their friction cones, on the boundary over the last 27
//! stages, and whose CoM follows the circle.

#[path = "support/cones.rs"]
mod cones;

use gharial::solvers::csqp::{Csqp, CsqpOptions};
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver};
use gharial_multibody::center_of_mass;
use gharial_problems::solo_com_circle::{self, CircleParams, CircleSetup, DT, MU, OMEGA, RADIUS};

/// Nodes of the tests: the cones of the 80-node problem bind from stage 53 on.
const N: usize = 80;
/// Tolerance of both solvers.
const TOL: f64 = 1e-8;

fn setup() -> CircleSetup {
    solo_com_circle::setup(&CircleParams {
        horizon: N,
        ..CircleParams::default()
    })
    .unwrap()
}

/// The catalogue's guess: `x0` at every node, `u_qs` at every stage.
fn guess(s: &CircleSetup) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    (vec![s.x0.clone(); N + 1], vec![s.u_stand.clone(); N])
}

fn solve_csqp(s: &CircleSetup) -> Solution {
    let (xs, us) = guess(s);
    let mut solver = Csqp::new(CsqpOptions::default().with(|o| {
        o.tol = TOL;
        o.admm.eps_abs = 1e-10;
        o.admm.eps_rel = 1e-10;
        o.admm.max_iters = 5000;
    }));
    solver.setup(&s.problem).unwrap();
    solver
        .solve(&s.problem, InitialGuess::primal(&xs, &us))
        .unwrap()
        .clone()
}

fn solve_proxddp(s: &CircleSetup) -> Solution {
    let (xs, us) = guess(s);
    let mut solver = ProxDdp::new(solo_com_circle::proxddp_options().with(|o| o.tol = TOL));
    solver.setup(&s.problem).unwrap();
    solver
        .solve(&s.problem, InitialGuess::primal(&xs, &us))
        .unwrap()
        .clone()
}

/// The cone margins of `sol` on the setup's contact dynamics.
fn cone_margins(s: &CircleSetup, sol: &Solution) -> Vec<[f64; 4]> {
    cones::cone_margins(&s.dynamics, MU, sol)
}

/// The largest distance (m) between the CoM at node `t` and
/// `c0 + r (sin ωt, cos ωt − 1, 0)`, over the nodes.
fn com_tracking_error(s: &CircleSetup, xs: &[Vec<f64>]) -> f64 {
    let model = s.dynamics.phase_space().model();
    let mut data = model.create_data();
    let zeros = vec![0.0; model.nv()];
    let mut worst = 0.0_f64;
    for (t, x) in xs.iter().enumerate() {
        let c = center_of_mass(model, &mut data, &x[..model.nq()], &zeros, &zeros).unwrap();
        let phase = OMEGA * t as f64 * DT;
        let target = [
            s.c0[0] + RADIUS * phase.sin(),
            s.c0[1] + RADIUS * (phase.cos() - 1.0),
            s.c0[2],
        ];
        let e = (0..3).map(|i| (c[i] - target[i]).powi(2)).sum::<f64>().sqrt();
        worst = worst.max(e);
    }
    worst
}

#[test]
fn csqp_and_proxddp_reach_the_same_optimum_inside_the_cones() {
    let s = setup();
    let (csqp, prox) = (solve_csqp(&s), solve_proxddp(&s));
    for (name, sol) in [("CSQP", &csqp), ("ProxDDP", &prox)] {
        eprintln!(
            "{name}: {:?} in {} iterations, cost {:.10e}, primal {:.1e}, dual {:.1e}",
            sol.status, sol.iterations, sol.cost, sol.prim_err, sol.dual_err
        );
        assert!(sol.status.converged(), "{name}: {:?}", sol.status);
        assert!(sol.prim_err <= TOL && sol.dual_err <= TOL, "{name}");
    }
    let rel = (csqp.cost - prox.cost).abs() / csqp.cost;
    eprintln!("relative cost difference {rel:.1e}");
    assert!(rel < 1e-6, "costs {} and {}", csqp.cost, prox.cost);
    for (name, sol) in [("CSQP", &csqp), ("ProxDDP", &prox)] {
        let margins = cone_margins(&s, sol);
        let worst = margins.iter().flatten().fold(f64::NEG_INFINITY, |a, &b| a.max(b));
        let active: Vec<usize> = (0..N).filter(|&t| margins[t].iter().any(|&m| m > -1e-6)).collect();
        eprintln!("{name}: largest ‖f_t‖ − μ f_n {worst:.1e} N; stages on a cone boundary: {active:?}");
        assert!(worst < 1e-7, "{name}: a force leaves its cone by {worst:e} N");
        // The cones bind: the HL foot from stage 53, where the unconstrained
        // optimum would slip.
        assert!(
            active.len() >= 20 && active.iter().all(|&t| t >= 50),
            "{name}: {active:?}"
        );
        let err = com_tracking_error(&s, &sol.xs);
        eprintln!("{name}: largest CoM distance to the circle {:.2} mm", 1e3 * err);
        assert!(err < 1e-4, "{name}: {err}");
    }
}

#[test]
fn the_standing_robot_is_at_the_start_of_the_circle() {
    let s = setup();
    let model = s.dynamics.phase_space().model();
    let mut data = model.create_data();
    let zeros = vec![0.0; model.nv()];
    let c = center_of_mass(model, &mut data, &s.x0[..model.nq()], &zeros, &zeros).unwrap();
    // The CoM height is the circle's; its x, y lie above the feet's mean (the
    // symmetric posture) within a millimetre.
    assert!((c.z - s.c0[2]).abs() < 1e-15);
    assert!(
        (c.x - s.c0[0]).abs() < 1e-3 && (c.y - s.c0[1]).abs() < 1e-3,
        "{c:?} {:?}",
        s.c0
    );
    assert_eq!(solo_com_circle::com_target(s.c0, 0.0), s.c0);
}

#[test]
fn bad_parameters_are_errors() {
    for (params, what) in [
        (
            CircleParams {
                horizon: 0,
                ..CircleParams::default()
            },
            "horizon",
        ),
        (
            CircleParams {
                horizon: solo_com_circle::MAX_HORIZON + 1,
                ..CircleParams::default()
            },
            "horizon",
        ),
        (
            CircleParams {
                mu: 0.0,
                ..CircleParams::default()
            },
            "mu",
        ),
        (
            CircleParams {
                mu: f64::NAN,
                ..CircleParams::default()
            },
            "mu",
        ),
    ] {
        let err = solo_com_circle::setup(&params).unwrap_err().to_string();
        assert!(err.contains(what), "{err}");
    }
    assert!(solo_com_circle::build(0).is_err());
}
