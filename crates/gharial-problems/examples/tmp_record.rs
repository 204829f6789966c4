#![allow(missing_docs)]
use gharial::solvers::InitialGuess;
use gharial::solvers::proxddp::{ProxDdp, Rollout};
fn main() {
    for info in gharial_problems::catalogue() {
        let ex = gharial_problems::build(info.name).unwrap();
        for rollout in [Rollout::Linear, Rollout::Nonlinear] {
            let mut o = ex.proxddp.clone();
            o.rollout = rollout;
            let mut s = ProxDdp::new(o);
            s.setup(&ex.problem).unwrap();
            let sol = s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
            let h: f64 = sol
                .history
                .iter()
                .map(|r| r.alpha + r.merit.abs().min(1e300) * 1e-300)
                .sum();
            println!(
                "    (\"{}\", {:?}, {}, {}, {:?}, {:?}, {:?}, {:?}, {:?}),",
                info.name,
                rollout,
                sol.iterations,
                sol.al_iterations,
                sol.cost,
                sol.prim_err,
                sol.dual_err,
                sol.xs[sol.xs.len() - 1][0],
                h
            );
        }
    }
}
