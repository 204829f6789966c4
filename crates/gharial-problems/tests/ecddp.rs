//! The experiments of ECDDP (El Kazdadi et al. 2021, IV) with BCL-DDP: the cart-pole with
//! the penalty strategies of Figs. 2-4, constant and affine multipliers, and the UR5
//! reaching three targets (Fig. 6); the optima against ProxDDP's, an independent solver
//! (a primal-dual augmented Lagrangian on the same problem).

use gharial::problem::Problem;
use gharial::solvers::bcl_ddp::{BclDdp, BclDdpOptions, Multipliers, PenaltyUpdate, Schedule};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solution, Solver, Status};
use gharial_problems::Example;

fn bcl(ex: &Example, opts: BclDdpOptions) -> Solution {
    let mut s = BclDdp::new(opts);
    s.setup(&ex.problem).unwrap();
    s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

fn proxddp(ex: &Example, tol: f64) -> Solution {
    let mut s = ProxDdp::new(ProxDdpOptions::default().with(|o| {
        o.tol = tol;
        o.max_iters = 2000;
    }));
    s.setup(&ex.problem).unwrap();
    s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

/// The settings of Fig. 2 (`μ_0 = 100`, `μ ← 100 μ`) with the given changes.
fn fig2(f: impl FnOnce(&mut BclDdpOptions)) -> BclDdpOptions {
    BclDdpOptions::default().with(|o| {
        o.mu_init = 100.0;
        o.penalty_factor = 100.0;
        o.max_iters = 1000;
        f(o);
    })
}

fn max_diff(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs()))
        .fold(0.0, f64::max)
}

