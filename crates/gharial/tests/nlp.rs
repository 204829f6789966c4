//! ProxNLP: small QPs against Clarabel's optima and multipliers
//! (`tests/data/qp_reference.json`, written by `tools/qp-reference`), nonlinear problems
//! on manifolds against their analytical optima and a finite-difference KKT check,
//! optimal control problems against ProxDDP, and bad input.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;
#[path = "support/nlp_problems.rs"]
mod nlp_problems;

use std::sync::Arc;

use faer::Mat;
use gharial::Error;
use gharial::autodiff::{AutoCostFn, AutoDiff, ManifoldScalar};
use gharial::constraints::{NegativeOrthant, SecondOrderCone};
use gharial::costs::QuadraticCost;
use gharial::functions::LinearUnaryFunction;
use gharial::nlp::{KktSolver, Nlp, NlpConstraint, NlpProblem, ProxNlp, ProxNlpOcp, ProxNlpOptions};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{HessianApprox, InitialGuess, Solver, Status};
use gharial::spaces::{Manifold, SO3, VectorSpace};
use lq_ocp::*;
use nlp_problems::*;
use serde_json::Value;

fn tight() -> ProxNlpOptions {
    ProxNlpOptions::default().with(|o| o.tol = 1e-11)
}

/// The projection onto the second-order cone `{(t, s): |s| <= t}` (written here from
/// its formula, independently of the library's).
fn soc_projection(z: &[f64]) -> Vec<f64> {
    let (t, s) = (z[0], &z[1..]);
    let r = s.iter().map(|v| v * v).sum::<f64>().sqrt();
    if r <= t {
        z.to_vec()
    } else if r <= -t {
        vec![0.0; z.len()]
    } else {
        let a = 0.5 * (t + r);
        std::iter::once(a).chain(s.iter().map(|v| a * v / r)).collect()
    }
}

/// The KKT residuals of `(x, ν)` for a fixture QP, from its data: stationarity
/// `Px + q + Σ J_kᵀ ν_k`, feasibility, and the natural complementarity
/// `|c - proj_C(c + ν)|` of every block.
fn qp_kkt_residual(case: &Value, x: &[f64], nu: &[f64]) -> f64 {
    let (p, q) = (mat_of(&case["P"]), vec_of(&case["q"]));
    let n = q.len();
    let mut g: Vec<f64> = (0..n)
        .map(|i| q[i] + (0..n).map(|j| p[(i, j)] * x[j]).sum::<f64>())
        .collect();
    let mut res: f64 = 0.0;
    let mut off = 0;
    for b in case["blocks"].as_array().unwrap() {
        let (a, rhs) = (mat_of(&b["A"]), vec_of(&b["b"]));
        let m = a.nrows();
        let ax: Vec<f64> = (0..m).map(|i| (0..n).map(|j| a[(i, j)] * x[j]).sum()).collect();
        let v = &nu[off..off + m];
        let kind = b["kind"].as_str().unwrap();
        // c and dc/dx = sign · A.
        let (c, sign): (Vec<f64>, f64) = match kind {
            "eq" | "le" => ((0..m).map(|i| ax[i] - rhs[i]).collect(), 1.0),
            "box" => (ax.clone(), 1.0),
            _ => ((0..m).map(|i| rhs[i] - ax[i]).collect(), -1.0),
        };
        for (j, gj) in g.iter_mut().enumerate() {
            *gj += sign * (0..m).map(|i| a[(i, j)] * v[i]).sum::<f64>();
        }
        let w: Vec<f64> = (0..m).map(|i| c[i] + v[i]).collect();
        let proj: Vec<f64> = match kind {
            "eq" => vec![0.0; m],
            "le" => w.iter().map(|wi| wi.min(0.0)).collect(),
            "box" => (0..m).map(|i| w[i].clamp(rhs[i], rhs[m + i])).collect(),
            _ => soc_projection(&w),
        };
        res = res.max(max_abs_diff(&c, &proj));
        off += m;
    }
    res.max(g.iter().fold(0.0, |a, v| a.max(v.abs())))
}

