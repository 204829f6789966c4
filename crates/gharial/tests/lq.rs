//! The LQ solvers against the dense KKT reference, and their errors.
//!
//! # Error measure
//!
//! Per block, relative to the reference solution `w*` (the dense LU solve):
//! - primal: `max(|xs - xs*|_∞, |us - us*|_∞) / max(1, |xs*|_∞, |us*|_∞)`;
//! - multipliers: `max(|λ - λ*|_∞, |ν - ν*|_∞) / max(1, |λ*|_∞, |ν*|_∞)`.
//!
//! # Why some multiplier tolerances depend on mu
//!
//! When the constraint rows of the whole problem (initial constraint, dynamics, path
//! constraints) are linearly dependent — more constraint rows than controls at a knot,
//! constraints on the last state, rank-deficient `[C D]` — the KKT matrix has singular
//! values of the order of the smallest regularisation `mu`, along directions that only
//! involve multipliers. A backward-stable solver then computes those multiplier components
//! with an error of about `ε/mu` (`ε` the machine epsilon), whatever the algorithm: two
//! backward-stable solutions may differ by that much. For these problems the tests make the
//! constraints consistent (a random trajectory satisfies them, so the multipliers stay
//! bounded as mu → 0), require the primal parts to agree to 1e-9, the multipliers to agree
//! to `1e-9 + C ε/mu_min`, and the KKT residuals (the backward error) to be tiny. When the
//! constraint rows are independent (at most `nu_t` rows per knot, none on the last state,
//! full-rank blocks), the KKT matrix stays well conditioned as mu → 0 and everything must
//! agree to 1e-9.
//!
//! The Riccati recursion itself loses accuracy like `ε/mu` (its value function grows like
//! `1/mu` in constrained directions, as in every Riccati-based proximal solver), so the
//! comparisons to 1e-9 use iterative refinement (`refinement_steps`); the plain recursion
//! is checked against its own `ε/mu` bound.

use faer::Col;
use gharial::lq::dense::{self, KktResiduals, kkt_residuals};
use gharial::lq::random::{self, SplitMix64, VariedOptions};
use gharial::lq::{LqError, LqProblem, LqSolution, ParallelRiccatiSolver, RiccatiOptions, RiccatiSolver};

const EPS: f64 = f64::EPSILON;

/// Relative errors of a solution, per block (module docs).
#[derive(Debug, Clone, Copy, Default)]
struct RelErr {
    primal: f64,
    dual: f64,
}

fn max_abs(v: &[Col<f64>]) -> f64 {
    v.iter()
        .flat_map(|c| (0..c.nrows()).map(move |i| c[i].abs()))
        .fold(0.0, f64::max)
}

/// `max |a - b|_∞`, infinite if a NaN appears.
fn max_diff(a: &[Col<f64>], b: &[Col<f64>]) -> f64 {
    let mut m: f64 = 0.0;
    for (x, y) in a.iter().zip(b) {
        for i in 0..x.nrows() {
            let d = (x[i] - y[i]).abs();
            if d.is_nan() {
                return f64::INFINITY;
            }
            m = m.max(d);
        }
    }
    m
}

fn rel_err(sol: &LqSolution, reference: &LqSolution) -> RelErr {
    let ps = 1f64.max(max_abs(&reference.xs)).max(max_abs(&reference.us));
    let ds = 1f64.max(max_abs(&reference.lambdas)).max(max_abs(&reference.nus));
    RelErr {
        primal: max_diff(&sol.xs, &reference.xs).max(max_diff(&sol.us, &reference.us)) / ps,
        dual: max_diff(&sol.lambdas, &reference.lambdas).max(max_diff(&sol.nus, &reference.nus)) / ds,
    }
}

/// KKT residuals relative to the solution's size.
fn rel_residual(problem: &LqProblem, sol: &LqSolution) -> f64 {
    let r: KktResiduals = kkt_residuals(problem, sol).unwrap();
    let scale = [&sol.xs, &sol.us, &sol.lambdas, &sol.nus]
        .iter()
        .map(|v| max_abs(v))
        .fold(1.0, f64::max);
    r.max() / scale
}

fn riccati(problem: &LqProblem, refinement_steps: usize) -> LqSolution {
    let opts = RiccatiOptions {
        refinement_steps,
        ..Default::default()
    };
    let mut solver = RiccatiSolver::with_options(problem, opts).unwrap();
    let mut sol = LqSolution::new(problem);
    solver.backward(problem, 0.0).unwrap();
    solver.forward(problem, &mut sol).unwrap();
    sol
}

/// The solution of `changed` (the vectors of `p` changed) by a backward pass on `p` and a
/// re-solve of the vectors alone (`backward_vectors`).
fn resolved(p: &LqProblem, changed: &LqProblem, opts: RiccatiOptions) -> LqSolution {
    let mut solver = RiccatiSolver::with_options(p, opts).unwrap();
    let mut sol = LqSolution::new(p);
    solver.backward(p, 0.0).unwrap();
    solver.backward_vectors(changed).unwrap();
    solver.forward(changed, &mut sol).unwrap();
    sol
}

