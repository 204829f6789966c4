//! BCL-DDP on equality-constrained LQ problems against the dense KKT solution, with
//! constant and affine multipliers, both penalty updates and both inner solvers; the
//! refusal of other constraint kinds; option validation; warm starts.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;

use std::sync::Arc;

use faer::{Col, Mat};
use gharial::constraints::{BoxConstraint, EqualityConstraintSet, NegativeOrthant};
use gharial::functions::{ControlError, LinearFunction};
use gharial::lq::{LqKnot, LqProblem, dense};
use gharial::problem::{Problem, StageConstraint, kkt_residuals};
use gharial::solvers::bcl_ddp::{BclDdp, BclDdpOptions, Multipliers, PenaltyUpdate};
use gharial::solvers::ddp::{DdpOptions, DdpVariant};
use gharial::solvers::{InitialGuess, Solution, Solver, SolverOptions, Status};
use lq_ocp::*;

fn solve(p: &Problem, opts: BclDdpOptions, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Solution {
    let mut solver = BclDdp::new(opts);
    solver.setup(p).unwrap();
    solver.solve(p, InitialGuess::primal(xs, us)).unwrap().clone()
}

/// The path equality `a·x_t + b·u_t + c = 0` at every stage (random, `b ≠ 0`).
struct PathRow {
    a: Mat<f64>,
    b: Mat<f64>,
    c: Vec<f64>,
}

fn path_row(lq: &Lq, seed: u64) -> PathRow {
    let mut rng = gharial::lq::random::SplitMix64::new(seed);
    PathRow {
        a: Mat::from_fn(1, lq.nx, |_, _| rng.uniform(-1.0, 1.0)),
        b: Mat::from_fn(1, lq.nu, |_, j| if j == 0 { 1.0 } else { rng.uniform(-0.5, 0.5) }),
        c: vec![rng.uniform(-0.2, 0.2)],
    }
}

/// The OCP of `lq` with the path row at every stage and optionally the terminal target.
fn ocp_with_path(lq: &Lq, row: &PathRow, target: Option<&[f64]>) -> Problem {
    let mut p = ocp(lq, None, target);
    let f = Arc::new(LinearFunction::new(row.a.as_ref(), row.b.as_ref(), &row.c).unwrap());
    let c = StageConstraint::new("path_row", f, Arc::new(EqualityConstraintSet));
    let stages: Vec<_> = p
        .stages()
        .iter()
        .map(|s| s.clone().with_constraint(c.clone()).unwrap())
        .collect();
    let mut q = Problem::new(p.x0().unwrap(), stages, p.terminal_cost().clone()).unwrap();
    for tc in p.terminal_constraints() {
        q.add_terminal_constraint(tc.clone()).unwrap();
    }
    p = q;
    p
}

/// The exact KKT system of [`ocp_with_path`].
fn exact_with_path(lq: &Lq, row: &PathRow, target: Option<&[f64]>) -> LqProblem {
    let mut exact = exact_lq(lq, target);
    let n = lq.n;
    for k in &mut exact.knots[..n] {
        let mut w = LqKnot::new(k.nx, k.nu, 1, k.nx_next);
        w.Q.copy_from(&k.Q);
        w.S.copy_from(&k.S);
        w.R.copy_from(&k.R);
        w.q.copy_from(&k.q);
        w.r.copy_from(&k.r);
        w.A.copy_from(&k.A);
        w.B.copy_from(&k.B);
        w.f.copy_from(&k.f);
        w.C.copy_from(&row.a);
        w.D.copy_from(&row.b);
        w.d = Col::from_fn(1, |_| row.c[0]);
        *k = w;
    }
    exact
}

/// Every combination of multipliers, penalty update and inner solver. Affine multipliers
/// converge more slowly (their feedback biases the stationarity of the augmented
/// Lagrangian by `Λᵀh` until `h` vanishes), so the penalty grows larger and the gradient's
/// rounding floor (about `ε μ`) with it: their tolerance is `1e-7`, the others' `1e-8`;
/// the same bias, `Λᵀh` with `Λ ~ μ`, stays in their multipliers (checked to `1e-3`).
fn all_options() -> Vec<(String, BclDdpOptions)> {
    let mut v = Vec::new();
    for multipliers in [Multipliers::Constant, Multipliers::Affine] {
        for penalty in [PenaltyUpdate::Factor, PenaltyUpdate::Adaptive] {
            for variant in [DdpVariant::Ddp, DdpVariant::Fddp] {
                let o = BclDdpOptions::default().with(|o| {
                    o.multipliers = multipliers;
                    o.penalty = penalty;
                    o.ddp = DdpOptions::new(variant);
                    o.tol = if multipliers == Multipliers::Affine { 1e-7 } else { 1e-8 };
                });
                v.push((format!("{multipliers:?} {penalty:?} {}", variant.name()), o));
            }
        }
    }
    v
}

/// Solution against the dense KKT solve: states, controls, multipliers of every
/// constraint, and the KKT residuals recomputed from the problem.
fn check_against_dense(p: &Problem, sol: &Solution, reference: &gharial::lq::LqSolution, tol: f64, what: &str) {
    assert_eq!(sol.status, Status::Converged, "{what}: {:?}", sol.status);
    let scale = 1.0 + reference.xs.iter().map(|c| c.norm_max()).fold(0.0, f64::max);
    let dx = max_diff(&sol.xs, &reference.xs) / scale;
    let du = max_diff(&sol.us, &reference.us) / scale;
    let dn = max_diff(&sol.nus, &reference.nus) / scale;
    let affine = what.contains("Affine");
    let dn_bound = if affine { 1e-3 } else { 200.0 * tol };
    assert!(
        dx < 20.0 * tol && du < 20.0 * tol && dn < dn_bound,
        "{what}: {dx:e} {du:e} {dn:e}"
    );
    let kkt = kkt_residuals(p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
    let kkt = if affine { kkt.primal() } else { kkt.max() };
    assert!(kkt < 100.0 * tol, "{what}: {kkt:?}");
}

#[test]
fn terminal_equality_lq_reaches_the_dense_kkt_solution() {
    for (seed, (nx, nu, n)) in [(1, (3, 2, 10)), (2, (4, 2, 20)), (4, (2, 1, 5))] {
        let lq = random_lq(nx, nu, n, seed);
        let target: Vec<f64> = (0..nx).map(|i| 0.1 * i as f64 - 0.05).collect();
        let p = ocp(&lq, None, Some(&target));
        let reference = dense::solve(&exact_lq(&lq, Some(&target))).unwrap();
        for (what, opts) in all_options() {
            let (xs, us) = zero_guess(&p);
            let tol = opts.tol;
            let sol = solve(&p, opts, &xs, &us);
            check_against_dense(&p, &sol, &reference, tol, &format!("seed {seed} {what}"));
            eprintln!(
                "seed {seed} {what}: {} iterations, {} updates",
                sol.iterations, sol.al_iterations
            );
            assert!(
                sol.al_iterations >= 1 && sol.iterations < 80,
                "{what}: {}",
                sol.iterations
            );
        }
    }
}

#[test]
fn path_and_terminal_equalities_reach_the_dense_kkt_solution() {
    for (seed, (nx, nu, n)) in [(5, (3, 2, 12)), (6, (4, 3, 15))] {
        let lq = random_lq(nx, nu, n, seed);
        let row = path_row(&lq, seed + 100);
        let target: Vec<f64> = (0..nx).map(|i| 0.05 * i as f64).collect();
        for t in [None, Some(target.as_slice())] {
            let p = ocp_with_path(&lq, &row, t);
            let reference = dense::solve(&exact_with_path(&lq, &row, t)).unwrap();
            for (what, opts) in all_options() {
                let (xs, us) = zero_guess(&p);
                let tol = opts.tol;
                let sol = solve(&p, opts, &xs, &us);
                let what = format!("seed {seed} terminal {} {what}", t.is_some());
                check_against_dense(&p, &sol, &reference, tol, &what);
                eprintln!("{what}: {} iterations, {} updates", sol.iterations, sol.al_iterations);
            }
        }
    }
}

/// Affine multipliers: after a multiplier update `Λ ← Λ + μ(h_x + h_u K)` (28); the solve
/// stays exact and its rows report the same optimum as constant multipliers.
#[test]
fn affine_and_constant_multipliers_agree() {
    let lq = random_lq(3, 2, 15, 9);
    let row = path_row(&lq, 19);
    let p = ocp_with_path(&lq, &row, None);
    let (xs, us) = zero_guess(&p);
    let base = BclDdpOptions::default().with(|o| o.tol = 1e-10);
    let c = solve(&p, base.clone(), &xs, &us);
    let a = solve(&p, base.with(|o| o.multipliers = Multipliers::Affine), &xs, &us);
    assert!(c.status.converged() && a.status.converged());
    let d =
        c.us.iter()
            .zip(&a.us)
            .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs()))
            .fold(0.0, f64::max);
    assert!(d < 1e-8, "{d:e}");
    assert!((c.cost - a.cost).abs() < 1e-9 * (1.0 + c.cost.abs()));
}

