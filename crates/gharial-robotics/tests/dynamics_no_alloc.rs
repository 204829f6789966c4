//! The multibody ODEs, their contact forces and their integration allocate nothing once
//! their data exist, counted with a global allocator.

mod common;

use std::sync::Arc;

use gharial::dynamics::{ExplicitDynamics, Ode, SemiImplicitEuler};
use gharial::spaces::Manifold;
use gharial_multibody::ReferenceFrame;
use gharial_robotics::{
    Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics, MultibodyPhaseSpace,
    MultibodyWeldFwdDynamics, set_contact_references,
};
use rand::SeedableRng;
use rand::rngs::SmallRng;

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// Distinct random states (the constrained ODE keeps the solution of its last point, so
/// each call must be at a new point to run the algorithms).
fn states(space: &MultibodyPhaseSpace, n: usize) -> Vec<Vec<f64>> {
    let mut rng = SmallRng::seed_from_u64(6);
    (0..n)
        .map(|_| {
            let mut x = vec![0.0; space.nx()];
            space.random(&mut rng, &mut x);
            x
        })
        .collect()
}

/// Allocations of `evaluate` + `jacobians` of `ode` and of a semi-implicit Euler step
/// of it, each at a new state.
fn count(name: &str, ode: Arc<dyn Ode>, space: &Arc<MultibodyPhaseSpace>) {
    let xs = states(space, 16);
    let u = vec![0.1; ode.nu()];
    let mut data = ode.create_data();
    let mut k = 0;
    let n = counting_alloc::allocations(|| {
        k += 1;
        ode.evaluate(&xs[k], &u, &mut data);
        ode.jacobians(&xs[k], &u, &mut data);
    });
    assert!(data.xdot().iter().all(|v| v.is_finite()), "{name}");
    println!("{name}: evaluate + jacobians: {n} allocations");
    assert_eq!(n, 0, "{name}: evaluate + jacobians allocated {n} times");
    let config: Arc<dyn Manifold> = space.configuration().clone();
    let step = SemiImplicitEuler::new(ode, config, 0.01).unwrap();
    let mut d = step.create_data();
    let n = counting_alloc::allocations(|| {
        k += 1;
        step.forward(&xs[k], &u, &mut d);
        step.jacobians(&xs[k], &u, &mut d);
    });
    println!("{name}: semi-implicit Euler forward + jacobians: {n} allocations");
    assert_eq!(n, 0, "{name}: semi-implicit Euler allocated {n} times");
}

#[test]
fn multibody_odes_do_not_allocate() {
    let ur5 = common::ur5();
    let space = Arc::new(MultibodyPhaseSpace::new(ur5.clone()));
    let free = MultibodyFreeFwdDynamics::new(space.clone(), Actuation::full(&ur5)).unwrap();
    count("ur5 free", Arc::new(free), &space);

    let solo = common::solo12();
    let space = Arc::new(MultibodyPhaseSpace::new(solo.clone()));
    let b = Arc::new(Actuation::floating_base(&solo).unwrap());
    let free = MultibodyFreeFwdDynamics::new(space.clone(), b.clone()).unwrap();
    count("solo12 free, floating base", Arc::new(free), &space);
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    for rf in [ReferenceFrame::LocalWorldAligned, ReferenceFrame::Local] {
        let spec = ContactSpec::point(rf).with_gains(20.0, 5.0);
        let mut contacts = gharial_robotics::contacts_at_frames(&solo, &feet, spec).unwrap();
        set_contact_references(&solo, &mut contacts, &gharial_multibody::neutral(&solo)).unwrap();
        let ode = Arc::new(MultibodyConstraintFwdDynamics::new(space.clone(), b.clone(), contacts).unwrap());
        count(&format!("solo12 4 feet {rf:?}"), ode.clone(), &space);
        // The contact forces and their Jacobians for a residual.
        let xs = states(&space, 8);
        let u = vec![0.2; ode.nu()];
        let mut cd = ode.create_contact_data();
        let mut k = 0;
        let n = counting_alloc::allocations(|| {
            k += 1;
            ode.contact_forces(&xs[k], &u, &mut cd).unwrap();
            ode.contact_force_jacobians(&xs[k], &u, &mut cd).unwrap();
        });
        println!("solo12 4 feet {rf:?}: contact forces + Jacobians: {n} allocations");
        assert_eq!(n, 0, "contact forces allocated {n} times");
    }
    let weld = MultibodyWeldFwdDynamics::new(space.clone(), b.clone(), "root_joint", 20.0, 5.0).unwrap();
    count("solo12 root welded", Arc::new(weld), &space);
    let dense = Actuation::matrix(&solo, b.to_matrix().as_ref()).unwrap();
    let free = MultibodyFreeFwdDynamics::new(space.clone(), dense).unwrap();
    count("solo12 free, dense B", Arc::new(free), &space);
}