fn parallel(problem: &LqProblem, threads: usize, refinement_steps: usize) -> LqSolution {
    let mut solver = ParallelRiccatiSolver::new(problem, threads, refinement_steps).unwrap();
    let mut sol = LqSolution::new(problem);
    solver.backward(problem, 0.0).unwrap();
    solver.forward(problem, &mut sol).unwrap();
    sol
}

/// A random test problem and what the tolerances need to know about it.
struct Case {
    problem: LqProblem,
    /// Constraint rows linearly independent (module docs): multipliers well conditioned.
    independent_rows: bool,
    /// Smallest nonzero regularisation.
    mu_min: f64,
    label: String,
}

/// Dimension ranges `(nx, nu, nc, N)` of case `i`: long horizons with tiny dimensions,
/// wide knots over short horizons, and medium and small problems, so that the dense
/// reference stays below about 1700 unknowns.
type Range = (usize, usize);

fn size_class(i: usize) -> (Range, Range, Range, Range) {
    match i % 10 {
        0 => ((1, 2), (1, 2), (0, 2), (100, 200)),
        1 | 2 => ((20, 40), (1, 40), (0, 40), (1, 3)),
        3..=6 => ((1, 10), (1, 10), (0, 10), (2, 30)),
        _ => ((1, 6), (1, 6), (0, 8), (1, 12)),
    }
}

fn random_case(rng: &mut SplitMix64, i: usize) -> Case {
    let (nx, nu, nc, n) = size_class(i);
    let mu_lo = 10f64.powf(rng.uniform(-10.0, 0.0));
    let mu_hi = (mu_lo * 10f64.powf(rng.uniform(0.0, 2.0))).min(1.0);
    let mut opts = VariedOptions {
        horizon: rng.int(n.0, n.1),
        nx,
        nu,
        nc,
        vary_dims: rng.uniform(0.0, 1.0) < 0.4,
        general_e: rng.uniform(0.0, 1.0) < 0.3,
        e_block: if rng.uniform(0.0, 1.0) < 0.5 { 0 } else { rng.int(1, 6) },
        rank_deficient: rng.uniform(0.0, 1.0) < 0.25,
        consistent: rng.uniform(0.0, 1.0) < 0.5,
        mu_dyn: if rng.uniform(0.0, 1.0) < 0.5 {
            0.0
        } else {
            rng.log_uniform(1e-10, 1.0)
        },
        mu_c: (mu_lo, mu_hi),
        hard_rows: rng.uniform(0.0, 1.0) < 0.2,
        initial_rows: match rng.int(0, 4) {
            0 | 1 => None,
            2 => Some(0),
            _ => Some(rng.int(1, nx.1)),
        },
        mu0: if rng.uniform(0.0, 1.0) < 0.5 {
            0.0
        } else {
            rng.log_uniform(1e-10, 1.0)
        },
    };
    // Dependent rows with a small mu: consistent constraints (module docs).
    let may_depend = opts.rank_deficient || opts.nc.1 > opts.nu.0 || opts.nc.1 > 0;
    if may_depend && mu_lo < 1e-4 {
        opts.consistent = true;
    }
    let problem = random::varied_problem(rng, &opts);
    let last = problem.knots.len() - 1;
    let independent_rows =
        !opts.rank_deficient && problem.knots[last].nc == 0 && problem.knots[..last].iter().all(|k| k.nc <= k.nu);
    let mu_min = problem
        .knots
        .iter()
        .flat_map(|k| (0..k.nc).map(move |r| k.mu_c[r]).chain([k.mu_dyn]))
        .chain([problem.mu0])
        .filter(|&m| m > 0.0)
        .fold(1.0, f64::min);
    let label = format!(
        "case {i}: N={} dims={:?}..{:?} E={} (block {}) mu_dyn={:.0e} mu_c=[{:.0e},{:.0e}] rankdef={} hard={} init={:?} mu0={:.0e} consistent={}",
        opts.horizon,
        (opts.nx, opts.nu, opts.nc),
        opts.vary_dims,
        opts.general_e,
        opts.e_block,
        opts.mu_dyn,
        mu_lo,
        mu_hi,
        opts.rank_deficient,
        opts.hard_rows,
        opts.initial_rows,
        opts.mu0,
        opts.consistent
    );
    Case {
        problem,
        independent_rows,
        mu_min,
        label,
    }
}