/// Largest constraint violation of `(xs, us)`, evaluated afresh.
fn violation(p: &Problem, sol: &Solution) -> f64 {
    let kkt = gharial::problem::kkt_residuals(p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
    kkt.constraints.max(kkt.dynamics)
}

/// Figs. 2-3: with the BCL rules, both the fixed factor and the adaptive penalty converge
/// to the constraint tolerance, at ProxDDP's optimum. Measured: fixed factor 419
/// iterations (3 multiplier updates, final μ = 1e8, violation 1.1e-11), adaptive 403
/// (3, μ = 9.2e7, 3.1e-11); the optimal cost 90.516804173 of both agrees with ProxDDP's
/// (tol 1e-8) to 1e-10 relative, the controls to 3e-4 and 9e-4 N (the gradient tolerance
/// 1e-6 on `∇_u L`, whose control Hessian is `dt = 0.01`, leaves about 1e-4 N per unit of
/// conditioning; the forces reach tens of newtons).
#[test]
fn bcl_converges_on_the_cartpole_with_both_penalty_updates() {
    let ex = gharial_problems::build("ecddp-cartpole").unwrap();
    let reference = proxddp(&ex, 1e-8);
    assert!(violation(&ex.problem, &reference) < 1e-8, "{:?}", reference.status);
    for penalty in [PenaltyUpdate::Factor, PenaltyUpdate::Adaptive] {
        let sol = bcl(&ex, fig2(|o| o.penalty = penalty));
        let viol = violation(&ex.problem, &sol);
        eprintln!(
            "{penalty:?}: {} after {} iterations, {} multiplier updates, mu {:e}, violation {viol:e}, cost {:.12}",
            sol.status, sol.iterations, sol.al_iterations, sol.mu, sol.cost
        );
        assert_eq!(sol.status, Status::Converged, "{penalty:?}");
        assert!(viol <= 1e-6, "{penalty:?}: {viol:e}");
        let rel = (sol.cost - reference.cost).abs() / reference.cost;
        let du = max_diff(&sol.us, &reference.us);
        eprintln!("  against ProxDDP: cost {rel:e} relative, controls {du:e}");
        assert!(rel < 1e-7 && du < 2e-3, "{penalty:?}: {rel:e} {du:e}");
    }
}

/// Fig. 4: updating the multipliers at every iteration and multiplying `μ` by 3 does not
/// converge. Measured: the penalty reaches its bound 1e12 after 22 iterations, at a
/// nearly feasible (violation 7.7e-6) but far from optimal point (cost 351.6, four times
/// the optimum 90.5); with no practical bound on μ (1e100) the regularisation fails after
/// 59 iterations at a feasible point (violation 7e-18) of cost 224.1.
#[test]
fn updating_every_iteration_does_not_converge_on_the_cartpole() {
    let ex = gharial_problems::build("ecddp-cartpole").unwrap();
    let optimum = bcl(&ex, fig2(|_| {})).cost;
    for mu_max in [1e12, 1e100] {
        let sol = bcl(
            &ex,
            fig2(|o| {
                o.schedule = Schedule::EveryIteration;
                o.penalty_factor = 3.0;
                o.mu_max = mu_max;
            }),
        );
        eprintln!(
            "every iteration, mu x 3 (mu_max {mu_max:e}): {} after {} iterations, mu {:e}, violation {:e}, cost {:.6} \
             (optimum {optimum:.6})",
            sol.status,
            sol.iterations,
            sol.mu,
            violation(&ex.problem, &sol),
            sol.cost
        );
        assert_ne!(sol.status, Status::Converged);
        assert!(sol.cost > 1.5 * optimum, "{} vs {optimum}", sol.cost);
    }
}

/// III-A and III-B: constant and affine multipliers both converge on the cart-pole whose
/// configuration constraint is written on the last control (29), to the same optimum.
/// Measured: constant 419 iterations, affine 399 (3 multiplier updates each).
#[test]
fn constant_and_affine_multipliers_both_converge() {
    let ex = gharial_problems::build("ecddp-cartpole-advanced").unwrap();
    let mut costs = Vec::new();
    for multipliers in [Multipliers::Constant, Multipliers::Affine] {
        let sol = bcl(&ex, fig2(|o| o.multipliers = multipliers));
        let viol = violation(&ex.problem, &sol);
        eprintln!(
            "{multipliers:?}: {} after {} iterations, {} multiplier updates, violation {viol:e}, cost {:.12}",
            sol.status, sol.iterations, sol.al_iterations, sol.cost
        );
        assert_eq!(sol.status, Status::Converged, "{multipliers:?}");
        assert!(viol <= 1e-6, "{multipliers:?}: {viol:e}");
        costs.push(sol.cost);
    }
    assert!((costs[0] - costs[1]).abs() < 1e-6 * costs[0], "{costs:?}");
    // The same problem as ecddp-cartpole, written differently: the same optimum.
    let terminal = bcl(&gharial_problems::build("ecddp-cartpole").unwrap(), fig2(|_| {}));
    assert!((terminal.cost - costs[0]).abs() < 1e-8 * costs[0]);
}

/// Fig. 6: the UR5 through three targets. Measured: 19 iterations (2 multiplier updates,
/// μ = 1e10), violation 4e-8, cost 0.3305504806; ProxDDP (tol 1e-8) 0.3305504943 (4e-8
/// relative), controls within 2e-5 N m. (The paper: about 50 iterations to 1e-6.)
#[test]
fn ur5_reaches_three_targets() {
    let ex = gharial_problems::build("ecddp-ur5").unwrap();
    let sol = bcl(&ex, fig2(|_| {}));
    let viol = violation(&ex.problem, &sol);
    eprintln!(
        "ur5: {} after {} iterations, {} multiplier updates, mu {:e}, violation {viol:e}, cost {:.10}",
        sol.status, sol.iterations, sol.al_iterations, sol.mu, sol.cost
    );
    assert_eq!(sol.status, Status::Converged);
    assert!(viol <= 1e-6, "{viol:e}");
    let reference = proxddp(&ex, 1e-8);
    let rel = (sol.cost - reference.cost).abs() / reference.cost;
    let du = max_diff(&sol.us, &reference.us);
    eprintln!(
        "  ProxDDP: {} cost {:.10}; cost {rel:e} relative, controls {du:e}",
        reference.status, reference.cost
    );
    assert!(rel < 1e-5 && du < 1e-2, "{rel:e} {du:e}");
}

/// ProxDDP at the catalogue's settings (`gharial solve ecddp-cartpole`: tolerance 1e-5,
/// the nonmonotone line search) converges on both cart-poles, to BCL-DDP's optimum.
/// Measured: 477 and 485 iterations, cost 90.516788 against 90.516804 (2e-7 relative).
#[test]
fn proxddp_converges_at_the_catalogue_settings() {
    for name in ["ecddp-cartpole", "ecddp-cartpole-advanced"] {
        let ex = gharial_problems::build(name).unwrap();
        let mut s = ex.options("proxddp").unwrap().build();
        s.setup(&ex.problem).unwrap();
        let sol = s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
        let viol = violation(&ex.problem, sol);
        eprintln!(
            "{name}: {} in {} iterations, cost {}, violation {viol:e}",
            sol.status, sol.iterations, sol.cost
        );
        assert_eq!(sol.status, Status::Converged, "{name}");
        assert!(viol <= 1e-5, "{name}: {viol:e}");
        let reference = bcl(&ex, fig2(|_| {}));
        assert_eq!(reference.status, Status::Converged, "{name}");
        let rel = (sol.cost - reference.cost).abs() / reference.cost;
        assert!(rel < 1e-6, "{name}: {} against {}", sol.cost, reference.cost);
    }
}
