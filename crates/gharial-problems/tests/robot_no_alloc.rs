//! No solver allocates in `solve` after `setup` on robot problems, counted with a global
//! allocator: ProxDDP and the DDP family on the UR5 of the catalogue (the box variants
//! with its torque limits), and ProxDDP on Solo-12 standing on four point contacts with
//! friction cones (second-order-cone sets) and torque limits.

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

use std::sync::Arc;

use gharial::constraints::SecondOrderCone;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::InitialGuess;
use gharial::solvers::Solver;
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions, Rollout, StepAcceptance};
use gharial::spaces::Manifold;
use gharial_multibody::{Model, ReferenceFrame, RootJoint};
use gharial_robotics::residuals::{FrictionCone, FrictionConeResidual, effort_limits};
use gharial_robotics::{Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyPhaseSpace};

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// Solves `problem` from the guess with each rollout and step acceptance and asserts
/// that no solve allocates.
fn assert_no_allocation(name: &str, problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>], mu_init: f64) {
    for rollout in [Rollout::Linear, Rollout::Nonlinear] {
        for step_acceptance in [StepAcceptance::Filter, StepAcceptance::NonmonotoneLinesearch] {
            let opts = ProxDdpOptions::default().with(|o| {
                o.mu_init = mu_init;
                o.rollout = rollout;
                o.step_acceptance = step_acceptance;
                o.max_iters = 8;
            });
            let mut solver = ProxDdp::new(opts);
            solver.setup(problem).unwrap();
            let mut iterations = 0;
            let count = counting_alloc::allocations(|| {
                iterations = solver.solve(problem, InitialGuess::primal(xs, us)).unwrap().iterations;
            });
            assert!(iterations >= 2, "{name}: the solves must do real work");
            assert_eq!(count, 0, "{name} {rollout:?} {step_acceptance:?}");
        }
    }
}

#[test]
fn ur5_solves_without_allocating() {
    for name in ["ur5", "ur5-box"] {
        let ex = gharial_problems::build(name).unwrap();
        assert_no_allocation(name, &ex.problem, &ex.xs0, &ex.us0, ex.proxddp.mu_init);
    }
}

#[test]
fn ur5_solves_without_allocating_with_the_ddp_family() {
    for (name, variants) in [
        ("ur5", [DdpVariant::Ddp, DdpVariant::Fddp]),
        ("ur5-box", [DdpVariant::BoxDdp, DdpVariant::BoxFddp]),
    ] {
        let ex = gharial_problems::build(name).unwrap();
        for variant in variants {
            let mut opts = DdpOptions::new(variant);
            opts.max_iters = 8;
            let mut solver = Ddp::new(opts);
            solver.setup(&ex.problem).unwrap();
            let mut iterations = 0;
            let count = counting_alloc::allocations(|| {
                let guess = InitialGuess::primal(&ex.xs0, &ex.us0);
                iterations = solver.solve(&ex.problem, guess).unwrap().iterations;
            });
            assert!(
                iterations >= 2,
                "{name} {}: the solves must do real work",
                variant.name()
            );
            assert_eq!(count, 0, "{name} {}", variant.name());
        }
    }
}

#[test]
fn solo12_on_four_contacts_solves_without_allocating() {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../gharial-multibody/tests/data/robots");
    let mut model = Model::from_urdf_file(dir.join("solo12.urdf"), RootJoint::FreeFlyer).unwrap();
    model.load_srdf_file(dir.join("solo.srdf")).unwrap();
    let q0 = model.reference_configuration("standing").unwrap().to_vec();
    let model = Arc::new(model);
    let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
    let actuation = Arc::new(Actuation::floating_base(&model).unwrap());
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned).with_gains(0.0, 10.0);
    let ode =
        Arc::new(MultibodyConstraintFwdDynamics::at_frames(space.clone(), actuation.clone(), &feet, spec).unwrap());
    let step = SemiImplicitEuler::new(ode.clone(), space.configuration().clone(), 0.01).unwrap();
    let x0: Vec<f64> = q0.iter().copied().chain(std::iter::repeat_n(0.0, model.nv())).collect();
    let (nu, ndx) = (actuation.nu(), space.ndx());
    let u0 = ode.quasi_static_torque(&q0).unwrap().u;
    let cost = CostStack::new(space.as_ref(), nu)
        .with(
            "state",
            Arc::new(QuadraticStateCost::diagonal(space.clone(), &x0, &vec![1.0; ndx], nu).unwrap()),
            1.0,
        )
        .unwrap()
        .with(
            "control",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &u0, &vec![1e-2; nu]).unwrap()),
            1.0,
        )
        .unwrap();
    let mut stage = StageModel::new(Arc::new(cost), Dynamics::Explicit(Arc::new(step))).unwrap();
    for k in 0..feet.len() {
        let cone = FrictionCone::new(0.8, [0.0, 0.0, 1.0]).unwrap();
        let r = FrictionConeResidual::new(ode.clone(), k, cone).unwrap();
        stage
            .add_constraint(StageConstraint::new(
                "friction",
                Arc::new(r),
                Arc::new(SecondOrderCone::new(3).unwrap()),
            ))
            .unwrap();
    }
    stage
        .add_constraint(effort_limits(&space, &actuation.actuated_dofs().unwrap()).unwrap())
        .unwrap();
    let terminal = QuadraticStateCost::diagonal(space.clone(), &x0, &vec![10.0; ndx], 0).unwrap();
    // Start away from the standing pose: the base 2 cm lower.
    let mut start = x0.clone();
    start[2] -= 0.02;
    let n = 10;
    let problem = Problem::new(&start, vec![stage; n], Arc::new(terminal)).unwrap();
    let us = vec![u0; n];
    let xs = gharial_problems::rollout(&problem, &us).unwrap();
    assert!(space.is_valid(&xs[n]));
    assert_no_allocation("solo12", &problem, &xs, &us, 1e-2);
}
