//! The stagewise ADMM QP solver against an independent QP solver: on the random
//! box-constrained LQ problems of `tests/data/qp_reference.json` (control bounds, some
//! with a terminal equality), its solution has Clarabel's optimal cost to 1e-6 and keeps
//! the bounds to the ADMM tolerance; warm starts take fewer iterations; a solve allocates
//! nothing; contradictory bounds are refused, infeasible ones end at the limit.

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
#[path = "support/lq_ocp.rs"]
mod lq_ocp;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

use faer::Col;
use gharial::lq::{LqKnot, LqProblem};
use gharial::problem::ProblemData;
use gharial::solvers::admm::{AdmmOptions, AdmmQp, AdmmStatus};
use lq_ocp::*;

/// The QP of a case: its exact LQ with one row per control (`D = I`) at every running
/// knot and, with a target, one per state (`C = I`) at the last; the bounds of the rows.
fn qp(case: &QpCase) -> (LqProblem, Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let lq = &case.lq;
    let mut p = exact_lq(lq, None);
    let (mut lo, mut hi) = (Vec::new(), Vec::new());
    let n = lq.n;
    for t in 0..=n {
        let old = &p.knots[t];
        let nc = if t < n {
            lq.nu
        } else if case.target.is_some() {
            lq.nx
        } else {
            0
        };
        let mut k = LqKnot::new(old.nx, old.nu, nc, old.nx_next);
        k.Q.copy_from(&old.Q);
        k.S.copy_from(&old.S);
        k.R.copy_from(&old.R);
        k.q = old.q.clone();
        k.r = old.r.clone();
        k.A.copy_from(&old.A);
        k.B.copy_from(&old.B);
        k.f = old.f.clone();
        if t < n {
            for i in 0..nc {
                k.D[(i, i)] = 1.0;
            }
            lo.push(vec![-case.umax; nc]);
            hi.push(vec![case.umax; nc]);
        } else {
            for i in 0..nc {
                k.C[(i, i)] = 1.0;
            }
            let xt = case.target.clone().unwrap_or_default();
            lo.push(xt.clone());
            hi.push(xt);
        }
        p.knots[t] = k;
    }
    (p, lo, hi)
}

fn trajectory(cols: &[Col<f64>]) -> Vec<Vec<f64>> {
    cols.iter().map(|c| c.iter().copied().collect()).collect()
}

#[test]
fn admm_reaches_the_optimum_of_an_independent_qp_solver() {
    let cases = qp_reference_cases();
    assert!(cases.len() >= 6);
    let opts = AdmmOptions::default().with(|o| {
        o.eps_abs = 1e-9;
        o.eps_rel = 0.0;
        o.max_iters = 20_000;
    });
    for case in &cases {
        let (mut lq, lo, hi) = qp(case);
        let mut admm = AdmmQp::new(&lq, opts).unwrap();
        let status = admm.solve(&mut lq, &lo, &hi, false).unwrap();
        assert_eq!(status, AdmmStatus::Converged, "seed {}", case.seed);
        let sol = admm.solution();
        let (xs, us) = (trajectory(&sol.xs), trajectory(&sol.us));
        let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
        let mut data = ProblemData::new(&p, 1).unwrap();
        let cost = data.evaluate(&p, &xs, &us);
        let rel = (cost - case.clarabel_cost).abs() / case.clarabel_cost.abs().max(1.0);
        assert!(
            rel < 1e-6,
            "seed {}: cost {cost} vs Clarabel {} ({rel:e})",
            case.seed,
            case.clarabel_cost
        );
        let worst = us
            .iter()
            .flatten()
            .map(|u| u.abs() - case.umax)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(worst < 1e-8, "seed {}: bound exceeded by {worst:e}", case.seed);
        assert!(worst > -1e-6, "seed {}: the bound is active", case.seed);
        if let Some(xt) = &case.target {
            let d = xs[case.lq.n]
                .iter()
                .zip(xt)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(d < 1e-7, "seed {}: terminal target missed by {d:e}", case.seed);
        }
        eprintln!(
            "seed {}: {} ADMM iterations, rho {:.3e}",
            case.seed,
            admm.iterations(),
            admm.rho()
        );
    }
}