#[test]
fn warm_start_from_the_solution_converges_at_once() {
    let lq = random_lq(3, 2, 10, 3);
    let target = [0.1, 0.0, -0.1];
    let p = ocp(&lq, None, Some(&target));
    let (xs, us) = zero_guess(&p);
    let mut solver = BclDdp::new(BclDdpOptions::default().with(|o| o.tol = 1e-9));
    solver.setup(&p).unwrap();
    let cold = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert!(cold.status.converged());
    let warm = solver.solve(&p, InitialGuess::from_solution(&cold)).unwrap();
    assert!(warm.status.converged());
    assert!(warm.iterations <= 1, "{} iterations", warm.iterations);
    assert!(warm.iterations < cold.iterations);
}

#[test]
fn inequality_and_box_constraints_are_refused_by_name() {
    let lq = random_lq(3, 2, 5, 1);
    let sp = space(&lq);
    let p = ocp(&lq, Some(0.5), None);
    let e = BclDdp::new(BclDdpOptions::default()).setup(&p).unwrap_err().to_string();
    assert!(
        e.contains("`u_box`") && e.contains("stage 0") && e.contains("equality"),
        "{e}"
    );
    let mut q = ocp(&lq, None, None);
    let f = Arc::new(gharial::functions::Unary::new(
        Arc::new(gharial::functions::StateError::new(sp.clone(), &[0.0; 3]).unwrap()),
        0,
    ));
    q.add_terminal_constraint(StageConstraint::new("x_N_le", f, Arc::new(NegativeOrthant)))
        .unwrap();
    let e = BclDdp::new(BclDdpOptions::default()).setup(&q).unwrap_err().to_string();
    assert!(e.contains("`x_N_le`") && e.contains("terminal"), "{e}");
    // An equality box ({0} written as a box) is still not the equality set.
    let mut r = ocp(&lq, None, None);
    let g = Arc::new(ControlError::new(sp.as_ref(), &[0.0, 0.0]).unwrap());
    let set = Arc::new(BoxConstraint::new(&[0.0, 0.0], &[0.0, 0.0]).unwrap());
    let stages: Vec<_> = r
        .stages()
        .iter()
        .map(|s| {
            s.clone()
                .with_constraint(StageConstraint::new("u_pin", g.clone(), set.clone()))
                .unwrap()
        })
        .collect();
    r = Problem::new(r.x0().unwrap(), stages, r.terminal_cost().clone()).unwrap();
    let e = BclDdp::new(BclDdpOptions::default()).setup(&r).unwrap_err().to_string();
    assert!(e.contains("`u_pin`"), "{e}");
}