#[test]
fn peers_generator_matches_reference_values() {
    // First values of the peers' README for 36:12:32, seed 42, bit for bit.
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

/// Riccati (with two refinement steps) against the dense KKT solve on 220 random problems:
/// nx, nu from 1 to 40, nc from 0 to 40 (rank-deficient blocks, rows without regularisation),
/// mu from 1e-10 to 1, N from 1 to 200, with and without an initial constraint, general `E`,
/// dimensions changing from knot to knot. Also the plain recursion against its `ε/mu` bound.
#[test]
fn riccati_matches_dense_kkt_on_random_problems() {
    let mut rng = SplitMix64::new(2024);
    // Worst measured values: refined primal, refined multipliers (independent rows),
    // refined multipliers / (ε/mu) (dependent rows), refined residual, plain primal /
    // (ε/mu), plain error with mu ≥ 1e-4.
    let mut worst = [0.0f64; 6];
    let mut covered = [false; 8];
    for i in 0..220 {
        let c = random_case(&mut rng, i);
        let p = &c.problem;
        let reference = dense::solve(p).unwrap();
        let refined = riccati(p, 2);
        let plain = riccati(p, 0);
        let er = rel_err(&refined, &reference);
        let ep = rel_err(&plain, &reference);
        let res = rel_residual(p, &refined);
        let e_mu = EPS / c.mu_min;
        assert!(er.primal <= 1e-9, "{}: primal {:e}", c.label, er.primal);
        if c.independent_rows {
            assert!(er.dual <= 1e-9, "{}: multipliers {:e}", c.label, er.dual);
            worst[1] = worst[1].max(er.dual);
        } else {
            assert!(er.dual <= 1e-9 + 1e3 * e_mu, "{}: multipliers {:e}", c.label, er.dual);
            worst[2] = worst[2].max(er.dual / e_mu);
        }
        assert!(res <= 1e-12, "{}: relative KKT residual {res:e}", c.label);
        assert!(
            ep.primal <= 1e-9 + 1e3 * e_mu,
            "{}: plain primal {:e}",
            c.label,
            ep.primal
        );
        if c.mu_min >= 1e-4 {
            assert!(ep.primal.max(ep.dual) <= 1e-9, "{}: plain {ep:?}", c.label);
            worst[5] = worst[5].max(ep.primal.max(ep.dual));
        }
        worst[0] = worst[0].max(er.primal);
        worst[3] = worst[3].max(res);
        worst[4] = worst[4].max(ep.primal / e_mu);
        // Coverage of the extremes the tests promise.
        let k = &p.knots;
        covered[0] |= k.iter().any(|k| k.nx >= 35);
        covered[1] |= k.iter().any(|k| k.nu >= 35);
        covered[2] |= k.iter().any(|k| k.nc >= 35);
        covered[3] |= k.len() > 150;
        covered[4] |= k.len() == 2;
        covered[5] |= c.mu_min < 1e-9;
        covered[6] |= p.nc0() == 0;
        covered[7] |= k.iter().any(|k| k.nx_next > 0 && k.E[(0, 0)] != -1.0);
    }
    println!(
        "worst over 220 problems: refined primal {:.1e}, refined multipliers (independent rows) {:.1e}, \
         refined multipliers (dependent rows) {:.1e} ε/mu, relative residual {:.1e}, plain primal {:.1e} ε/mu, \
         plain (mu ≥ 1e-4) {:.1e}",
        worst[0], worst[1], worst[2], worst[3], worst[4], worst[5]
    );
    assert!(covered.iter().all(|&c| c), "coverage {covered:?}");
}

/// The parallel solver equals the serial one on random problems (with refinement, as the
/// comparison with the dense reference), for 2 to 4 threads, and is deterministic.
#[test]
fn parallel_matches_serial() {
    let mut rng = SplitMix64::new(77);
    let mut worst: f64 = 0.0;
    for i in 0..60 {
        let c = random_case(&mut rng, i);
        let p = &c.problem;
        let serial = riccati(p, 2);
        let threads = 2 + i % 3;
        let par = parallel(p, threads, 2);
        let e = rel_err(&par, &serial);
        assert!(e.primal <= 1e-9, "{} threads {threads}: primal {:e}", c.label, e.primal);
        let tol = if c.independent_rows {
            1e-9
        } else {
            1e-9 + 1e3 * EPS / c.mu_min
        };
        assert!(e.dual <= tol, "{} threads {threads}: multipliers {:e}", c.label, e.dual);
        let res = rel_residual(p, &par);
        assert!(
            res <= 1e-12,
            "{}: residual {res:e} (serial {:e})",
            c.label,
            rel_residual(p, &serial)
        );
        if c.independent_rows {
            worst = worst.max(e.primal.max(e.dual));
        } else {
            worst = worst.max(e.primal);
        }
        // Without refinement: the serial recursion's bound on the primal part (the
        // multipliers are ill-determined by ε/mu, module docs).
        let plain_par = parallel(p, threads, 0);
        let plain = riccati(p, 0);
        let e = rel_err(&plain_par, &plain);
        assert!(
            e.primal <= 1e-9 + 1e3 * EPS / c.mu_min,
            "{} plain: primal {:e}",
            c.label,
            e.primal
        );
        if c.mu_min >= 1e-4 {
            assert!(e.dual <= 1e-9, "{} plain: multipliers {:e}", c.label, e.dual);
        }
        if i % 10 == 0 {
            // Deterministic: the same bits on a second solver and a second solve.
            let again = parallel(p, threads, 2);
            assert!(rel_err(&again, &par).primal == 0.0 && rel_err(&again, &par).dual == 0.0);
        }
    }
    println!("parallel vs serial, worst relative error: {worst:.1e}");
}

/// Long horizons with large knots (no dense reference: too big): tiny KKT residuals, and
/// the parallel solver equals the serial one.
#[test]
fn long_horizon_large_knots() {
    let mut rng = SplitMix64::new(9);
    for (nc, rank_deficient, general_e, mu_dyn) in [(10, false, false, 0.0), (40, true, true, 1e-6)] {
        let opts = VariedOptions {
            horizon: 200,
            nx: (40, 40),
            nu: (10, 10),
            nc: (nc, nc),
            rank_deficient,
            general_e,
            mu_dyn,
            mu_c: (1e-8, 1e-6),
            ..Default::default()
        };
        let p = random::varied_problem(&mut rng, &opts);
        let serial = riccati(&p, 1);
        assert!(rel_residual(&p, &serial) <= 1e-12);
        let par = parallel(&p, 2, 1);
        let e = rel_err(&par, &serial);
        assert!(e.primal <= 1e-9, "primal {:e}", e.primal);
        assert!(e.dual <= 1e-9 + 1e3 * EPS / 1e-8, "multipliers {:e}", e.dual);
    }
}

/// A small problem with every feature: general `E`, `mu_dyn`, hard rows, varying
/// dimensions, a partial initial constraint.
/// A varied problem with `E = -I` (`e = None`), a random `E` (`Some(0)`) or a random
/// leading `k × k` block of `E` (`Some(k)`).
fn feature_problem(seed: u64, e: Option<usize>, mu_dyn: f64) -> LqProblem {
    let mut rng = SplitMix64::new(seed);
    random::varied_problem(
        &mut rng,
        &VariedOptions {
            horizon: 8,
            nx: (2, 6),
            nu: (2, 4),
            nc: (0, 3),
            vary_dims: true,
            general_e: e.is_some(),
            e_block: e.unwrap_or(0),
            mu_dyn,
            mu_c: (1e-4, 1e-2),
            hard_rows: true,
            initial_rows: Some(2),
            mu0: 1e-5,
            ..Default::default()
        },
    )
}

fn mat_vec(m: faer::MatRef<'_, f64>, x: &Col<f64>) -> Vec<f64> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)] * x[j]).sum())
        .collect()
}

/// The exposed per-knot quantities are the right ones, checked on the dense solution: the
/// gains reproduce `u` and `ν`; the Q-function gives the stationarity in `u`; the value
/// function gives the co-state (`P x + p = -E_{t-1}ᵀ λ_t`); the rollout gains (50b-c) give
/// `x_{t+1}` and `λ_{t+1}`.
#[test]
fn exposed_gains_and_value_functions_match_the_dense_solution() {
    let cases = [
        (1, None, 0.0),
        (2, Some(0), 0.0),
        (3, None, 1e-2),
        (4, Some(0), 1e-3),
        (5, Some(2), 1e-2),
    ];
    for (seed, e, mu_dyn) in cases {
        let p = feature_problem(seed, e, mu_dyn);
        let w = dense::solve(&p).unwrap();
        let opts = RiccatiOptions {
            rollout_gains: true,
            refinement_steps: 0,
        };
        let mut solver = RiccatiSolver::with_options(&p, opts).unwrap();
        solver.backward(&p, 0.0).unwrap();
        let n = p.knots.len();
        let scale = 1f64.max(max_abs(&w.xs)).max(max_abs(&w.lambdas)).max(max_abs(&w.nus));
        let tol = 1e-10 * scale;
        for t in 0..n {
            let (k, st) = (&p.knots[t], solver.stage(t));
            let x = &w.xs[t];
            let kx = mat_vec(st.K(), x);
            let zx = mat_vec(st.Z(), x);
            for i in 0..k.nu {
                assert!((st.k()[i] + kx[i] - w.us[t][i]).abs() <= tol, "knot {t}: u = k + K x");
            }
            for i in 0..k.nc {
                assert!(
                    (st.zeta()[i] + zx[i] - w.nus[t][i]).abs() <= 1e2 * tol,
                    "knot {t}: ν = ζ + Z x"
                );
            }
            // Q_u + Q_uu u + Q_ux x + Dᵀν = 0.
            let quu_u = mat_vec(st.Q_uu(), &w.us[t]);
            let qux_x = mat_vec(st.Q_xu().transpose(), x);
            let dt_nu = mat_vec(k.D.transpose(), &w.nus[t]);
            for i in 0..k.nu {
                let v = st.Q_u()[i] + quu_u[i] + qux_x[i] + dt_nu[i];
                assert!(v.abs() <= tol, "knot {t}: stationarity of the Q-function {v:e}");
            }
            if t > 0 {
                let px = mat_vec(st.P(), x);
                let et_l = mat_vec(p.knots[t - 1].E.transpose(), &w.lambdas[t]);
                for i in 0..k.nx {
                    let vx = st.p()[i] + px[i];
                    assert!(
                        (vx + et_l[i]).abs() <= tol,
                        "knot {t}: value gradient {vx} vs {}",
                        -et_l[i]
                    );
                }
            }
            if t + 1 < n {
                let (c, cm) = st.x_next_gains().unwrap();
                let (xi, xim) = st.lambda_next_gains().unwrap();
                let (cx, xix) = (mat_vec(cm, x), mat_vec(xim, x));
                for i in 0..k.nx_next {
                    assert!(
                        (c[i] + cx[i] - w.xs[t + 1][i]).abs() <= tol,
                        "knot {t}: x_next = c + C x"
                    );
                    assert!(
                        (xi[i] + xix[i] - w.lambdas[t + 1][i]).abs() <= tol,
                        "knot {t}: λ_next = ξ + Ξ x"
                    );
                }
            }
        }
        assert!(RiccatiSolver::new(&p).unwrap().stage(0).x_next_gains().is_none());
    }
}

/// `backward_vectors` after a change of `q, r, f, d, g0` equals a full solve of the changed
/// problem (serial and parallel).
#[test]
fn backward_vectors_resolves_new_vectors() {
    let p = feature_problem(5, Some(4), 1e-3);
    let mut changed = p.clone();
    let mut rng = SplitMix64::new(6);
    for k in &mut changed.knots {
        for v in [&mut k.q, &mut k.r, &mut k.f, &mut k.d] {
            for i in 0..v.nrows() {
                v[i] += rng.uniform(-1.0, 1.0);
            }
        }
    }
    for i in 0..changed.g0.nrows() {
        changed.g0[i] += rng.uniform(-1.0, 1.0);
    }
    let reference = dense::solve(&changed).unwrap();
    let opts = RiccatiOptions {
        rollout_gains: false,
        refinement_steps: 1,
    };
    let mut solver = RiccatiSolver::with_options(&p, opts).unwrap();
    let mut sol = LqSolution::new(&p);
    solver.backward(&p, 0.0).unwrap();
    solver.forward(&p, &mut sol).unwrap();
    solver.backward_vectors(&changed).unwrap();
    solver.forward(&changed, &mut sol).unwrap();
    let e = rel_err(&sol, &reference);
    assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "serial {e:?}");
    let mut par = ParallelRiccatiSolver::new(&p, 3, 1).unwrap();
    par.backward(&p, 0.0).unwrap();
    par.forward(&p, &mut sol).unwrap();
    par.backward_vectors(&changed).unwrap();
    par.forward(&changed, &mut sol).unwrap();
    let e = rel_err(&sol, &reference);
    assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "parallel {e:?}");
}