#[test]
fn a_warm_start_takes_fewer_iterations_and_bad_bounds_are_refused() {
    let case = &qp_reference_cases()[0];
    let (mut lq, lo, mut hi) = qp(case);
    let mut admm = AdmmQp::new(&lq, AdmmOptions::default()).unwrap();
    assert_eq!(admm.solve(&mut lq, &lo, &hi, false).unwrap(), AdmmStatus::Converged);
    let cold = admm.iterations();
    assert_eq!(admm.solve(&mut lq, &lo, &hi, true).unwrap(), AdmmStatus::Converged);
    assert!(admm.iterations() < cold, "warm {} vs cold {cold}", admm.iterations());
    let allocations = counting_alloc::local_allocations_during(|| {
        admm.solve(&mut lq, &lo, &hi, false).unwrap();
    });
    assert_eq!(allocations, 0, "a solve allocates nothing");
    hi[3][0] = lo[3][0] - 1.0;
    let e = admm.solve(&mut lq, &lo, &hi, false).unwrap_err().to_string();
    assert!(e.contains("knot 3, row 0"), "{e}");
    assert!(admm.solve(&mut lq, &lo[..2], &hi, false).is_err());
    assert!(AdmmQp::new(&lq, AdmmOptions::default().with(|o| o.alpha = 2.0)).is_err());
}

/// The residuals are computed on the check iterations only, but those reported are of the
/// last iteration: a converged solve stops on a check (a multiple of 25 iterations) and
/// its primal residual `|G δ - z|_∞` bounds the violation of the bounds by `G δ`, recomputed
/// here from the solution; so does the residual of a solve stopped by a limit that is not
/// a multiple of 25.
#[test]
fn the_reported_residuals_are_those_of_the_last_iteration() {
    let case = &qp_reference_cases()[1];
    let (mut lq, lo, hi) = qp(case);
    for max_iters in [1000, 37] {
        let mut admm = AdmmQp::new(&lq, AdmmOptions::default().with(|o| o.max_iters = max_iters)).unwrap();
        let status = admm.solve(&mut lq, &lo, &hi, false).unwrap();
        let (prim, dual) = admm.residuals();
        let sol = admm.solution();
        let (mut violation, mut g_max) = (0.0_f64, 0.0_f64);
        for (t, knot) in lq.knots.iter().enumerate() {
            for i in 0..knot.nc {
                let mut g = (0..knot.nx).map(|j| knot.C[(i, j)] * sol.xs[t][j]).sum::<f64>();
                g += (0..knot.nu).map(|j| knot.D[(i, j)] * sol.us[t][j]).sum::<f64>();
                violation = violation.max(lo[t][i] - g).max(g - hi[t][i]);
                g_max = g_max.max(g.abs());
            }
        }
        assert!(dual.is_finite() && dual >= 0.0, "{dual}");
        assert!(
            violation <= prim * (1.0 + 1e-12) + 1e-15,
            "violation {violation:e} > residual {prim:e}"
        );
        if max_iters == 1000 {
            assert_eq!(status, AdmmStatus::Converged);
            assert_eq!(admm.iterations() % 25, 0, "{}", admm.iterations());
            assert!(prim <= 1e-4 + 1e-4 * (g_max + prim), "{prim:e}");
        } else {
            assert_eq!((status, admm.iterations()), (AdmmStatus::MaxIterations, 37));
        }
    }
}

/// The x-updates roll out states and controls only; the solution returned, converged or
/// at the iteration limit, is nevertheless the whole solution of the last x-update's LQ
/// (its knots hold that LQ's vectors): states, controls, co-states and the LQ's
/// constraint multipliers equal a dense KKT solve of it.
#[test]
fn the_returned_solution_solves_the_last_lq_whole() {
    use gharial::lq::dense;
    let case = &qp_reference_cases()[1];
    let (mut lq, lo, hi) = qp(case);
    for (max_iters, expected) in [(1000, AdmmStatus::Converged), (37, AdmmStatus::MaxIterations)] {
        let mut admm = AdmmQp::new(&lq, AdmmOptions::default().with(|o| o.max_iters = max_iters)).unwrap();
        assert_eq!(admm.solve(&mut lq, &lo, &hi, false).unwrap(), expected);
        let reference = dense::solve(&lq).unwrap();
        let sol = admm.solution();
        let blocks = [
            (&sol.xs, &reference.xs, "x"),
            (&sol.us, &reference.us, "u"),
            (&sol.lambdas, &reference.lambdas, "lambda"),
            (&sol.nus, &reference.nus, "nu"),
        ];
        for (got, want, what) in blocks {
            let scale = want.iter().flat_map(|c| c.iter()).fold(1.0_f64, |m, v| m.max(v.abs()));
            for (t, (g, w)) in got.iter().zip(want).enumerate() {
                for (a, b) in g.iter().zip(w.iter()) {
                    assert!((a - b).abs() <= 1e-8 * scale, "{max_iters}: {what}[{t}] {a} vs {b}");
                }
            }
        }
    }
}

