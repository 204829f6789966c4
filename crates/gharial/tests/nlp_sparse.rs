//! ProxNLP's sparse KKT solve against its dense one on the small problems of `nlp.rs`
//! (Clarabel's QPs with equality, inequality, box and second-order-cone blocks, the
//! tilt-limited alignment on SO(3), the capped sphere, and the LQ optimal control
//! problems with bounds, terminal constraints and implicit dynamics): both take the same
//! iterates, every record of the iteration history and the final point and multipliers
//! agreeing to 1e-10.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;
#[path = "support/nlp_problems.rs"]
mod nlp_problems;

use gharial::nlp::{KktSolver, Nlp, NlpSolution, ProxNlp, ProxNlpOcp, ProxNlpOptions};
use gharial::solvers::{HessianApprox, InitialGuess, IterationRecord, Solver};
use lq_ocp::*;
use nlp_problems::*;

/// `|a - b|`, relative above 1.
fn diff(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1.0)
}

/// The fields of an iteration record that the iterates determine.
fn fields(r: &IterationRecord) -> [f64; 10] {
    [
        r.alpha,
        r.inner_crit,
        r.prim_err,
        r.dual_err,
        r.preg,
        r.cost,
        r.dphi0,
        r.merit,
        r.dmerit,
        r.mu,
    ]
}

/// The dense and the sparse solve took the same iterates.
fn assert_same_iterates(name: &str, dense: &NlpSolution, sparse: &NlpSolution) {
    assert_eq!(
        (dense.status, dense.iterations, dense.al_iterations),
        (sparse.status, sparse.iterations, sparse.al_iterations),
        "{name}: status, iterations, outer iterations"
    );
    assert!(dense.iterations > 0, "{name}: no iteration");
    assert_eq!(dense.history.len(), sparse.history.len(), "{name}");
    for (a, b) in dense.history.iter().zip(&sparse.history) {
        let worst = fields(a)
            .iter()
            .zip(fields(b))
            .map(|(x, y)| diff(*x, y))
            .fold(0.0, f64::max);
        assert!(worst < 1e-10, "{name}: iteration {}: {a:?} vs {b:?}", a.iter);
    }
    let dx = max_abs_diff(&dense.x, &sparse.x);
    let dnu = max_abs_diff(&dense.multipliers, &sparse.multipliers);
    assert!(dx < 1e-10 && dnu < 1e-10, "{name}: |Δx| {dx:e}, |Δν| {dnu:e}");
    assert!(diff(dense.cost, sparse.cost) < 1e-10, "{name}: cost");
}

/// Solves `nlp` from `x0` with the dense and the sparse KKT solve.
fn solve_both(nlp: &dyn Nlp, opts: &ProxNlpOptions, x0: &[f64]) -> [NlpSolution; 2] {
    [KktSolver::Dense, KktSolver::Sparse].map(|kkt| {
        let mut solver = ProxNlp::new(opts.clone().with(|o| o.kkt = kkt));
        solver.setup(nlp).unwrap();
        assert_eq!(solver.kkt_stats().unwrap().sparse, kkt == KktSolver::Sparse);
        solver.solve(nlp, x0, None).unwrap().clone()
    })
}

fn options(hessian: HessianApprox) -> ProxNlpOptions {
    ProxNlpOptions::default().with(|o| {
        o.tol = 1e-11;
        o.hessian = hessian;
    })
}

#[test]
fn sparse_kkt_takes_the_dense_iterates_on_small_nlps() {
    for case in qp_cases() {
        let nlp = qp_nlp(&case);
        let x0 = vec![0.0; nlp.space().nx()];
        let [d, s] = solve_both(&nlp, &options(HessianApprox::GaussNewton), &x0);
        assert_same_iterates(case["name"].as_str().unwrap(), &d, &s);
    }
    let (tilt, _, _) = tilt_problem();
    for hessian in [HessianApprox::GaussNewton, HessianApprox::Exact] {
        // Gauss-Newton converges linearly here: its first 40 iterates are compared.
        let opts = options(hessian).with(|o| o.max_iters = 40);
        let [d, s] = solve_both(&tilt, &opts, &tilt_start());
        assert_same_iterates(&format!("tilt {hessian:?}"), &d, &s);
        let sphere = capped_sphere([0.6, -0.9, 1.5], 0.2);
        let [d, s] = solve_both(&sphere, &options(hessian), &[0.3, 0.3, -0.5]);
        assert_same_iterates(&format!("capped sphere {hessian:?}"), &d, &s);
    }
}

#[test]
fn sparse_kkt_takes_the_dense_iterates_on_lq_ocps() {
    let lq = random_lq(3, 2, 8, 31);
    let target = reachable_target(&lq, 0.3);
    let (implicit, _) = implicit_euler_ocp(&lq, 0.1);
    let problems = [
        ("plain", ocp(&lq, None, None)),
        ("bounds", ocp(&lq, Some(0.3), None)),
        ("bounds-terminal", ocp(&lq, Some(0.3), Some(&target))),
        ("implicit", implicit),
    ];
    for (name, p) in &problems {
        let (xs, us) = zero_guess(p);
        for hessian in [HessianApprox::GaussNewton, HessianApprox::Exact] {
            let [d, s] = [KktSolver::Dense, KktSolver::Sparse].map(|kkt| {
                let mut solver = ProxNlpOcp::new(options(hessian).with(|o| o.kkt = kkt));
                Solver::setup(&mut solver, p).unwrap();
                assert_eq!(solver.kkt_stats().unwrap().sparse, kkt == KktSolver::Sparse);
                solver.solve(p, InitialGuess::primal(&xs, &us)).unwrap();
                solver.nlp_solution().clone()
            });
            assert!(d.status.converged(), "{name}: {}", d.status);
            assert_same_iterates(&format!("{name} {hessian:?}"), &d, &s);
        }
    }
}