#[test]
fn bad_options_are_refused_with_their_name() {
    let cases: Vec<(&str, BclDdpOptions)> = vec![
        ("tol", BclDdpOptions::default().with(|o| o.tol = 0.0)),
        ("mu_init", BclDdpOptions::default().with(|o| o.mu_init = 0.5)),
        ("mu_init", BclDdpOptions::default().with(|o| o.mu_init = f64::NAN)),
        ("mu_max", BclDdpOptions::default().with(|o| o.mu_max = 1.0)),
        ("bcl_alpha", BclDdpOptions::default().with(|o| o.bcl_alpha = 1.0)),
        (
            "adaptive_beta",
            BclDdpOptions::default().with(|o| o.adaptive_beta = 0.0),
        ),
        (
            "penalty_factor",
            BclDdpOptions::default().with(|o| o.penalty_factor = 1.0),
        ),
        ("max_growth", BclDdpOptions::default().with(|o| o.max_growth = 2.0)),
        ("max_iters", BclDdpOptions::default().with(|o| o.max_iters = 0)),
        ("eta_init", BclDdpOptions::default().with(|o| o.eta_init = -1.0)),
        (
            "ddp.variant",
            BclDdpOptions::default().with(|o| o.ddp = DdpOptions::new(DdpVariant::BoxDdp)),
        ),
        ("reg_max", BclDdpOptions::default().with(|o| o.ddp.reg_max = -1.0)),
    ];
    let lq = random_lq(2, 1, 4, 1);
    let p = ocp(&lq, None, Some(&[0.0, 0.0]));
    for (name, opts) in cases {
        let e = opts.validate().unwrap_err().to_string();
        assert!(e.contains(name), "{name}: {e}");
        let e = BclDdp::new(opts).setup(&p).unwrap_err().to_string();
        assert!(e.contains(name), "{name}: {e}");
    }
}

#[test]
fn picked_by_name_and_solve_before_setup_is_an_error() {
    let options = SolverOptions::from_name("bcl-ddp").unwrap();
    assert_eq!(options.name(), "bcl-ddp");
    let mut solver = options.build();
    assert_eq!(solver.name(), "bcl-ddp");
    let lq = random_lq(2, 1, 4, 2);
    let p = ocp(&lq, None, Some(&[0.1, 0.0]));
    let (xs, us) = zero_guess(&p);
    let e = solver
        .solve(&p, InitialGuess::primal(&xs, &us))
        .unwrap_err()
        .to_string();
    assert!(e.contains("before setup"), "{e}");
    solver.setup(&p).unwrap();
    assert!(
        solver
            .solve(&p, InitialGuess::primal(&xs, &us))
            .unwrap()
            .status
            .converged()
    );
    let e = solver.setup_receding(&p, &[]).unwrap_err().to_string();
    assert!(e.contains("receding"), "{e}");
}