/// Knots whose constraints act on the controls alone (`C = 0`, products with it skipped)
/// mixed with general knots: serial and parallel solutions, also after new vectors, agree
/// with the dense KKT solve.
#[test]
fn control_only_constraints_match_the_dense_solution() {
    for (seed, e) in [(11, None), (12, Some(0)), (13, Some(3))] {
        let mut p = feature_problem(seed, e, 1e-3);
        for k in p.knots.iter_mut().step_by(2) {
            k.C = faer::Mat::zeros(k.nc, k.nx);
        }
        assert!(p.knots.iter().any(|k| k.nc > 0 && k.C.norm_max() == 0.0));
        let reference = dense::solve(&p).unwrap();
        let e = rel_err(&riccati(&p, 1), &reference);
        assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "serial {e:?}");
        let e = rel_err(&parallel(&p, 3, 1), &reference);
        assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "parallel {e:?}");
        let mut changed = p.clone();
        let mut rng = SplitMix64::new(seed + 100);
        for k in &mut changed.knots {
            for i in 0..k.d.nrows() {
                k.d[i] += rng.uniform(-1.0, 1.0);
            }
            for i in 0..k.q.nrows() {
                k.q[i] += rng.uniform(-1.0, 1.0);
            }
        }
        let reference = dense::solve(&changed).unwrap();
        let opts = RiccatiOptions {
            rollout_gains: false,
            refinement_steps: 1,
        };
        let e = rel_err(&resolved(&p, &changed, opts), &reference);
        assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "new vectors {e:?}");
    }
}

