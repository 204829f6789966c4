//! The LQ solvers against the dense KKT reference.

use gharial::lq::dense::{self, kkt_residuals};
use gharial::lq::random::{self, SplitMix64, VariedOptions};
use gharial::lq::{LqProblem, LqSolution, RiccatiOptions, RiccatiSolver};

/// Relative errors of `sol` against `reference`, per block: primal (`xs`, `us`) relative
/// to `max(1, |primal_ref|_∞)`, multipliers (`lambdas`, `nus`) relative to
/// `max(1, |multipliers_ref|_∞)`.
#[derive(Debug, Clone, Copy, Default)]
struct RelErr {
    primal: f64,
    dual: f64,
}

fn max_abs(v: &[faer::Col<f64>]) -> f64 {
    v.iter()
        .flat_map(|c| (0..c.nrows()).map(move |i| c[i].abs()))
        .fold(0.0, f64::max)
}

fn max_diff(a: &[faer::Col<f64>], b: &[faer::Col<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..x.nrows()).map(move |i| (x[i] - y[i]).abs()))
        .fold(f64::NAN, |m, d| if m.is_nan() || d > m || d.is_nan() { d } else { m })
        .max(0.0)
}

fn rel_err(sol: &LqSolution, reference: &LqSolution) -> RelErr {
    let ps = 1f64.max(max_abs(&reference.xs)).max(max_abs(&reference.us));
    let ds = 1f64.max(max_abs(&reference.lambdas)).max(max_abs(&reference.nus));
    let nan_to_inf = |e: f64| if e.is_nan() { f64::INFINITY } else { e };
    RelErr {
        primal: nan_to_inf(max_diff(&sol.xs, &reference.xs).max(max_diff(&sol.us, &reference.us)) / ps),
        dual: nan_to_inf(max_diff(&sol.lambdas, &reference.lambdas).max(max_diff(&sol.nus, &reference.nus)) / ds),
    }
}

fn riccati(problem: &LqProblem) -> LqSolution {
    riccati_refined(problem, 0)
}

fn riccati_refined(problem: &LqProblem, steps: usize) -> LqSolution {
    let opts = RiccatiOptions {
        refinement_steps: steps,
        ..Default::default()
    };
    let mut solver = RiccatiSolver::with_options(problem, opts).unwrap();
    let mut sol = LqSolution::new(problem);
    solver.backward(problem, 0.0).unwrap();
    solver.forward(problem, &mut sol).unwrap();
    sol
}

#[test]
fn peers_generator_matches_reference_values() {
    let p = random::peers_problem(36, 12, 32, 16, 42, 1e-8).problem;
    let k0 = &p.knots[0];
    assert_eq!(k0.Q[(0, 0)], 0.4171836110624386);
    assert_eq!(k0.S[(0, 0)], -0.12329284195579082);
    assert_eq!(k0.R[(0, 0)], 0.45016807464217334);
    assert_eq!(k0.q[0], 0.8139165087098132);
    assert_eq!(k0.A[(0, 1)], 0.011679477544434148);
    assert_eq!(k0.B[(0, 0)], 0.9966348180753526);
    assert_eq!(k0.C[(0, 0)], -0.05677290087729152);
    assert_eq!(k0.D[(0, 0)], -0.09781392083136344);
    assert_eq!(k0.f[0], -0.660426603213496);
    assert_eq!(p.g0[0], 0.2862206020869711);
    assert_eq!(p.knots[16].Q[(0, 0)], 0.48381063756349896);
    assert_eq!(p.knots[16].d[0], -0.05514695433390363);
}

#[test]
fn riccati_matches_dense_smoke() {
    let mut rng = SplitMix64::new(7);
    for (i, opts) in [
        VariedOptions::default(),
        VariedOptions {
            general_e: true,
            mu_dyn: 1e-3,
            ..Default::default()
        },
        VariedOptions {
            vary_dims: true,
            nx: (1, 6),
            nu: (1, 4),
            nc: (0, 5),
            rank_deficient: true,
            hard_rows: true,
            initial_rows: Some(2),
            mu0: 1e-4,
            ..Default::default()
        },
    ]
    .iter()
    .enumerate()
    {
        let p = random::varied_problem(&mut rng, opts);
        let reference = dense::solve(&p).unwrap();
        let sol = riccati(&p);
        let e = rel_err(&sol, &reference);
        let r = kkt_residuals(&p, &sol);
        println!("case {i}: {e:?} {r:?} dense {:?}", kkt_residuals(&p, &reference));
        assert!(e.primal < 1e-9 && e.dual < 1e-9, "case {i}: {e:?}");
    }
}