/// A QP without constraint rows (an unconstrained LQ) is solved by the first x-update:
/// one iteration, the dense KKT solution with its co-states.
#[test]
fn a_qp_without_rows_takes_one_iteration() {
    use gharial::lq::dense;
    let mut lq = exact_lq(&random_lq(4, 2, 12, 5), None);
    let empty = vec![Vec::new(); lq.knots.len()];
    let mut admm = AdmmQp::new(&lq, AdmmOptions::default()).unwrap();
    assert_eq!(
        admm.solve(&mut lq, &empty, &empty, false).unwrap(),
        AdmmStatus::Converged
    );
    assert_eq!(admm.iterations(), 1);
    let reference = dense::solve(&lq).unwrap();
    let sol = admm.solution();
    for (got, want) in [
        (&sol.xs, &reference.xs),
        (&sol.us, &reference.us),
        (&sol.lambdas, &reference.lambdas),
    ] {
        for (g, w) in got.iter().zip(want) {
            for (a, b) in g.iter().zip(w.iter()) {
                assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()), "{a} vs {b}");
            }
        }
    }
}

/// An infeasible QP (a terminal target out of reach of the bounded controls) ends at the
/// iteration limit with a large primal residual, not in a hang.
#[test]
fn an_infeasible_qp_ends_at_the_iteration_limit() {
    let case = qp_reference_cases().into_iter().find(|c| c.target.is_some()).unwrap();
    let (mut lq, mut lo, mut hi) = qp(&case);
    let n = case.lq.n;
    lo[n].iter_mut().for_each(|v| *v = 1e3);
    hi[n].iter_mut().for_each(|v| *v = 1e3);
    let mut admm = AdmmQp::new(&lq, AdmmOptions::default().with(|o| o.max_iters = 300)).unwrap();
    assert_eq!(admm.solve(&mut lq, &lo, &hi, false).unwrap(), AdmmStatus::MaxIterations);
    assert_eq!(admm.iterations(), 300);
    assert!(admm.residuals().0 > 1.0, "{:?}", admm.residuals());
}

/// CSQP on the same LQ problems written as OCPs (control bounds as `ControlError` in a
/// box, the target as a terminal equality): Clarabel's optimum, the KKT conditions with
/// the multipliers it returns, in few SQP iterations.
#[test]
fn csqp_reaches_the_optimum_of_an_independent_qp_solver() {
    use gharial::problem::kkt_residuals;
    use gharial::solvers::csqp::{Csqp, CsqpOptions};
    use gharial::solvers::{InitialGuess, Solver, Status};
    for case in &qp_reference_cases() {
        let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
        let (xs, us) = zero_guess(&p);
        let opts = CsqpOptions::default().with(|o| {
            o.tol = 1e-7;
            o.admm = o.admm.with(|a| {
                a.eps_abs = 1e-9;
                a.eps_rel = 0.0;
                a.max_iters = 20_000;
            });
        });
        let mut solver = Csqp::new(opts);
        solver.setup(&p).unwrap();
        let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        assert_eq!(sol.status, Status::Converged, "seed {}", case.seed);
        assert!(sol.iterations <= 3, "seed {}: {} iterations", case.seed, sol.iterations);
        let rel = (sol.cost - case.clarabel_cost).abs() / case.clarabel_cost.abs().max(1.0);
        assert!(
            rel < 1e-6,
            "seed {}: cost {} vs Clarabel {}",
            case.seed,
            sol.cost,
            case.clarabel_cost
        );
        let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < 1e-6, "seed {}: {kkt:?}", case.seed);
        let allocations = counting_alloc::local_allocations_during(|| {
            solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        });
        assert_eq!(allocations, 0, "seed {}: a CSQP solve allocates nothing", case.seed);
    }
}