/// Constraint rows that do not depend on the control (`D` row zero: obstacles, state
/// bounds), mixed with rows that do, leave the stage factorization (their multipliers are
/// their right-hand side over `-mu_c`): serial and parallel solves and re-solves with new
/// vectors equal the dense KKT solution; with `mu_c = 0` on one row (Bunch-Kaufman) too,
/// and with every row of `D` zero (the controls' rows alone in the factorization).
#[test]
fn state_only_constraint_rows_match_the_dense_solution() {
    for (seed, e, hard, every) in [
        (21, None, false, 2),
        (22, Some(0), false, 2),
        (23, Some(3), false, 2),
        (24, None, true, 2),
        (25, None, false, 1),
        (26, Some(2), false, 1),
    ] {
        let mut p = feature_problem(seed, e, 1e-3);
        for k in &mut p.knots {
            // (A row with `D = 0` and `mu_c = 0` would make the stage system singular.)
            for i in (0..k.nc).step_by(every).filter(|&i| k.mu_c[i] > 0.0) {
                for j in 0..k.nu {
                    k.D[(i, j)] = 0.0;
                }
            }
            if hard && k.nc > 1 {
                k.mu_c[1] = 0.0;
            }
        }
        assert!(p.knots.iter().any(|k| k.nu > 0 && k.nc > 1));
        let reference = dense::solve(&p).unwrap();
        let e = rel_err(&riccati(&p, 1), &reference);
        assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "seed {seed}: serial {e:?}");
        let e = rel_err(&parallel(&p, 3, 1), &reference);
        assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "seed {seed}: parallel {e:?}");
        let mut changed = p.clone();
        let mut rng = SplitMix64::new(seed + 100);
        for k in &mut changed.knots {
            for i in 0..k.d.nrows() {
                k.d[i] += rng.uniform(-1.0, 1.0);
            }
        }
        let reference = dense::solve(&changed).unwrap();
        let e = rel_err(&resolved(&p, &changed, RiccatiOptions::default()), &reference);
        assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "seed {seed}: new vectors {e:?}");
    }
}

