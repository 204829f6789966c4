//! Problem construction and solving driven by arbitrary bytes: the entry point of the
//! `problem` fuzz target (`fuzz/fuzz_targets/problem.rs`) and of the bad-input tests,
//! which replay its corpus and random byte strings on the stable toolchain.
//!
//! The bytes choose sizes (zero included), numbers (NaN, infinities, 1e300, raw bit
//! patterns), mismatched dimensions, constraint sets, solver options and guesses. The
//! contract checked: every constructor and solver call returns a clear `Err` or a
//! result; a solve returns finite states and controls (the last accepted iterate) and a
//! status that agrees with its residuals, and its solution is accepted as a warm start.

use std::sync::Arc;

use faer::Mat;
use gharial::constraints::{BoxConstraint, EqualityConstraintSet, NegativeOrthant, SecondOrderCone};
use gharial::costs::QuadraticCost;
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::functions::{ControlError, StateError};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{HessianApprox, Merit, ProxDdp, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::solvers::{InitialGuess, Status};
use gharial::spaces::{Manifold, VectorSpace};

/// Reads decisions from the bytes; zeros once they run out.
pub struct Bytes<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Bytes<'a> {
    /// A reader over `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    /// The next byte (0 past the end).
    pub fn byte(&mut self) -> u8 {
        let b = self.data.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    /// An integer in `0..=max`.
    pub fn upto(&mut self, max: usize) -> usize {
        self.byte() as usize % (max + 1)
    }

    /// Whether the next byte is odd.
    pub fn flag(&mut self) -> bool {
        self.byte() % 2 == 1
    }

    /// A number: mostly moderate values, sometimes NaN, infinities, extremes or raw bits.
    pub fn real(&mut self) -> f64 {
        let tag = self.byte();
        let v = self.byte() as i8 as f64;
        match tag % 64 {
            0..=56 => v / 16.0,
            57..=59 => v / 4096.0,
            60 | 61 => v * 1e3,
            62 => [
                f64::NAN,
                f64::INFINITY,
                -f64::INFINITY,
                1e300,
                -1e300,
                1e-300,
                f64::MAX,
                0.0,
            ][(v as i64).rem_euclid(8) as usize],
            _ => f64::from_bits(u64::from_le_bytes(std::array::from_fn(|_| self.byte()))),
        }
    }

    /// `n` numbers.
    pub fn reals(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.real()).collect()
    }

    /// A `rows x cols` matrix of numbers.
    pub fn mat(&mut self, rows: usize, cols: usize) -> Mat<f64> {
        let v = self.reals(rows * cols);
        Mat::from_fn(rows, cols, |i, j| v[i * cols + j])
    }
}

/// Builds a problem from the bytes, or the error a constructor returned.
pub fn problem(b: &mut Bytes) -> gharial::Result<(Problem, usize, usize)> {
    let (nx, nu, n) = (b.upto(5), b.upto(3), b.upto(6));
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(nx));
    let cols = if b.upto(7) == 0 { b.upto(5) } else { nx };
    let (a, bm, c) = (b.mat(nx, cols), b.mat(nx, nu), b.reals(nx));
    let dynamics = if b.flag() {
        LinearDiscreteDynamics::between(a.as_ref(), bm.as_ref(), &c)?
    } else {
        LinearDiscreteDynamics::new(a.as_ref(), bm.as_ref(), &c)?
    };
    let (q, s, r) = (b.mat(nx, nx), b.mat(nx, nu), b.mat(nu, nu));
    let cost = QuadraticCost::new(q.as_ref(), s.as_ref(), r.as_ref(), &b.reals(nx), &b.reals(nu))?;
    let mut stage = StageModel::new(Arc::new(cost), Dynamics::Explicit(Arc::new(dynamics)))?;
    for _ in 0..b.upto(2) {
        stage.add_constraint(path_constraint(b, &space, nx, nu)?)?;
    }
    let terminal = QuadraticCost::terminal(b.mat(nx, nx).as_ref(), &b.reals(nx))?;
    let mut problem = Problem::new(&b.reals(nx), vec![stage; n], Arc::new(terminal))?;
    if b.flag() {
        let target = b.reals(nx);
        let f = Arc::new(gharial::functions::Unary::new(
            Arc::new(StateError::new(space.clone(), &target)?),
            0,
        ));
        problem.add_terminal_constraint(StageConstraint::new("x_N", f, Arc::new(EqualityConstraintSet)))?;
    }
    Ok((problem, nx, nu))
}

