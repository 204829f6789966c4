//! The bad-input suite of the core: malformed problems, options and guesses give a
//! clear `Error` or a documented status, never a panic, an abort or a silent NaN.
//!
//! - `corpus_replays`: every file of `fuzz/corpus/problem/` (the fuzz target's corpus)
//!   through the fuzz entry point;
//! - `random_byte_strings`: random inputs to the same entry point (proptest);
//! - the other tests pin one defect class each.

mod fuzz_entry;

use std::sync::Arc;

use faer::Mat;
use gharial::constraints::BoxConstraint;
use gharial::costs::{QuadraticCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::functions::ControlError;
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::solvers::{HISTORY_LIMIT, InitialGuess, Status};
use gharial::spaces::{CartesianProduct, Manifold, SE3, SO2, VectorSpace};
use proptest::prelude::*;

/// Cases per proptest run (the suite's size is reported by `cargo test -- --nocapture`).
const CASES: u32 = 20_000;

fn corpus_dir() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/problem")
}

#[test]
fn corpus_replays() {
    let mut files: Vec<_> = std::fs::read_dir(corpus_dir())
        .expect("the fuzz corpus is checked in")
        .map(|e| e.expect("corpus entry").path())
        .collect();
    files.sort();
    assert!(files.len() >= 20, "only {} corpus files", files.len());
    let mut solved = 0;
    for f in &files {
        let bytes = std::fs::read(f).expect("corpus file");
        let outcome = std::panic::catch_unwind(|| fuzz_entry::run(&bytes));
        assert!(outcome.is_ok(), "corpus file {} breaks the contract", f.display());
        solved += usize::from(matches!(outcome, Ok(fuzz_entry::Outcome::Solved(_))));
    }
    eprintln!(
        "bad input: replayed {} corpus files, {solved} reached a solve",
        files.len()
    );
    assert!(
        solved >= 5,
        "the corpus must exercise the solver, not only the constructors"
    );
}

/// Random byte strings through the fuzz entry point, with a census of how far they got
/// (the suite must reach the solver often, not only the constructors' checks).
#[test]
fn random_byte_strings() {
    use proptest::test_runner::{Config, TestRunner};
    let census = std::sync::Mutex::new(std::collections::HashMap::<String, usize>::new());
    let mut runner = TestRunner::new(Config {
        cases: CASES,
        failure_persistence: None,
        ..Config::default()
    });
    let outcome = runner.run(&proptest::collection::vec(any::<u8>(), 0..600), |bytes| {
        let o = fuzz_entry::run(&bytes);
        let key = match o {
            fuzz_entry::Outcome::Solved(s) => format!("solved: {s}"),
            other => format!("{other:?}"),
        };
        *census.lock().unwrap().entry(key).or_default() += 1;
        Ok(())
    });
    outcome.unwrap();
    let census = census.into_inner().unwrap();
    let solved: usize = census
        .iter()
        .filter(|(k, _)| k.starts_with("solved"))
        .map(|(_, v)| v)
        .sum();
    eprintln!("bad input: {CASES} random cases: {census:?}");
    assert!(
        solved * 10 >= CASES as usize,
        "only {solved} of {CASES} cases reached a solve"
    );
}

/// A 2-state double integrator with a control box, `n` stages.
fn small_problem(n: usize) -> (Problem, Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(2));
    let a = Mat::from_fn(2, 2, |i, j| {
        if i == j {
            1.0
        } else if j == i + 1 {
            0.1
        } else {
            0.0
        }
    });
    let b = Mat::from_fn(2, 1, |i, _| if i == 1 { 0.1 } else { 0.0 });
    let dynamics = Dynamics::Explicit(Arc::new(
        LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0; 2]).unwrap(),
    ));
    let q = Mat::<f64>::identity(2, 2);
    let r = Mat::from_fn(1, 1, |_, _| 0.1);
    let cost = QuadraticCost::new(q.as_ref(), Mat::zeros(2, 1).as_ref(), r.as_ref(), &[0.0; 2], &[0.0]).unwrap();
    let limits = StageConstraint::new(
        "u",
        Arc::new(ControlError::new(space.as_ref(), &[0.0]).unwrap()),
        Arc::new(BoxConstraint::new(&[-1.0], &[1.0]).unwrap()),
    );
    let stage = StageModel::new(Arc::new(cost), dynamics)
        .unwrap()
        .with_constraint(limits)
        .unwrap();
    let terminal = QuadraticCost::terminal(q.as_ref(), &[0.0; 2]).unwrap();
    let problem = Problem::new(&[1.0, 0.0], vec![stage; n], Arc::new(terminal)).unwrap();
    let xs = vec![vec![1.0, 0.0]; n + 1];
    let us = vec![vec![0.0]; n];
    (problem, xs, us)
}