/// Equality + inequality, box and second-order-cone QPs: ProxNLP's optimum, value and
/// multipliers equal Clarabel's, and its KKT residuals recomputed from the data are at
/// round-off. On the cone, an interior-point solver measures complementarity by the
/// product `cᵀν`, which is second order in the misalignment of `c` and `ν` on the cone's
/// boundary: Clarabel's point (residuals 1e-12 by its measure) has a natural
/// complementarity residual of 2e-7 and lies 2e-7 from ProxNLP's (1e-12), so there the
/// comparison is to 1e-6 and the KKT residual decides.
#[test]
fn small_qps_match_clarabel_optimum_and_multipliers() {
    let cases = qp_cases();
    assert_eq!(cases.len(), 3);
    for case in &cases {
        let name = case["name"].as_str().unwrap();
        let nlp = qp_nlp(case);
        let mut solver = ProxNlp::new(tight());
        solver.setup(&nlp).unwrap();
        let x0 = vec![0.0; nlp.space().nx()];
        let sol = solver.solve(&nlp, &x0, None).unwrap();
        assert_eq!(sol.status, Status::Converged, "{name}: {:?}", sol.status);
        let tol = if name == "soc" { 1e-6 } else { 1e-8 };
        let x_ref = vec_of(&case["clarabel_x"]);
        let dx = max_abs_diff(&sol.x, &x_ref);
        assert!(dx < tol, "{name}: |x - x_clarabel| = {dx:e}");
        let obj = case["clarabel_obj"].as_f64().unwrap();
        assert!(
            (sol.cost - obj).abs() < 1e-10 * obj.abs().max(1.0),
            "{name}: {} vs {obj}",
            sol.cost
        );
        let nu_ref: Vec<f64> = case["blocks"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|b| vec_of(&b["clarabel_nu"]))
            .collect();
        let dnu = max_abs_diff(&sol.multipliers, &nu_ref);
        assert!(dnu < tol, "{name}: |nu - nu_clarabel| = {dnu:e}");
        let kkt = qp_kkt_residual(case, &sol.x, &sol.multipliers);
        assert!(kkt < 1e-10, "{name}: KKT residual {kkt:e}");
        // Some constraint is active (the test is not an unconstrained one in disguise).
        assert!(nu_ref.iter().any(|v| v.abs() > 1e-3), "{name}: no active constraint");
    }
}

/// Central finite differences of `δ ↦ g(x ⊕ δ)` on `space`.
fn fd_gradient(space: &dyn Manifold, x: &[f64], g: &dyn Fn(&[f64]) -> f64) -> Vec<f64> {
    let h = 1e-6;
    let mut xp = vec![0.0; x.len()];
    (0..space.ndx())
        .map(|j| {
            let mut v = vec![0.0; space.ndx()];
            v[j] = h;
            space.integrate(x, &v, &mut xp);
            let gp = g(&xp);
            v[j] = -h;
            space.integrate(x, &v, &mut xp);
            (gp - g(&xp)) / (2.0 * h)
        })
        .collect()
}

