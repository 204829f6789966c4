//! The randomised families of `profiles`: reproducible from the seed, distinct
//! instances in the documented ranges, valid problems whose first instances the solvers
//! solve (KKT residuals recomputed independently of the solver), and clear errors.

use gharial::problem::kkt_residuals;
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver};
use gharial_problems::profiles::{FAMILIES, MAX_COUNT, family};
use gharial_problems::{Example, total_cost};

fn x0(ex: &Example) -> Vec<f64> {
    ex.problem.x0().expect("fixed initial state").to_vec()
}

/// What tells instances apart: the initial state and the cost of the guess (the
/// humanoid's instances differ by their goal only).
fn key(ex: &Example) -> (Vec<f64>, f64) {
    (x0(ex), total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap())
}

#[test]
fn instances_are_reproducible_from_the_seed_and_distinct() {
    for info in FAMILIES {
        let a = family(info.name, 7, 4).unwrap();
        let b = family(info.name, 7, 4).unwrap();
        let prefix = family(info.name, 7, 2).unwrap();
        let other = family(info.name, 8, 4).unwrap();
        assert_eq!(a.len(), 4);
        for i in 0..4 {
            assert_eq!(
                key(&a[i]),
                key(&b[i]),
                "{} instance {i} differs between two builds",
                info.name
            );
            assert_eq!(a[i].xs0, b[i].xs0);
            assert_eq!(a[i].us0, b[i].us0);
            assert_ne!(
                key(&a[i]),
                key(&other[i]),
                "{} instance {i}: seeds 7 and 8 agree",
                info.name
            );
            for j in 0..i {
                assert_ne!(key(&a[i]), key(&a[j]), "{} instances {j} and {i} coincide", info.name);
            }
        }
        for (p, q) in prefix.iter().zip(&a) {
            assert_eq!(key(p), key(q), "{}: a smaller count is not a prefix", info.name);
        }
    }
}

#[test]
fn initial_states_are_in_the_documented_ranges() {
    let pi = std::f64::consts::PI;
    for ex in family("reach", 3, 20).unwrap() {
        let x = x0(&ex);
        assert_eq!(x.len(), 12);
        assert!(x[..6].iter().all(|q| q.abs() <= pi), "{x:?}");
        assert!(x[6..].iter().all(|v| *v == 0.0), "{x:?}");
    }
    for ex in family("pendulum", 3, 20).unwrap() {
        let x = x0(&ex);
        assert!(x[0].abs() <= pi && x[1..] == [0.0; 3], "{x:?}");
        assert_eq!(ex.problem.nu(0), 1, "the paper's double pendulum has one actuator");
    }
    for ex in family("quadrotor", 3, 20).unwrap() {
        let x = x0(&ex);
        assert!(x[..3].iter().all(|p| p.abs() <= 1.0), "{x:?}");
        let norm: f64 = x[3..7].iter().map(|q| q * q).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() < 1e-12, "quaternion norm {norm}");
        assert!(x[7..].iter().all(|v| *v == 0.0), "{x:?}");
    }
    let x_neutral = x0(&family("humanoid", 3, 1).unwrap()[0]);
    for ex in family("humanoid", 3, 5).unwrap() {
        assert_eq!(x0(&ex), x_neutral, "the humanoid's goal is random, not its start");
        // At the guess only the foot terms cost: (N dt ½ + 100 · ½) |d|² for the goal
        // offset d, whose squared norm lies in [0.05², 0.2² + 0.1² + 0.2²].
        let n = ex.problem.horizon() as f64;
        let d2 = total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap() / (0.5 * n * ex.dt.unwrap() + 50.0);
        assert!(
            (0.05f64.powi(2) - 1e-12..=0.09 + 1e-12).contains(&d2),
            "goal offset² {d2}"
        );
    }
}

#[test]
fn instances_are_valid_problems_with_the_paper_warm_start() {
    for info in FAMILIES {
        for ex in family(info.name, 1, 3).unwrap() {
            ex.problem.check_trajectory(&ex.xs0, &ex.us0).unwrap();
            assert!(
                ex.xs0.iter().all(|x| *x == ex.xs0[0]),
                "{}: the state guess is x0",
                info.name
            );
            let cost = total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap();
            assert!(cost.is_finite() && cost > 0.0, "{}: initial cost {cost}", info.name);
        }
    }
}

/// Solves `ex` with SQP at tol 1e-4, then with ProxDDP if SQP did not converge.
fn solve(ex: &Example) -> Option<Solution> {
    let guess = || InitialGuess::primal(&ex.xs0, &ex.us0);
    let mut sqp = Ddp::new(DdpOptions::new(DdpVariant::Sqp).with(|o| {
        o.tol = 1e-4;
        o.max_iters = 200;
    }));
    sqp.setup(&ex.problem).unwrap();
    if sqp.solve(&ex.problem, guess()).unwrap().status.converged() {
        return Some(sqp.solution().clone());
    }
    let mut prox = ProxDdp::new(ex.proxddp.clone().with(|o| o.tol = 1e-4));
    prox.setup(&ex.problem).unwrap();
    let sol = prox.solve(&ex.problem, guess()).unwrap();
    sol.status.converged().then(|| sol.clone())
}