#[test]
fn unbounded_iteration_limits_reserve_bounded_memory() {
    let (p, xs, us) = small_problem(10);
    for max_iters in [usize::MAX, 1 << 40] {
        let mut solver = ProxDdp::new(ProxDdpOptions::default().with(|o| {
            o.max_iters = max_iters;
        }));
        solver.setup(&p).expect("setup with an unbounded iteration limit");
        let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        assert_eq!(sol.status, Status::Converged);
        assert!(sol.history.capacity() <= HISTORY_LIMIT);
        assert_eq!(sol.history.len(), sol.iterations);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

    /// Any option values: `setup` refuses the invalid ones with the option's name, and a
    /// solve with the others ends with finite iterates.
    #[test]
    fn random_options_are_validated_or_solved(
        tol in prop_oneof![Just(f64::NAN), Just(-1.0), Just(0.0), Just(f64::INFINITY), 1e-12..1.0f64],
        mu_init in prop_oneof![Just(f64::NAN), Just(0.0), Just(1e300), 1e-9..10.0f64],
        mu_update_factor in prop_oneof![Just(1.0), Just(0.0), Just(f64::NAN), 0.01..0.99f64],
        preg_increase in prop_oneof![Just(1.0), Just(f64::INFINITY), Just(f64::NAN), 1.5..100.0f64],
        max_iters in prop_oneof![Just(0usize), Just(usize::MAX), 1usize..50],
        threads in prop_oneof![Just(0usize), Just(1000usize), 1usize..4],
        nonmonotone_eta in prop_oneof![Just(-0.5), Just(2.0), 0.0..1.0f64],
    ) {
        let (p, xs, us) = small_problem(8);
        let opts = ProxDdpOptions::default().with(|o| { o.tol = tol; o.mu_init = mu_init; o.mu_update_factor = mu_update_factor; o.preg_increase = preg_increase; o.max_iters = max_iters; o.num_threads = threads; o.nonmonotone_eta = nonmonotone_eta; o.mu_lower_bound = 1e-12; });
        let valid = opts.validate();
        let mut solver = ProxDdp::new(opts);
        match solver.setup(&p) {
            Err(e) => {
                prop_assert!(valid.is_err());
                prop_assert!(matches!(e, gharial::Error::InvalidOption { .. }), "{e}");
            }
            Ok(()) => {
                let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
                prop_assert!(sol.xs.iter().chain(&sol.us).flatten().all(|v| v.is_finite()));
                prop_assert!(sol.status != Status::NotStarted);
            }
        }
    }

    /// Guesses of the wrong shape or with non-finite entries are refused by name.
    #[test]
    fn malformed_guesses_are_refused(
        extra_state in 0usize..2, missing_control in 0usize..2, bad in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(-f64::INFINITY)],
        t in 0usize..6, which in 0usize..3,
    ) {
        let (p, mut xs, mut us) = small_problem(6);
        let mut solver = ProxDdp::new(ProxDdpOptions::default());
        solver.setup(&p).unwrap();
        match which {
            0 => xs[t][t % 2] = bad,
            1 => us[t][0] = bad,
            _ => {
                xs.extend(std::iter::repeat_n(vec![0.0; 2], extra_state));
                us.truncate(us.len() - missing_control);
                if extra_state + missing_control == 0 {
                    us[t] = vec![0.0; 2];
                }
            }
        }
        let e = solver.solve(&p, InitialGuess::primal(&xs, &us)).err();
        prop_assert!(e.is_some());
        let msg = e.unwrap().to_string();
        prop_assert!(msg.contains("xs") || msg.contains("us"), "{msg}");
    }

    /// States off the manifold (unit quaternions and unit circles) are refused by
    /// `Problem::new`, `Problem::set_x0` and the guess check alike.
    #[test]
    fn states_off_the_manifold_are_refused(scale in prop_oneof![Just(0.0), Just(3.0), 0.5..0.999f64, 1.001..2.0f64], which in 0usize..2) {
        let space: Arc<dyn Manifold> = Arc::new(CartesianProduct::new(vec![Arc::new(SE3), Arc::new(SO2)]));
        let mut x = vec![0.0; space.nx()];
        space.neutral(&mut x);
        let good = x.clone();
        let k = if which == 0 { 6 } else { 7 };
        x[k] *= scale;
        let cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &good, &[1.0; 7], 1).unwrap());
        let dynamics = Dynamics::Explicit(Arc::new(Hold { space: space.clone() }));
        let stage = StageModel::new(cost, dynamics).unwrap();
        let terminal = Arc::new(QuadraticStateCost::diagonal(space.clone(), &good, &[1.0; 7], 0).unwrap());
        prop_assert!(Problem::new(&x, vec![stage.clone(); 2], terminal.clone()).is_err());
        let mut p = Problem::new(&good, vec![stage; 2], terminal).unwrap();
        prop_assert!(p.set_x0(&x).is_err());
        prop_assert_eq!(p.x0().unwrap(), &good[..]);
        let xs = vec![good.clone(), x.clone(), good.clone()];
        prop_assert!(p.check_trajectory(&xs, &[vec![0.0], vec![0.0]]).is_err());
    }
}