/// On SO(3): turn the body z axis towards `a` (tilted by γ) with the tilt limited to
/// β < γ. Optimum: the axis tilted by β towards `a`, cost `-cos(γ - β)`, multiplier
/// `sin(γ - β) / sin β`; and the Lagrangian's tangent gradient by finite differences
/// vanishes there. The rotation about the body axis is free: the reduced Hessian is
/// singular and the inertia correction keeps the steps defined.
#[test]
fn tilt_limited_alignment_on_so3_reaches_the_analytical_optimum() {
    let (gamma, beta, phi) = TILT_ANGLES;
    let (nlp, cost, tilt) = tilt_problem();
    let space = nlp.space();
    let x0 = tilt_start();
    // The exact Hessian: the constraint's curvature makes the Lagrangian's Hessian
    // positive on the tangent of the constraint (the Gauss-Newton one is indefinite there
    // and needs a large primal regularisation, which leaves a linear rate).
    {
        let hessian = HessianApprox::Exact;
        let mut solver = ProxNlp::new(ProxNlpOptions::default().with(|o| {
            o.tol = 1e-10;
            o.hessian = hessian;
        }));
        solver.setup(&nlp).unwrap();
        let sol = solver.solve(&nlp, &x0, None).unwrap().clone();
        assert_eq!(sol.status, Status::Converged, "{hessian:?}");
        let b = body_z(&sol.x);
        let b_star = [beta.sin() * phi.cos(), beta.sin() * phi.sin(), beta.cos()];
        assert!(
            max_abs_diff(&b, &b_star) < 1e-8,
            "{hessian:?}: axis {b:?} vs {b_star:?}"
        );
        assert!(
            (sol.cost + (gamma - beta).cos()).abs() < 1e-9,
            "{hessian:?}: cost {}",
            sol.cost
        );
        let nu_star = (gamma - beta).sin() / beta.sin();
        assert!(
            (sol.multipliers[0] - nu_star).abs() < 1e-7,
            "{hessian:?}: ν {:?}",
            sol.multipliers
        );
        // Finite-difference KKT: ∇(f + ν c)(x ⊕ δ) = 0 at δ = 0.
        let nu = sol.multipliers[0];
        let lagrangian = |q: &[f64]| {
            let mut cd = gharial::costs::Cost::create_data(&*cost);
            gharial::costs::Cost::evaluate(&*cost, q, &[], &mut cd);
            let mut fd = gharial::functions::StageFunctionData::new(3, 0, 1, tilt.create_workspace());
            tilt.evaluate(q, &mut fd);
            cd.value + nu * fd.value[0]
        };
        let g = fd_gradient(space, &sol.x, &lagrangian);
        assert!(
            g.iter().all(|v| v.abs() < 1e-7),
            "{hessian:?}: FD Lagrangian gradient {g:?}"
        );
    }
}

/// The point of the unit sphere closest to `a` below the plane `x_3 = h`: on the circle
/// `x_3 = h`, `x_12 = r a_12 / |a_12|` (`r = √(1 - h²)`), with multipliers
/// `ν_sphere = (|a_12| / r - 1) / 2` and `ν_plane = a_3 - h |a_12| / r`.
#[test]
fn closest_point_on_a_capped_sphere_matches_the_analytical_kkt_point() {
    let a = [0.6, -0.9, 1.5];
    let h = 0.2;
    let nlp = capped_sphere(a, h);
    let r = (1.0 - h * h).sqrt();
    let a12 = (a[0] * a[0] + a[1] * a[1]).sqrt();
    let x_star = [r * a[0] / a12, r * a[1] / a12, h];
    let nu_star = [(a12 / r - 1.0) / 2.0, a[2] - h * a12 / r];
    for hessian in [HessianApprox::GaussNewton, HessianApprox::Exact] {
        let mut solver = ProxNlp::new(tight().with(|o| o.hessian = hessian));
        solver.setup(&nlp).unwrap();
        let sol = solver.solve(&nlp, &[0.3, 0.3, -0.5], None).unwrap();
        assert_eq!(sol.status, Status::Converged, "{hessian:?}");
        assert!(max_abs_diff(&sol.x, &x_star) < 1e-9, "{hessian:?}: {:?}", sol.x);
        assert!(
            max_abs_diff(&sol.multipliers, &nu_star) < 1e-8,
            "{hessian:?}: {:?}",
            sol.multipliers
        );
    }
}