/// Some instances are hard (the point of the benchmark): of the first four of each
/// family at least two solve, and every solution passes the independent checks.
#[test]
fn the_first_instances_of_each_family_solve() {
    for info in FAMILIES {
        let mut solved = 0;
        for (i, ex) in family(info.name, 1, 4).unwrap().iter().enumerate() {
            let Some(sol) = solve(ex) else { continue };
            solved += 1;
            let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
            assert!(kkt.max() < 1e-3, "{} instance {i}: KKT {kkt:?}", info.name);
            let start = total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap();
            assert!(
                sol.cost < start,
                "{} instance {i}: cost {} from {start}",
                info.name,
                sol.cost
            );
            if info.name == "pendulum" {
                // Upright: both angles near 0 modulo 2π.
                let x = &sol.xs[ex.problem.horizon()];
                assert!(
                    x[0].cos() > 0.99 && x[1].cos() > 0.99,
                    "pendulum instance {i} ends at {x:?}"
                );
            }
        }
        assert!(solved >= 2, "{}: {solved} of the first 4 instances solved", info.name);
    }
}

#[test]
fn bad_names_and_counts_are_errors() {
    let e = family("taichi", 1, 3).unwrap_err().to_string();
    assert!(
        e.contains("taichi") && e.contains("reach, quadrotor, pendulum, humanoid"),
        "{e}"
    );
    let e = family("reach", 1, MAX_COUNT + 1).unwrap_err().to_string();
    assert!(e.contains(&MAX_COUNT.to_string()), "{e}");
    assert!(family("pendulum", 1, 0).unwrap().is_empty());
}

/// Checks the first instances of `name` (seed 1) against `refs`: the initial cost to
/// 1e-12 and the costs after one and two SQP steps to `step_tol` (relative).
fn assert_sqp_costs(name: &str, refs: &[(f64, f64, f64)], step_tol: f64) {
    for (i, (ex, r)) in family(name, 1, refs.len()).unwrap().iter().zip(refs).enumerate() {
        let start = total_cost(&ex.problem, &ex.xs0, &ex.us0).unwrap();
        assert!(
            (start - r.0).abs() <= 1e-12 * r.0,
            "{name} instance {i}: initial cost {start} vs {}",
            r.0
        );
        for (steps, cost) in [(1, r.1), (2, r.2)] {
            let mut sqp = Ddp::new(DdpOptions::new(DdpVariant::Sqp).with(|o| {
                o.tol = 1e-14;
                o.max_iters = steps;
            }));
            sqp.setup(&ex.problem).unwrap();
            let sol = sqp.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
            assert_eq!(sol.iterations, steps, "{name} instance {i}");
            assert!(
                (sol.cost - cost).abs() <= step_tol * cost,
                "{name} instance {i}: cost after {steps} steps {} vs {cost}",
                sol.cost
            );
        }
    }
}

/// SQP on the first two `quadrotor` instances (SE(3) × R⁶) against references outside
/// gharial (`bench/peers/fig1.py`, the instances rebuilt with crocoddyl 3.2.1):
/// - the initial cost (crocoddyl's cost models) and the first step, from the guess whose
///   gaps are only in the velocities: mim_solvers 0.3.0's SQP with `reg_min = 0`
///   (gharial's regularisation starts at 0), to 1e-9;
/// - the second step, from a point with gaps in the pose: a dense KKT solve of the LQ
///   subproblem with the gaps `fs = log(x₊⁻¹ f(x, u))` linearised in all their arguments,
///   `dx₊ = fs + Ad(exp fs)(F_x dx + F_u du)`, to 1e-9. mim_solvers leaves the transport
///   `Ad(exp fs)` out (`dx₊ = F_x dx + F_u du + fs`) and its second step differs
///   (0.26272 and 0.010052 instead); both reach the same optimum, in as many iterations
///   within a few (crates/gharial-problems/README.md, "Benchmark families").
#[test]
fn sqp_steps_on_the_quadrotor_match_mim_solvers_and_the_exact_gap_linearisation() {
    // (initial cost, cost after 1 step, after 2 steps)
    let refs = [
        (16.7662344737636, 8.285674292691685e-1, 2.835127889332449e-1),
        (7.345599659277933, 2.959045243825743e-2, 1.172084027855727e-2),
    ];
    assert_sqp_costs("quadrotor", &refs, 1e-9);
}

/// The first `pendulum` instances against mim_solvers 0.3.0's SQP (`reg_min = 0`) on the
/// instances rebuilt with crocoddyl 3.2.1 and pinocchio 4 (`bench/peers/fig1.py --family
/// pendulum --trace I`: example-robot-data's URDF, crocoddyl's double-pendulum actuation
/// and goal residual with the Gauss-Newton Hessian, semi-implicit Euler): the initial
/// cost, and the costs after one and two steps, which depend on the dynamics (ABA of
/// pinocchio), their derivatives and the cost derivatives. Instance 1's first step opens
/// gaps of 4e4 (1-norm), which amplify rounding: its second step agrees to 2.7e-9, the
/// others to 1e-9.
#[test]
fn sqp_steps_on_the_pendulum_match_mim_solvers() {
    let refs = [
        (8.619166206644463, 1.078603860574832e-2, 2.901127785241623e-3),
        (9.735368924967929e1, 2.189695559195048e1, 1.001831854854414e1),
        (1.983469096190514e2, 1.934723206549833e2, 1.752624968313664e2),
    ];
    assert_sqp_costs("pendulum", &refs, 1e-8);
}