/// A constraint on the controls or the state, with a set chosen by the bytes.
pub fn path_constraint(
    b: &mut Bytes,
    space: &Arc<dyn Manifold>,
    nx: usize,
    nu: usize,
) -> gharial::Result<StageConstraint> {
    let on_state = b.flag();
    let (f, nr): (Arc<dyn gharial::functions::StageFunction>, usize) = if on_state {
        let e = StateError::new(space.clone(), &b.reals(nx))?;
        (Arc::new(gharial::functions::Unary::new(Arc::new(e), nu)), nx)
    } else {
        (Arc::new(ControlError::new(space.as_ref(), &b.reals(nu))?), nu)
    };
    let set: Arc<dyn gharial::constraints::ConstraintSet> = match b.upto(3) {
        0 => Arc::new(BoxConstraint::new(&b.reals(nr), &b.reals(nr))?),
        1 => Arc::new(NegativeOrthant),
        2 => Arc::new(SecondOrderCone::new(nr)?),
        _ => Arc::new(EqualityConstraintSet),
    };
    let c = StageConstraint::new("c", f, set);
    Ok(if b.flag() { c.with_scale(b.real()) } else { c })
}

/// Solver options chosen by the bytes (invalid ones included).
pub fn options(b: &mut Bytes) -> ProxDdpOptions {
    let mut o = ProxDdpOptions::default().with(|o| {
        o.max_iters = 1 + b.upto(40);
        o.max_al_iters = 1 + b.upto(20);
        o.rollout = if b.flag() { Rollout::Nonlinear } else { Rollout::Linear };
        o.step_acceptance = [
            StepAcceptance::Filter,
            StepAcceptance::Linesearch,
            StepAcceptance::NonmonotoneLinesearch,
        ][b.upto(2)];
        o.merit = if b.flag() { Merit::Primal } else { Merit::PrimalDual };
        o.hessian = if b.flag() {
            HessianApprox::Exact
        } else {
            HessianApprox::GaussNewton
        };
        o.active_set_iters = b.upto(3);
        o.num_threads = 1 + b.upto(2);
    });
    if b.flag() {
        o.tol = b.real().abs();
        o.mu_init = b.real().abs();
        o.mu_lower_bound = o.mu_lower_bound.min(o.mu_init);
    }
    if b.upto(7) == 0 {
        o.dyn_al_scale = b.real();
        o.preg_increase = b.real();
    }
    o
}

/// A guess: states and controls, of the wrong sizes when the bytes say so.
pub fn guess(b: &mut Bytes, problem: &Problem, nx: usize, nu: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = problem.horizon();
    let wrong = b.upto(7) == 0;
    let (extra_state, long_state, long_control) = (wrong && b.flag(), wrong && b.flag(), wrong && b.flag());
    let xs = (0..=n + usize::from(extra_state))
        .map(|t| b.reals(problem.space(t.min(n)).nx() + usize::from(t == 0 && long_state)))
        .collect();
    let us = (0..n).map(|_| b.reals(nu + usize::from(long_control))).collect();
    let _ = nx;
    (xs, us)
}

/// How far a case got.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// A constructor refused the model.
    Model,
    /// `setup` refused the options.
    Setup,
    /// `solve` refused the guess.
    Guess,
    /// The solve ran and ended with this status.
    Solved(Status),
}

/// Builds, sets up and solves whatever the bytes describe, checking the contract.
///
/// # Panics
/// When the library breaks the contract (that is what the tests look for).
pub fn run(data: &[u8]) -> Outcome {
    let mut b = Bytes::new(data);
    let Ok((problem, nx, nu)) = problem(&mut b) else {
        return Outcome::Model;
    };
    let mut solver = ProxDdp::new(options(&mut b));
    if solver.setup(&problem).is_err() {
        return Outcome::Setup;
    }
    let (xs, us) = guess(&mut b, &problem, nx, nu);
    let tol = solver.options.tol;
    let Ok(sol) = solver.solve(&problem, InitialGuess::primal(&xs, &us)) else {
        return Outcome::Guess;
    };
    let finite = |v: &[Vec<f64>]| v.iter().flatten().all(|x| x.is_finite());
    assert!(
        finite(&sol.xs) && finite(&sol.us),
        "non-finite iterate returned with status {}",
        sol.status
    );
    assert_ne!(sol.status, Status::NotStarted);
    if sol.status == Status::Converged {
        assert!(
            sol.prim_err <= tol && sol.dual_err <= tol,
            "converged at {:e} / {:e}",
            sol.prim_err,
            sol.dual_err
        );
        assert!(sol.cost.is_finite());
        let kkt = gharial::problem::kkt_residuals(&problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus)
            .expect("the solution has the problem's shape");
        assert!(
            kkt.max() <= 10.0 * tol.max(1e-10),
            "converged, but the KKT residuals are {kkt:?} (tol {tol:e})"
        );
    }
    let sol = sol.clone();
    solver
        .solve(&problem, InitialGuess::from_solution(&sol))
        .expect("a solution is a valid warm start");
    Outcome::Solved(sol.status)
}