/// `backward_with` and `value_from_gains`: plugging the unconstrained LQR gains
/// `k = -Q_uu⁻¹Q_u`, `K = -Q_uu⁻¹Q_ux` (computed here by an LU solve of each `Q_uu`) into
/// the sweep gives the dense solution of an unconstrained problem; the built-in stage solve
/// used as the law gives the backward pass's solution.
#[test]
fn custom_gains_through_backward_with() {
    use gharial::linalg::Lu;
    let mut rng = SplitMix64::new(8);
    let p = random::varied_problem(
        &mut rng,
        &VariedOptions {
            horizon: 12,
            nx: (3, 5),
            nu: (1, 3),
            nc: (0, 0),
            vary_dims: true,
            ..Default::default()
        },
    );
    let reference = dense::solve(&p).unwrap();
    let mut solver = RiccatiSolver::new(&p).unwrap();
    solver
        .backward_with(&p, |_, st, _| {
            let (nx, nu, _, _) = st.dims();
            let mut lu = Lu::new(nu, 1 + nx);
            lu.factor(st.Q_uu()).unwrap();
            let mut g = faer::Mat::from_fn(
                nu,
                1 + nx,
                |i, j| {
                    if j == 0 { -st.Q_u()[i] } else { -st.Q_xu()[(j - 1, i)] }
                },
            );
            lu.solve_in_place(g.as_mut());
            let k: Vec<f64> = (0..nu).map(|i| g[(i, 0)]).collect();
            st.value_from_gains(&k, g.as_ref().subcols(1, nx))
        })
        .unwrap();
    let mut sol = LqSolution::new(&p);
    solver.forward(&p, &mut sol).unwrap();
    let e = rel_err(&sol, &reference);
    assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "{e:?}");

    let p = feature_problem(9, Some(0), 1e-2);
    let reference = dense::solve(&p).unwrap();
    let mut other = RiccatiSolver::new(&p).unwrap();
    other
        .backward_with(&p, |knot, st, next| {
            st.solve_kkt(knot, next.map(|n| n.0), 0.0)?;
            st.solve_kkt_vectors(knot, next)
        })
        .unwrap();
    let mut sol2 = LqSolution::new(&p);
    other.forward(&p, &mut sol2).unwrap();
    let e = rel_err(&sol2, &reference);
    assert!(e.primal <= 1e-9 && e.dual <= 1e-9, "{e:?}");

    // Wrong gain shapes are reported, not a panic.
    let err = other
        .backward_with(&p, |_, st, _| {
            st.value_from_gains(&[1.0; 7], faer::Mat::<f64>::zeros(7, 7).as_ref())
        })
        .unwrap_err();
    assert!(
        matches!(
            err,
            LqError::Dimension {
                field: "feedforward gain k",
                ..
            }
        ),
        "{err:?}"
    );
}

/// Solves with the serial and the parallel solver; both must fail with the same error
/// (returns the serial one).
fn solve_error(p: &LqProblem, primal_reg: f64) -> LqError {
    let mut s = RiccatiSolver::new(p).unwrap();
    let mut sol = LqSolution::new(p);
    let e1 = s
        .backward(p, primal_reg)
        .and_then(|()| s.forward(p, &mut sol))
        .unwrap_err();
    let mut par = ParallelRiccatiSolver::new(p, 3, 0).unwrap();
    let e2 = par
        .backward(p, primal_reg)
        .and_then(|()| par.forward(p, &mut sol))
        .unwrap_err();
    // The same error, up to the inertia counted (computed from different matrices).
    let strip = |e: &LqError| match e {
        LqError::Inertia { knot, system, .. } => format!("inertia {knot} {system}"),
        e => format!("{e:?}"),
    };
    assert_eq!(strip(&e1), strip(&e2), "serial and parallel report different errors");
    e1
}