/// ProxNLP on the whole optimal control problem and ProxDDP reach the same optimum (states,
/// controls, cost, co-states) on random LQ problems: unconstrained, with control bounds,
/// with a terminal equality, and with implicit dynamics.
#[test]
fn proxnlp_on_lq_ocps_equals_proxddp() {
    let lq = random_lq(3, 2, 8, 31);
    let target = reachable_target(&lq, 0.3);
    let (implicit, _) = implicit_euler_ocp(&lq, 0.1);
    let problems = [
        ("plain", ocp(&lq, None, None)),
        ("bounds", ocp(&lq, Some(0.3), None)),
        ("bounds-terminal", ocp(&lq, Some(0.3), Some(&target))),
        ("implicit", implicit),
    ];
    for (name, p) in problems {
        let (xs, us) = zero_guess(&p);
        let mut ddp = ProxDdp::new(ProxDdpOptions::default().with(|o| o.tol = 1e-11));
        ddp.setup(&p).unwrap();
        let a = ddp.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
        assert!(a.status.converged(), "{name}: proxddp {}", a.status);
        let mut nlp = ProxNlpOcp::new(tight());
        Solver::setup(&mut nlp, &p).unwrap();
        let b = nlp.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        assert!(b.status.converged(), "{name}: proxnlp {}", b.status);
        let dx =
            a.xs.iter()
                .zip(&b.xs)
                .map(|(u, v)| max_abs_diff(u, v))
                .fold(0.0, f64::max);
        let du =
            a.us.iter()
                .zip(&b.us)
                .map(|(u, v)| max_abs_diff(u, v))
                .fold(0.0, f64::max);
        let dl = a
            .lambdas
            .iter()
            .zip(&b.lambdas)
            .map(|(u, v)| max_abs_diff(u, v))
            .fold(0.0, f64::max);
        assert!(dx < 1e-8 && du < 1e-8, "{name}: |Δx| {dx:e}, |Δu| {du:e}");
        assert!(
            (a.cost - b.cost).abs() < 1e-8 * a.cost.abs().max(1.0),
            "{name}: {} vs {}",
            a.cost,
            b.cost
        );
        assert!(dl < 1e-6, "{name}: |Δλ| {dl:e}");
    }
}

/// The box-constrained LQ fixtures: ProxNLP's cost equals Clarabel's.
#[test]
fn proxnlp_on_box_lq_fixtures_matches_clarabel_cost() {
    for case in qp_reference_cases().iter().filter(|c| c.lq.n <= 20) {
        let p = ocp(&case.lq, Some(case.umax), case.target.as_deref());
        let (xs, us) = zero_guess(&p);
        let mut nlp = ProxNlpOcp::new(tight());
        Solver::setup(&mut nlp, &p).unwrap();
        let sol = nlp.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        assert!(sol.status.converged(), "seed {}: {}", case.seed, sol.status);
        let rel = (sol.cost - case.clarabel_cost).abs() / case.clarabel_cost.abs().max(1.0);
        assert!(rel < 1e-8, "seed {}: {} vs {}", case.seed, sol.cost, case.clarabel_cost);
    }
}

