//! ALTRO's car escape (Table I, §IV): the infeasible start (III-B) from the states
//! interpolated through six poses finds a collision-free path out of the room, where
//! AL-iLQR started from the rollout of the guess's controls does not.

use gharial::solvers::altro::{Altro, AltroOptions};
use gharial::solvers::{InitialGuess, Solution, Solver, Status};

/// The wall discs `(x, y, r)` of the escape (the same numbers as the problem's).
fn walls() -> Vec<[f64; 3]> {
    let line = |from: [f64; 2], to: [f64; 2], n: usize| {
        (0..n).map(move |i| {
            let s = i as f64 / (n - 1) as f64;
            [from[0] + s * (to[0] - from[0]), from[1] + s * (to[1] - from[1]), 0.5]
        })
    };
    line([0.0, 0.0], [0.0, 5.0], 30)
        .chain(line([5.0, 0.0], [5.0, 5.0], 30))
        .chain(line([10.0, 0.0], [10.0, 5.0], 30))
        .chain(line([0.0, 0.0], [10.0, 0.0], 50))
        .chain(line([0.0, 5.0], [3.0, 5.0], 15))
        .chain(line([5.0, 5.0], [8.0, 5.0], 15))
        .collect()
}

/// The deepest penetration of a wall disc by the states `x_1..x_{N-1}` (the constrained
/// ones), in distance: `max(r - |p - c|)`, negative when every state is outside.
fn penetration(sol: &Solution) -> f64 {
    let walls = walls();
    let n = sol.xs.len() - 1;
    let mut worst = f64::NEG_INFINITY;
    for x in &sol.xs[1..n] {
        for [cx, cy, r] in &walls {
            worst = worst.max(r - ((x[0] - cx).powi(2) + (x[1] - cy).powi(2)).sqrt());
        }
    }
    worst
}

fn goal_error(sol: &Solution) -> f64 {
    let x = sol.xs.last().unwrap();
    (x[0] - 7.5).abs().max((x[1] - 2.5).abs()).max(x[2].abs())
}

fn solve(ex: &gharial_problems::Example, opts: AltroOptions) -> Solution {
    let mut s = Altro::new(opts);
    s.setup(&ex.problem).unwrap();
    s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

#[test]
fn escape_needs_the_infeasible_start() {
    let ex = gharial_problems::build("car-escape").unwrap();
    // The authors' settings for the escape.
    let opts = AltroOptions::default().with(|o| {
        o.penalty_initial = 10.0;
        o.penalty_scaling = 100.0;
        o.cost_tolerance_intermediate = 1e-3;
        o.constraint_tolerance = 1e-8;
        o.iterations_outer = 20;
    });
    let infeasible = solve(&ex, opts.clone().with(|o| o.infeasible_start = true));
    let rollout = solve(&ex, opts);
    for (name, s) in [("infeasible start", &infeasible), ("rollout", &rollout)] {
        eprintln!(
            "{name}: {:?} c_max {:e} cost {} iters {} outer {} time {:?} penetration {:e} goal {:e}",
            s.status,
            s.prim_err,
            s.cost,
            s.iterations,
            s.al_iterations,
            s.solve_time,
            penetration(s),
            goal_error(s)
        );
    }
    assert_eq!(infeasible.status, Status::Converged);
    assert!(infeasible.prim_err <= 1e-8);
    assert!(penetration(&infeasible) < 1e-6, "{:e}", penetration(&infeasible));
    assert!(goal_error(&infeasible) < 1e-6);
    assert!(
        rollout.status != Status::Converged || penetration(&rollout) > 1e-6,
        "AL-iLQR from the rollout"
    );
}
