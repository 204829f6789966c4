//! The LQ solvers allocate nothing after construction (a counting global allocator;
//! this file is its own test binary so that no other test allocates concurrently).

use gharial::lq::random::{self, SplitMix64, VariedOptions};
use gharial::lq::{LqSolution, ParallelRiccatiSolver, RiccatiOptions, RiccatiSolver};

#[path = "support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// Problems that exercise every path: general `E` with `mu_dyn > 0` (LU of `E`, `I + P'G`),
/// hard rows (Bunch-Kaufman), varying dimensions, the peers' problem (`E = -I`, LDLᵀ).
fn problems() -> Vec<gharial::lq::LqProblem> {
    let mut rng = SplitMix64::new(5);
    vec![
        random::peers_problem(8, 3, 5, 12, 42, 1e-8).problem,
        random::varied_problem(
            &mut rng,
            &VariedOptions {
                horizon: 15,
                nx: (2, 7),
                nu: (1, 4),
                nc: (0, 5),
                vary_dims: true,
                general_e: true,
                mu_dyn: 1e-3,
                hard_rows: true,
                rank_deficient: true,
                initial_rows: Some(2),
                mu0: 1e-6,
                ..Default::default()
            },
        ),
    ]
}

/// One test function: the global counter must not see other tests. The serial solver is
/// checked on the current thread's counter; the parallel solvers (all alive together, so
/// that no pool shuts down meanwhile) on the global one.
#[test]
fn lq_solvers_allocate_nothing_after_setup() {
    let problems = problems();
    for p in &problems {
        // Serial solver, with every option that uses storage: rollout gains, refinement.
        let opts = RiccatiOptions {
            rollout_gains: true,
            refinement_steps: 2,
        };
        let mut solver = RiccatiSolver::with_options(p, opts).unwrap();
        let mut sol = LqSolution::new(p);
        let n = counting_alloc::local_allocations_during(|| {
            for _ in 0..3 {
                solver.backward(p, 1e-9).unwrap();
                solver.forward(p, &mut sol).unwrap();
                solver.backward_vectors(p).unwrap();
                solver.forward(p, &mut sol).unwrap();
            }
        });
        assert_eq!(n, 0, "the serial Riccati solver allocated {n} times");
    }
    // Parallel solvers: nothing either, on any thread (the count is the process's).
    let mut solvers: Vec<_> = problems
        .iter()
        .map(|p| (ParallelRiccatiSolver::new(p, 3, 1).unwrap(), LqSolution::new(p)))
        .collect();
    for (p, (solver, sol)) in problems.iter().zip(&mut solvers) {
        for _ in 0..3 {
            solver.backward(p, 0.0).unwrap();
            solver.forward(p, sol).unwrap();
        }
        let solves: usize = 126;
        let n = counting_alloc::allocations_during(|| {
            for _ in 0..solves {
                solver.backward(p, 0.0).unwrap();
                solver.backward_vectors(p).unwrap();
                solver.forward(p, sol).unwrap();
            }
        });
        assert_eq!(
            n, 0,
            "the parallel Riccati solver allocated {n} times in {solves} solves"
        );
    }
}