#[test]
fn wrong_dimensions_are_reported_with_knot_and_field() {
    use faer::Mat;
    let p = feature_problem(10, None, 0.0);
    let mut bad = p.clone();
    bad.knots[3].B = Mat::zeros(1, 1);
    let e = RiccatiSolver::new(&bad).unwrap_err();
    assert!(
        matches!(
            e,
            LqError::Dimension {
                knot: 3,
                field: "B",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(matches!(
        ParallelRiccatiSolver::new(&bad, 2, 0),
        Err(LqError::Dimension {
            knot: 3,
            field: "B",
            ..
        })
    ));
    assert!(matches!(
        dense::solve(&bad),
        Err(LqError::Dimension {
            knot: 3,
            field: "B",
            ..
        })
    ));

    // A chain that breaks: knot 2 announces a next state one larger than knot 3's.
    let mut bad = p.clone();
    let k = &mut bad.knots[2];
    let ny = k.nx_next + 1;
    *k = gharial::lq::LqKnot::new(k.nx, k.nu, k.nc, ny);
    let e = RiccatiSolver::new(&bad).unwrap_err();
    assert!(
        matches!(
            e,
            LqError::Dimension {
                knot: 2,
                field: "nx_next",
                ..
            }
        ),
        "{e:?}"
    );

    let mut bad = p.clone();
    bad.G0 = Mat::zeros(2, p.knots[0].nx + 1);
    assert!(matches!(
        RiccatiSolver::new(&bad),
        Err(LqError::Dimension {
            knot: 0,
            field: "G0",
            ..
        })
    ));
    assert!(matches!(
        RiccatiSolver::new(&LqProblem { knots: vec![], ..bad }),
        Err(LqError::Empty)
    ));

    // A solver used with another problem, or a solution of other dimensions.
    let mut solver = RiccatiSolver::new(&p).unwrap();
    let shorter = LqProblem {
        knots: p.knots[..5].to_vec(),
        ..p.clone()
    };
    let e = solver.backward(&shorter, 0.0).unwrap_err();
    assert!(
        matches!(
            e,
            LqError::Dimension {
                field: "number of knots",
                ..
            }
        ),
        "{e:?}"
    );
    let other = feature_problem(11, None, 0.0);
    if other.knots.len() == p.knots.len() {
        assert!(matches!(solver.backward(&other, 0.0), Err(LqError::Dimension { .. })));
    }
    solver.backward(&p, 0.0).unwrap();
    let mut wrong = LqSolution::new(&p);
    wrong.us[4] = Col::zeros(9);
    let e = solver.forward(&p, &mut wrong).unwrap_err();
    assert!(
        matches!(
            e,
            LqError::Dimension {
                knot: 4,
                field: "solution us",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(matches!(
        kkt_residuals(&p, &wrong),
        Err(LqError::Dimension { knot: 4, .. })
    ));
}

#[test]
fn non_finite_inputs_are_reported_with_knot_and_field() {
    let p = feature_problem(12, Some(0), 1e-3);
    type Poison = fn(&mut gharial::lq::LqKnot);
    let set: [(usize, &str, Poison); 8] = [
        (3, "q", |k| k.q[0] = f64::NAN),
        (2, "A", |k| k.A[(0, 0)] = f64::INFINITY),
        (5, "R", |k| k.R[(0, 0)] = f64::NAN),
        (4, "f", |k| k.f[0] = f64::NAN),
        (6, "E", |k| k.E[(1, 0)] = f64::NAN),
        (1, "S", |k| k.S[(0, 0)] = f64::NEG_INFINITY),
        (7, "r", |k| k.r[0] = f64::NAN),
        (0, "Q", |k| k.Q[(0, 0)] = f64::NAN),
    ];
    for (knot, field, f) in set {
        let mut bad = p.clone();
        f(&mut bad.knots[knot]);
        let e = solve_error(&bad, 0.0);
        assert_eq!(e, LqError::NonFinite { knot, field }, "{field}");
        assert_eq!(dense::solve(&bad).unwrap_err(), LqError::NonFinite { knot, field });
    }
    // Constraint data, at a knot that has constraint rows.
    let t = (0..p.knots.len())
        .find(|&t| p.knots[t].nc > 0 && p.knots[t].nu > 0)
        .unwrap();
    for field in ["C", "D", "d"] {
        let mut bad = p.clone();
        match field {
            "C" => bad.knots[t].C[(0, 0)] = f64::NAN,
            "D" => bad.knots[t].D[(0, 0)] = f64::NAN,
            _ => bad.knots[t].d[0] = f64::NAN,
        }
        assert_eq!(solve_error(&bad, 0.0), LqError::NonFinite { knot: t, field });
    }
    let mut bad = p.clone();
    bad.g0[0] = f64::NAN;
    assert_eq!(solve_error(&bad, 0.0), LqError::NonFinite { knot: 0, field: "g0" });
    let mut bad = p.clone();
    bad.knots[t].mu_c[0] = f64::INFINITY;
    assert_eq!(solve_error(&bad, 0.0), LqError::NonFinite { knot: t, field: "mu_c" });
    let mut bad = p.clone();
    bad.knots[2].mu_dyn = -1.0;
    assert_eq!(
        solve_error(&bad, 0.0),
        LqError::Negative {
            knot: 2,
            field: "mu_dyn"
        }
    );
    let mut bad = p.clone();
    bad.mu0 = -1e-3;
    assert_eq!(solve_error(&bad, 0.0), LqError::Negative { knot: 0, field: "mu0" });

    // backward_vectors sees new non-finite vectors too.
    let mut solver = RiccatiSolver::new(&p).unwrap();
    solver.backward(&p, 0.0).unwrap();
    let mut bad = p.clone();
    bad.knots[3].f[0] = f64::NAN;
    assert_eq!(
        solver.backward_vectors(&bad).unwrap_err(),
        LqError::NonFinite { knot: 3, field: "f" }
    );
}

#[test]
fn singular_and_indefinite_systems_are_reported() {
    use faer::Mat;
    let p = feature_problem(13, None, 0.0);
    // A singular E.
    let mut bad = p.clone();
    bad.knots[2].E = Mat::zeros(bad.knots[2].nx_next, bad.knots[2].nx_next);
    assert_eq!(
        solve_error(&bad, 0.0),
        LqError::Singular {
            knot: 2,
            system: "dynamics matrix E"
        }
    );
    // A negative definite R: wrong inertia, cured by the primal regularisation.
    let mut bad = p.clone();
    let nu = bad.knots[3].nu;
    bad.knots[3].R = Mat::from_fn(nu, nu, |i, j| if i == j { -50.0 } else { 0.0 });
    let e = solve_error(&bad, 0.0);
    assert!(
        matches!(
            e,
            LqError::Inertia {
                knot: 3,
                system: "stage KKT",
                ..
            }
        ),
        "{e:?}"
    );
    let mut solver = RiccatiSolver::new(&bad).unwrap();
    solver.backward(&bad, 100.0).unwrap();
    // More rows without regularisation than controls: a singular stage system.
    let mut bad = p.clone();
    let k = &mut bad.knots[1];
    let nc = k.nu + 1;
    *k = gharial::lq::LqKnot {
        nc,
        C: Mat::from_fn(nc, k.nx, |_, j| j as f64),
        D: Mat::from_fn(nc, k.nu, |i, j| ((i + 1) * (j + 2)) as f64 * 0.3),
        d: Col::zeros(nc),
        mu_c: Col::zeros(nc),
        ..k.clone()
    };
    let e = solve_error(&bad, 0.0);
    assert!(matches!(e, LqError::Inertia { knot: 1, .. }), "{e:?}");
    // A free x_0 whose value function is singular: no state cost anywhere.
    let mut bad = p.clone();
    bad.G0 = Mat::zeros(0, bad.knots[0].nx);
    bad.g0 = Col::zeros(0);
    for k in &mut bad.knots {
        k.Q = Mat::zeros(k.nx, k.nx);
        k.S = Mat::zeros(k.nx, k.nu);
        k.C = Mat::zeros(k.nc, k.nx);
    }
    let e = solve_error(&bad, 0.0);
    assert!(
        matches!(
            e,
            LqError::Inertia {
                knot: 0,
                system: "initial KKT",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(matches!(dense::solve(&bad), Err(LqError::Singular { .. })));
}

#[test]
fn invalid_calls_are_errors() {
    let p = feature_problem(14, None, 0.0);
    let mut solver = RiccatiSolver::new(&p).unwrap();
    let mut sol = LqSolution::new(&p);
    assert_eq!(solver.forward(&p, &mut sol).unwrap_err(), LqError::NotFactored);
    assert_eq!(solver.backward_vectors(&p).unwrap_err(), LqError::NotFactored);
    for reg in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            solver.backward(&p, reg),
            Err(LqError::Option { name: "primal_reg", .. })
        ));
    }
    // A failed backward pass leaves no factorization behind.
    solver.backward(&p, 0.0).unwrap();
    let mut bad = p.clone();
    bad.knots[2].q[0] = f64::NAN;
    assert!(solver.backward(&bad, 0.0).is_err());
    assert_eq!(solver.forward(&p, &mut sol).unwrap_err(), LqError::NotFactored);
    assert!(matches!(
        ParallelRiccatiSolver::new(&p, 0, 0),
        Err(LqError::Option {
            name: "num_threads",
            ..
        })
    ));
    // Errors convert into the library's error type with the same message.
    let e: gharial::Error = LqError::NonFinite { knot: 3, field: "q" }.into();
    assert!(e.to_string().contains("LQ knot 3: non-finite value in q"), "{e}");
}

#[test]
fn stage_methods_check_their_arguments() {
    let p = feature_problem(15, None, 0.0);
    let mut solver = RiccatiSolver::new(&p).unwrap();
    // A law that forgets the next value function, or passes another knot.
    let e = solver
        .backward_with(&p, |knot, st, _| st.solve_kkt(knot, None, 0.0))
        .unwrap_err();
    assert!(
        matches!(
            e,
            LqError::Dimension {
                field: "next value Hessian",
                ..
            }
        ),
        "{e:?}"
    );
    let other = p.knots[0].clone();
    let e = solver
        .backward_with(&p, |_, st, next| st.solve_kkt(&other, next.map(|n| n.0), 0.0))
        .unwrap_err();
    assert!(matches!(e, LqError::Dimension { .. }), "{e:?}");
}