/// CSQP on QPs whose Hessian is singular in the controls (no running cost, a terminal
/// cost on one state: most knots' `Q_uu` vanish) regularises them as SQP does instead
/// of stopping at the first factorization: converged at the optimal cost 0, with and
/// without control bounds.
#[test]
fn csqp_regularises_singular_qps() {
    use faer::Mat;
    use gharial::problem::kkt_residuals;
    use gharial::solvers::csqp::{Csqp, CsqpOptions};
    use gharial::solvers::{InitialGuess, Solver, Status};
    let mut lq = random_lq(4, 2, 10, 17);
    lq.q = Mat::zeros(4, 4);
    lq.s = Mat::zeros(4, 2);
    lq.r = Mat::zeros(2, 2);
    lq.qf = Mat::from_fn(4, 4, |i, j| if i == 0 && j == 0 { 1.0 } else { 0.0 });
    lq.c = vec![0.0; 4];
    (lq.qv, lq.rv, lq.qfv) = (vec![0.0; 4], vec![0.0; 2], vec![0.0; 4]);
    for umax in [None, Some(5.0)] {
        let p = ocp(&lq, umax, None);
        let (xs, us) = zero_guess(&p);
        let mut solver = Csqp::new(CsqpOptions::default());
        solver.setup(&p).unwrap();
        let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        assert_eq!(sol.status, Status::Converged, "{umax:?}");
        assert!(sol.cost < 1e-10, "{umax:?}: {}", sol.cost);
        let kkt = kkt_residuals(&p, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < 1e-6, "{umax:?}: {kkt:?}");
    }
}

/// CSQP with second-order-cone constraints (a cone on the controls of a random LQ,
/// `‖(u_1, u_2)‖ ≤ u_0 + 0.3`, the shape of a friction cone) reaches ProxDDP's optimum,
/// with the cone active; a penalty (L1) is refused at setup.
#[test]
fn csqp_handles_second_order_cones_like_proxddp() {
    use std::sync::Arc;

    use gharial::constraints::{L1Penalty, SecondOrderCone};
    use gharial::functions::ControlError;
    use gharial::problem::StageConstraint;
    use gharial::solvers::csqp::{Csqp, CsqpOptions};
    use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
    use gharial::solvers::{InitialGuess, Solver, Status};
    let lq = random_lq(4, 3, 30, 77);
    let mut p = ocp(&lq, None, None);
    let sp = space(&lq);
    let cone = || {
        StageConstraint::new(
            "cone",
            Arc::new(ControlError::new(sp.as_ref(), &[-0.3, 0.0, 0.0]).unwrap()),
            Arc::new(SecondOrderCone::new(3).unwrap()),
        )
    };
    for s in p.stages_mut() {
        s.add_constraint(cone()).unwrap();
    }
    let (xs, us) = zero_guess(&p);
    let mut reference = ProxDdp::new(ProxDdpOptions::default().with(|o| {
        o.tol = 1e-7;
        o.mu_init = 1e-5;
        o.max_iters = 1000;
    }));
    reference.setup(&p).unwrap();
    let r = reference.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert_eq!(
        r.status,
        Status::Converged,
        "ProxDDP: {} after {} iterations, prim {:e} dual {:e}",
        r.status,
        r.iterations,
        r.prim_err,
        r.dual_err
    );
    let mut csqp = Csqp::new(CsqpOptions::default().with(|o| {
        o.tol = 1e-7;
        o.admm = o.admm.with(|a| {
            a.eps_abs = 1e-9;
            a.eps_rel = 0.0;
            a.max_iters = 20_000;
        });
    }));
    csqp.setup(&p).unwrap();
    let sol = csqp.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
    assert_eq!(sol.status, Status::Converged, "{}", sol.status);
    let rel = (sol.cost - r.cost).abs() / r.cost.abs().max(1.0);
    assert!(rel < 1e-6, "cost {} vs ProxDDP {}", sol.cost, r.cost);
    let margin = |u: &Vec<f64>| u[0] + 0.3 - (u[1] * u[1] + u[2] * u[2]).sqrt();
    let worst = sol.us.iter().map(margin).fold(f64::INFINITY, f64::min);
    assert!(worst > -1e-6 && worst < 1e-6, "the cone is active and kept: {worst:e}");
    let mut l1 = ocp(&lq, None, None);
    let pen = StageConstraint::new(
        "l1",
        Arc::new(ControlError::new(sp.as_ref(), &[0.0; 3]).unwrap()),
        Arc::new(L1Penalty::new(1.0).unwrap()),
    );
    l1.stages_mut()[0].add_constraint(pen).unwrap();
    let e = Csqp::new(CsqpOptions::default()).setup(&l1).unwrap_err().to_string();
    assert!(e.contains("penalty"), "{e}");
}
