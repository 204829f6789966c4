//! A floating base without contacts: the Solo-12 released 0.5 m above the ground falls
//! for 0.6 s while a foot reaches for a point (state and control regularisation, a foot
//! translation cost; no constraint). ProxDDP's default dynamics step on unconstrained
//! problems is the exact one; here its co-states drift far from the proximal estimates
//! and the exact step stops descending the merit (the line search failed after 40-50
//! iterations at every `mu_init`). The default now falls back to the proximal step (42)
//! for the rest of the solve: ProxDDP converges to FDDP's optimum.

use std::sync::Arc;

use gharial::costs::{CostStack, QuadraticControlCost, QuadraticResidualCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, SemiImplicitEuler};
use gharial::functions::Unary;
use gharial::problem::{Problem, StageModel, kkt_residuals};
use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::proxddp::{DynamicsStep, ProxDdp, ProxDdpOptions};
use gharial::solvers::{InitialGuess, Solution, Solver, Status};
use gharial::spaces::Manifold;
use gharial_multibody::{Model, RootJoint, forward_kinematics_placements};
use gharial_problems::robots::SOLO_URDF;
use gharial_robotics::residuals::FrameTranslationResidual;
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace};

const N: usize = 30;
const DT: f64 = 0.02;

/// The falling Solo-12 and its zero-torque guess.
fn falling_solo() -> (Problem, Vec<Vec<f64>>) {
    let model = Arc::new(Model::from_urdf_str(SOLO_URDF, RootJoint::FreeFlyer).unwrap());
    let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
    let ode =
        Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), Actuation::floating_base(&model).unwrap()).unwrap());
    let nu = model.nv() - 6;
    let step = SemiImplicitEuler::new(ode, space.configuration().clone(), DT).unwrap();
    let dynamics = Dynamics::Explicit(Arc::new(step));
    let (nq, nv) = (space.nq(), space.nv());
    let mut x0 = vec![0.0; space.nx()];
    space.neutral(&mut x0);
    x0[2] = 0.5;
    let mut data = model.create_data();
    forward_kinematics_placements(&model, &mut data, &x0[..nq]).unwrap();
    let frame = &model.frames()[model.frame_id("FR_FOOT").unwrap()];
    let foot = data
        .joint_placement(frame.parent_joint)
        .compose(&frame.placement)
        .translation;
    let target = [foot[0] + 0.1, foot[1], foot[2] + 0.1];
    let cost = |nu: usize, w_foot: f64| {
        let dyn_space: Arc<dyn Manifold> = space.clone();
        let state = QuadraticStateCost::diagonal(dyn_space.clone(), &x0, &vec![0.1; 2 * nv], nu).unwrap();
        let mut c = CostStack::new(dyn_space.as_ref(), nu)
            .with("state", Arc::new(state), 1.0)
            .unwrap();
        if nu > 0 {
            let u = QuadraticControlCost::diagonal(dyn_space.as_ref(), &vec![0.0; nu], &vec![1e-3; nu]).unwrap();
            c = c.with("control", Arc::new(u), 1.0).unwrap();
        }
        let r = FrameTranslationResidual::new(&space, "FR_FOOT", &target).unwrap();
        let foot = QuadraticResidualCost::diagonal(Arc::new(Unary::new(Arc::new(r), nu)), &[w_foot; 3]).unwrap();
        c.with("foot", Arc::new(foot), 1.0).unwrap()
    };
    let stage = StageModel::new(Arc::new(cost(nu, 10.0)), dynamics).unwrap();
    let problem = Problem::new(&x0, vec![stage; N], Arc::new(cost(0, 100.0))).unwrap();
    (problem, vec![vec![0.0; nu]; N])
}

/// A solve of `solver` from `(xs, us)`, after its setup.
fn solve(solver: &mut dyn Solver, problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Solution {
    solver.setup(problem).unwrap();
    solver.solve(problem, InitialGuess::primal(xs, us)).unwrap().clone()
}

#[test]
fn proxddp_converges_on_a_falling_floating_base() {
    let (problem, us) = falling_solo();
    let xs = gharial_problems::rollout(&problem, &us).unwrap();
    let fddp = DdpOptions::default().with(|o| {
        o.variant = DdpVariant::Fddp;
        o.tol = 1e-6;
        o.max_iters = 200;
    });
    let reference = solve(&mut Ddp::new(fddp), &problem, &xs, &us);
    assert_eq!(reference.status, Status::Converged);
    let options = |step: DynamicsStep| {
        ProxDdpOptions::default().with(|o| {
            o.tol = 1e-5;
            o.mu_init = 1e-4;
            o.max_iters = 300;
            o.dynamics_step = step;
        })
    };
    // The exact step alone (the former default) fails; the default falls back and converges.
    let failed = solve(&mut ProxDdp::new(options(DynamicsStep::Exact)), &problem, &xs, &us);
    let what = |s: &Solution| format!("{:?} after {}", s.status, s.iterations);
    assert_eq!(failed.status, Status::LinesearchFailure, "{}", what(&failed));
    let sol = solve(&mut ProxDdp::new(options(DynamicsStep::Auto)), &problem, &xs, &us);
    assert_eq!(sol.status, Status::Converged, "{}", what(&sol));
    let kkt = kkt_residuals(&problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
    assert!(
        kkt.dynamics.max(kkt.initial) <= 1e-5 && kkt.stationarity <= 1e-5,
        "{kkt:?}"
    );
    let rel = (sol.cost - reference.cost).abs() / reference.cost;
    assert!(rel < 1e-5, "ProxDDP {} against FDDP {}", sol.cost, reference.cost);
}