#[test]
fn bad_input_gets_clear_errors_and_statuses() {
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let cost = Arc::new(QuadraticCost::terminal(Mat::<f64>::identity(2, 2).as_ref(), &[1.0, -1.0]).unwrap());
    // A constraint of another dimension, and a set of another dimension.
    let f3 = Arc::new(LinearUnaryFunction::new(Mat::<f64>::identity(3, 3).as_ref(), &[0.0; 3]).unwrap());
    let e = NlpProblem::new(space.clone(), cost.clone())
        .unwrap()
        .with_constraint(NlpConstraint::new("wide", f3, Arc::new(NegativeOrthant)))
        .unwrap_err();
    assert!(
        matches!(e, Error::Dimension { .. }) && e.to_string().contains("wide"),
        "{e}"
    );
    let f2 = Arc::new(LinearUnaryFunction::new(Mat::<f64>::identity(2, 2).as_ref(), &[0.0; 2]).unwrap());
    let e = NlpProblem::new(space.clone(), cost.clone())
        .unwrap()
        .with_constraint(NlpConstraint::new(
            "cone",
            f2.clone(),
            Arc::new(SecondOrderCone::new(3).unwrap()),
        ))
        .unwrap_err();
    assert!(e.to_string().contains("cone"), "{e}");
    // A cost with controls is not a cost of the variable.
    let staged = Arc::new(
        QuadraticCost::new(
            Mat::<f64>::identity(2, 2).as_ref(),
            Mat::zeros(2, 1).as_ref(),
            Mat::<f64>::identity(1, 1).as_ref(),
            &[0.0; 2],
            &[0.0],
        )
        .unwrap(),
    );
    assert!(NlpProblem::new(space.clone(), staged).is_err());
    // Solve before setup, wrong sizes, non-finite values, invalid options.
    let nlp = NlpProblem::new(space.clone(), cost.clone()).unwrap();
    let mut solver = ProxNlp::new(ProxNlpOptions::default());
    assert!(solver.solve(&nlp, &[0.0, 0.0], None).is_err());
    solver.setup(&nlp).unwrap();
    assert!(matches!(solver.solve(&nlp, &[0.0], None), Err(Error::Dimension { .. })));
    assert!(matches!(
        solver.solve(&nlp, &[0.0, f64::NAN], None),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        solver.solve(&nlp, &[0.0, 0.0], Some(&[1.0])),
        Err(Error::Dimension { .. })
    ));
    let mut bad = ProxNlp::new(ProxNlpOptions::default().with(|o| o.mu_init = -1.0));
    assert!(matches!(bad.setup(&nlp), Err(Error::InvalidOption { .. })));
    // A point that is not on the manifold.
    let so3: Arc<dyn Manifold> = Arc::new(SO3::new());
    let c3 = Arc::new(AutoDiff::cost(so3.clone(), Alignment { a: [0.0, 0.0, 1.0] }).unwrap());
    let rot = NlpProblem::new(so3, c3).unwrap();
    let mut s3 = ProxNlp::new(ProxNlpOptions::default());
    s3.setup(&rot).unwrap();
    assert!(s3.solve(&rot, &[1.0, 1.0, 0.0, 0.0], None).is_err());
    // Infeasible constraints: x_0 >= 1 and x_0 <= 0.
    let row = Mat::from_fn(1, 2, |_, j| f64::from(u8::from(j == 0)));
    let minus_row = Mat::from_fn(1, 2, |_, j| -f64::from(u8::from(j == 0)));
    let infeasible = NlpProblem::new(space.clone(), cost.clone())
        .unwrap()
        .with_constraint(NlpConstraint::new(
            "x0 <= 0",
            Arc::new(LinearUnaryFunction::new(row.as_ref(), &[0.0]).unwrap()),
            Arc::new(NegativeOrthant),
        ))
        .unwrap()
        .with_constraint(NlpConstraint::new(
            "x0 >= 1",
            Arc::new(LinearUnaryFunction::new(minus_row.as_ref(), &[1.0]).unwrap()),
            Arc::new(NegativeOrthant),
        ))
        .unwrap();
    let mut s = ProxNlp::new(ProxNlpOptions::default());
    s.setup(&infeasible).unwrap();
    let sol = s.solve(&infeasible, &[0.0, 0.0], None).unwrap();
    assert_eq!(sol.status, Status::Infeasible, "{:?}", sol.status);
    assert!(sol.prim_err > 0.4, "{}", sol.prim_err);
    // A cost that is not finite at the start: the status says so and nothing panics.
    let sqrt_cost = Arc::new(AutoDiff::cost(space.clone(), SqrtCost).unwrap());
    let nan = NlpProblem::new(space.clone(), sqrt_cost).unwrap();
    let mut s = ProxNlp::new(ProxNlpOptions::default());
    s.setup(&nan).unwrap();
    assert_eq!(s.solve(&nan, &[-1.0, 0.0], None).unwrap().status, Status::NonFinite);
    // The OCP solver: solve before setup, another problem's dimensions, receding horizons.
    let lq = random_lq(2, 1, 4, 3);
    let p = ocp(&lq, None, None);
    let (xs, us) = zero_guess(&p);
    let mut o = ProxNlpOcp::new(ProxNlpOptions::default());
    assert!(o.solve(&p, InitialGuess::primal(&xs, &us)).is_err());
    Solver::setup(&mut o, &p).unwrap();
    let other = ocp(&random_lq(2, 1, 5, 3), None, None);
    let (xs5, us5) = zero_guess(&other);
    assert!(o.solve(&other, InitialGuess::primal(&xs5, &us5)).is_err());
    assert!(o.setup_receding(&p, &[]).unwrap_err().to_string().contains("receding"));
    // A problem too large for the dense system is refused before anything is allocated
    // when the dense solve is asked for; the default solves it sparsely.
    let long = ocp(&random_lq(2, 1, 1000, 3), None, None);
    let mut dense = ProxNlpOcp::new(ProxNlpOptions::default().with(|o| o.kkt = KktSolver::Dense));
    let e = Solver::setup(&mut dense, &long).unwrap_err().to_string();
    assert!(e.contains("5004 rows") && e.contains("proxddp"), "{e}");
    Solver::setup(&mut o, &long).unwrap();
    assert!(o.kkt_stats().is_some_and(|k| k.sparse && k.dim == 5004));
}

