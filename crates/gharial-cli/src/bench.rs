//! `gharial bench riccati`: timing of the LQ solvers on the peers' random problems.

use std::time::Instant;

use gharial::lq::dense::kkt_residuals;
use gharial::lq::random::peers_problem;
use gharial::lq::{LqProblem, LqSolution, ParallelRiccatiSolver, RiccatiOptions, RiccatiSolver};

/// Settings of the Riccati benchmark.
pub struct RiccatiBench {
    /// `nx:nu:nc` of the main series.
    pub dims: (usize, usize, usize),
    /// Horizons of the main series.
    pub horizons: Vec<usize>,
    /// Extra cases `nx:nu:nc:N`.
    pub extra: Vec<(usize, usize, usize, usize)>,
    /// Thread counts of the parallel solver (1 = serial solver).
    pub threads: Vec<usize>,
    /// Constraint regularisation.
    pub mu: f64,
    /// Generator seed.
    pub seed: u64,
    /// Time budget per case and solver, seconds.
    pub budget: f64,
    /// Passes over the case list (the budget is split between them).
    pub rounds: usize,
    /// Refinement steps.
    pub refine: usize,
}

enum Solver {
    Serial(RiccatiSolver),
    Parallel(ParallelRiccatiSolver),
}

impl Solver {
    /// The backward pass; the solver's error as text.
    fn backward(&mut self, p: &LqProblem) -> Result<(), String> {
        match self {
            Solver::Serial(s) => s.backward(p, 0.0),
            Solver::Parallel(s) => s.backward(p, 0.0),
        }
        .map_err(|e| format!("backward pass: {e}"))
    }

    /// The forward pass; the solver's error as text.
    fn forward(&mut self, p: &LqProblem, sol: &mut LqSolution) -> Result<(), String> {
        match self {
            Solver::Serial(s) => s.forward(p, sol),
            Solver::Parallel(s) => s.forward(p, sol),
        }
        .map_err(|e| format!("forward pass: {e}"))
    }
}

struct Run {
    problem: LqProblem,
    n: usize,
    dims: (usize, usize, usize),
    threads: usize,
    legs: usize,
    solver: Solver,
    sol: LqSolution,
    tb: Vec<f64>,
    tf: Vec<f64>,
    tt: Vec<f64>,
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

impl Run {
    /// The solver of `problem` on `threads` threads (1: the serial one), checked by one
    /// backward and forward pass.
    fn new(b: &RiccatiBench, (nx, nu, nc, n): (usize, usize, usize, usize), threads: usize) -> Result<Self, String> {
        let problem = peers_problem(nx, nu, nc, n, b.seed, b.mu).problem;
        let (mut solver, legs) = if threads <= 1 {
            let opts = RiccatiOptions {
                refinement_steps: b.refine,
                ..Default::default()
            };
            let s = RiccatiSolver::with_options(&problem, opts).expect("solver");
            (Solver::Serial(s), 1)
        } else {
            let s = ParallelRiccatiSolver::new(&problem, threads, b.refine).expect("solver");
            let legs = s.num_legs();
            (Solver::Parallel(s), legs)
        };
        let mut sol = LqSolution::new(&problem);
        solver
            .backward(&problem)
            .and_then(|()| solver.forward(&problem, &mut sol))
            .map_err(|e| {
                let hint = if b.mu == 0.0 {
                    " (at mu = 0 a constraint without control makes the stage system singular; take mu > 0)"
                } else {
                    ""
                };
                format!("case {nx}:{nu}:{nc}:{n}, mu = {:e}: {e}{hint}", b.mu)
            })?;
        Ok(Run {
            problem,
            n,
            dims: (nx, nu, nc),
            threads,
            legs,
            solver,
            sol,
            tb: Vec::new(),
            tf: Vec::new(),
            tt: Vec::new(),
        })
    }

    /// `warm_up` untimed solves, then timed ones for `seconds` (at least 3).
    fn time(&mut self, warm_up: usize, seconds: f64) -> Result<(), String> {
        for _ in 0..warm_up {
            self.solver.backward(&self.problem)?;
            self.solver.forward(&self.problem, &mut self.sol)?;
        }
        let start = Instant::now();
        let mut reps = 0;
        while reps < 3 || start.elapsed().as_secs_f64() < seconds {
            let t0 = Instant::now();
            self.solver.backward(&self.problem)?;
            let t1 = Instant::now();
            self.solver.forward(&self.problem, &mut self.sol)?;
            let t2 = Instant::now();
            self.tb.push((t1 - t0).as_secs_f64() * 1e6);
            self.tf.push((t2 - t1).as_secs_f64() * 1e6);
            self.tt.push((t2 - t0).as_secs_f64() * 1e6);
            reps += 1;
        }
        Ok(())
    }

    /// The table row of this run.
    fn row(&self) -> String {
        let res = kkt_residuals(&self.problem, &self.sol).expect("dimensions match");
        let (tt, tmin) = (median(&self.tt), min(&self.tt));
        format!(
            "| {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} ({:.1}) | {:.2} ({:.2}) | {} | {:.1e} / {:.1e} / {:.1e} |",
            self.dims.0,
            self.dims.1,
            self.dims.2,
            self.n,
            self.legs,
            median(&self.tb),
            median(&self.tf),
            tt,
            tmin,
            tt / self.n as f64,
            tmin / self.n as f64,
            self.tt.len(),
            res.dynamics,
            res.constraints,
            res.dual
        )
    }
}

/// Runs the benchmark and prints one table per thread count. A case the LQ solver
/// refuses (for example a constraint without control at `mu = 0`) is an error, found by
/// one solve of every case before any timing.
pub fn run(b: &RiccatiBench) -> Result<(), String> {
    let mut cases: Vec<(usize, usize, usize, usize)> =
        b.horizons.iter().map(|&n| (b.dims.0, b.dims.1, b.dims.2, n)).collect();
    cases.extend(b.extra.iter().copied());
    let mut runs = Vec::new();
    for &case in &cases {
        for &threads in &b.threads {
            runs.push(Run::new(b, case, threads)?);
        }
    }
    // Rounds over the cases, in alternating order, share the budget.
    let rounds = b.rounds.max(1);
    for round in 0..rounds {
        let order: Vec<usize> = if round % 2 == 0 {
            (0..runs.len()).collect()
        } else {
            (0..runs.len()).rev().collect()
        };
        for i in order {
            runs[i].time(if round == 0 { 3 } else { 1 }, b.budget / rounds as f64)?;
        }
    }
    out!(
        "Riccati backward + forward on the peers' random LQ problems (seed {}, mu = {:e}, refinement steps {}); \
         median over repetitions (min in parentheses), µs",
        b.seed,
        b.mu,
        b.refine
    );
    for &threads in &b.threads {
        out!();
        if threads <= 1 {
            out!("serial RiccatiSolver");
        } else {
            out!("ParallelRiccatiSolver, {threads} threads");
        }
        out!("| nx | nu | nc | N | legs | backward | forward | total | per stage | reps | KKT dyn / cstr / dual |");
        out!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
        for r in runs.iter().filter(|r| r.threads == threads) {
            out!("{}", r.row());
        }
    }
    Ok(())
}
