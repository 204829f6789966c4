//! `SolverOptions`: every solver by name, the error for an unknown name, and a solve with
//! a solver built from its options.

#[path = "support/lq_ocp.rs"]
mod lq_ocp;

use gharial::Error;
use gharial::solvers::{InitialGuess, SolverOptions};
use lq_ocp::*;

#[test]
fn every_name_builds_the_solver_of_that_name() {
    assert_eq!(SolverOptions::names().len(), 10);
    for &name in SolverOptions::names() {
        let options = SolverOptions::from_name(name).unwrap();
        assert_eq!(options.name(), name);
        options.validate().unwrap();
        assert_eq!(options.build().name(), name);
    }
}

#[test]
fn an_unknown_name_is_refused_with_the_valid_names() {
    let e = SolverOptions::from_name("ipopt").unwrap_err();
    assert!(matches!(e, Error::InvalidOption { .. }), "{e:?}");
    let message = e.to_string();
    assert!(message.contains("unknown solver `ipopt`"), "{message}");
    for name in SolverOptions::names() {
        assert!(message.contains(name), "{message}");
    }
}

#[test]
fn a_solver_built_by_name_solves_an_lq_problem() {
    let lq = random_lq(3, 2, 10, 5);
    let p = ocp(&lq, None, None);
    let (xs, us) = zero_guess(&p);
    for &name in SolverOptions::names() {
        let mut solver = SolverOptions::from_name(name).unwrap().build();
        solver.setup(&p).unwrap();
        let sol = solver.solve(&p, InitialGuess::primal(&xs, &us)).unwrap();
        assert!(sol.status.converged(), "{name}: {}", sol.status);
    }
}