/// `√x_0 + x_1²`: not finite for `x_0 < 0`.
struct SqrtCost;

impl AutoCostFn for SqrtCost {
    fn nx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        0
    }
    fn eval<D: ManifoldScalar>(&self, x: &[D], _u: &[D]) -> D {
        x[0].sqrt() + x[1] * x[1]
    }
}

/// Stops after `n` iterations.
struct StopAfter(usize);

impl gharial::solvers::Callback for StopAfter {
    fn on_iteration(&mut self, record: &gharial::solvers::IterationRecord) -> bool {
        record.iter + 1 < self.0
    }
}

/// A callback stops the solve with the last accepted iterate; the solution warm-starts a
/// new solve, which converges at once; the iteration table goes to the chosen sink.
#[test]
fn callbacks_warm_starts_and_the_log() {
    let lq = random_lq(3, 2, 8, 7);
    let p = ocp(&lq, Some(0.3), None);
    let (xs, us) = zero_guess(&p);
    let lines = Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let sink = lines.clone();
    let log = gharial::solvers::log::LogSink::Function(Arc::new(move |l| sink.lock().unwrap().push(l.to_string())));
    let mut solver = ProxNlpOcp::new(tight().with(|o| o.log = log));
    Solver::setup(&mut solver, &p).unwrap();
    let full = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap().clone();
    assert!(
        full.status.converged() && full.iterations > 2,
        "{} {}",
        full.status,
        full.iterations
    );
    assert_eq!(full.history.len(), full.iterations);
    let logged = lines.lock().unwrap().clone();
    assert!(
        logged[0].contains("inner_crit") && logged.len() > full.iterations,
        "{logged:?}"
    );
    let stopped = solver
        .solve_with_callback(&p, InitialGuess::primal(&xs, &us), &mut StopAfter(2))
        .unwrap()
        .clone();
    assert_eq!((stopped.status, stopped.iterations), (Status::Interrupted, 2));
    let warm = solver.solve(&p, InitialGuess::from_solution(&full)).unwrap();
    assert!(
        warm.status.converged() && warm.iterations <= 1,
        "{} {}",
        warm.status,
        warm.iterations
    );
    let dx = full
        .xs
        .iter()
        .zip(&warm.xs)
        .map(|(a, b)| max_abs_diff(a, b))
        .fold(0.0, f64::max);
    assert!(dx < 1e-10, "{dx:e}");
}
