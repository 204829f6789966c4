//! Robots inside a `Problem`: states of the wrong size or off the configuration manifold
//! (a quaternion that is not normalised) are refused by name at construction, in
//! `set_x0` and in the guess.

mod common;

use std::sync::Arc;

use gharial::costs::QuadraticStateCost;
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::problem::{Problem, StageModel};
use gharial::solvers::InitialGuess;
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::spaces::Manifold;
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace};

#[test]
fn states_off_the_configuration_manifold_are_refused() {
    let model = common::solo12();
    let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
    let ode =
        Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), Actuation::floating_base(&model).unwrap()).unwrap());
    let step = SemiImplicitEuler::new(ode, space.configuration().clone(), 0.01).unwrap();
    let mut x0 = vec![0.0; space.nx()];
    space.neutral(&mut x0);
    let nu = 12;
    let cost = Arc::new(QuadraticStateCost::diagonal(space.clone(), &x0, &vec![1.0; space.ndx()], nu).unwrap());
    let stage = StageModel::new(cost, Dynamics::Explicit(Arc::new(step))).unwrap();
    let terminal = Arc::new(QuadraticStateCost::diagonal(space.clone(), &x0, &vec![1.0; space.ndx()], 0).unwrap());

    // The base quaternion (entries 3..7 of q) with norm 3.
    let mut bad = x0.clone();
    bad[6] = 3.0;
    let e = Problem::new(&bad, vec![stage.clone(); 4], terminal.clone())
        .err()
        .unwrap();
    assert!(
        e.to_string().contains("initial state x0") && e.to_string().contains("not a valid point"),
        "{e}"
    );
    let e = Problem::new(&x0[..10], vec![stage.clone(); 4], terminal.clone())
        .err()
        .unwrap();
    assert!(e.to_string().contains("x0"), "{e}");

    let mut p = Problem::new(&x0, vec![stage; 4], terminal).unwrap();
    assert!(p.set_x0(&bad).is_err());
    let xs_bad = vec![x0.clone(), bad.clone(), x0.clone(), x0.clone(), x0.clone()];
    let us = vec![vec![0.0; nu]; 4];
    let mut solver = ProxDdp::new(ProxDdpOptions::default());
    solver.setup(&p).unwrap();
    let e = solver.solve(&p, InitialGuess::primal(&xs_bad, &us)).err().unwrap();
    assert!(e.to_string().contains("xs[1]"), "{e}");
}