/// `y = x ⊕ (u, 0, ...)`: stays on any manifold.
struct Hold {
    space: Arc<dyn Manifold>,
}

impl gharial::dynamics::ExplicitDynamics for Hold {
    fn space(&self) -> &Arc<dyn Manifold> {
        &self.space
    }
    fn nu(&self) -> usize {
        1
    }
    fn forward(&self, x: &[f64], u: &[f64], d: &mut gharial::dynamics::ExplicitDynamicsData) {
        let mut v = vec![0.0; self.space.ndx()];
        v[0] = u[0];
        self.space.integrate(x, &v, d.xnext_mut());
    }
    fn jacobians(&self, x: &[f64], u: &[f64], d: &mut gharial::dynamics::ExplicitDynamicsData) {
        let mut v = vec![0.0; self.space.ndx()];
        v[0] = u[0];
        self.space.jintegrate(x, &v, gharial::spaces::Arg::First, d.jx.as_mut());
        let mut jv = Mat::zeros(v.len(), v.len());
        self.space.jintegrate(x, &v, gharial::spaces::Arg::Second, jv.as_mut());
        for i in 0..v.len() {
            d.ju[(i, 0)] = jv[(i, 0)];
        }
    }
}

#[test]
fn infinite_and_huge_bounds_print_compactly() {
    let e = BoxConstraint::new(&[f64::MAX], &[-f64::MAX]).err().unwrap().to_string();
    assert!(e.contains("1.7976931348623157e308") && e.len() < 200, "{e}");
    let e = ProxDdp::new(ProxDdpOptions::default().with(|o| {
        o.tol = -f64::MAX;
    }))
    .setup(&small_problem(2).0)
    .err()
    .unwrap()
    .to_string();
    assert!(e.len() < 120, "{e}");
}

#[test]
fn non_square_linear_dynamics_need_the_explicit_constructor() {
    let a = Mat::<f64>::zeros(2, 3);
    let b = Mat::<f64>::zeros(2, 1);
    let e = LinearDiscreteDynamics::new(a.as_ref(), b.as_ref(), &[0.0; 2])
        .err()
        .unwrap();
    assert!(e.to_string().contains("A columns"), "{e}");
    assert!(LinearDiscreteDynamics::between(a.as_ref(), b.as_ref(), &[0.0; 2]).is_ok());
}

/// A path constraint whose value overflows to `inf` (a linear row `f64::MAX x_0` at
/// `x_0 = 2`) is a non-finite point: every solver says `NonFinite` (CSQP ended in a
/// regularisation failure; with a NaN value, where `f64::max` dropped the NaN from the
/// violation, CSQP and ALTRO reported `Converged`).
#[test]
fn an_overflowing_constraint_is_reported_non_finite() {
    use gharial::constraints::NegativeOrthant;
    use gharial::functions::LinearFunction;
    use gharial::solvers::SolverOptions;
    let (p, _, us) = small_problem(4);
    let big = Mat::from_fn(1, 2, |_, j| if j == 0 { f64::MAX } else { 0.0 });
    let row = LinearFunction::new(big.as_ref(), Mat::zeros(1, 1).as_ref(), &[0.0]).unwrap();
    let stages: Vec<StageModel> = p
        .stages()
        .iter()
        .map(|s| {
            s.clone()
                .with_constraint(StageConstraint::new(
                    "big",
                    Arc::new(row.clone()),
                    Arc::new(NegativeOrthant),
                ))
                .unwrap()
        })
        .collect();
    let q = Problem::new(&[2.0, 0.0], stages, p.terminal_cost().clone()).unwrap();
    let xs = vec![vec![2.0, 0.0]; 5];
    for name in ["csqp", "altro", "proxddp"] {
        let mut s = SolverOptions::from_name(name).unwrap().build();
        s.setup(&q).unwrap();
        let sol = s.solve(&q, InitialGuess::primal(&xs, &us)).unwrap();
        assert_eq!(sol.status, Status::NonFinite, "{name}: {:?}", sol.status);
    }
}
