//! The welded-body dynamics against the world-contact dynamics (a weld of a root free
//! flyer is a 6D LOCAL contact at the root), the composite rigid body it must equal when
//! the constraint holds, finite differences, and bad input.

mod common;

use common::*;

use std::sync::Arc;

use gharial::check::{CheckOptions, check_ode};
use gharial::dynamics::{Ode, OdeData};
use gharial_multibody::spatial::{Inertia, Mat3, Se3, Vec3};
use gharial_multibody::{
    ContactModel, ContactType, JointLimits, JointType, Model, ReferenceFrame, aba, generalized_gravity,
};
use gharial_robotics::{
    Actuation, MultibodyConstraintFwdDynamics, MultibodyPhaseSpace, MultibodyWeldFwdDynamics, gravity_compensation,
};
use rand::SeedableRng;
use rand::rngs::SmallRng;

const KP: f64 = 30.0;
const KD: f64 = 11.0;

/// A box of 0.4 kg with its centre of mass off the joint origin.
fn object_inertia() -> Inertia {
    Inertia::from_com(
        0.4,
        Vec3::new(0.01, -0.02, 0.03),
        Mat3::from_diagonal(&Vec3::new(4e-4, 5e-4, 3e-4)),
    )
}

/// The grasp placement of the object in the joint frame of the UR5's `tool0`.
fn grasp(model: &Model) -> (usize, Se3) {
    let tool = &model.frames()[model.frame_id("tool0").unwrap()];
    let offset = Se3::new(Mat3::identity(), Vec3::new(0.0, 0.0, 0.05));
    (tool.parent_joint, tool.placement.compose(&offset))
}

/// The UR5 with the object on a free flyer `object` below `tool0`, and the UR5 with the
/// object's inertia welded to the wrist (the composite body).
fn ur5_with_object() -> (Arc<Model>, Arc<Model>) {
    let mut held = (*ur5()).clone();
    let (parent, placement) = grasp(&held);
    let id = held
        .add_joint(
            parent,
            JointType::FreeFlyer,
            placement,
            "object",
            JointLimits::unbounded(&JointType::FreeFlyer),
        )
        .unwrap();
    held.append_body_to_joint(id, &object_inertia(), &Se3::identity())
        .unwrap();
    let mut welded = (*ur5()).clone();
    welded
        .append_body_to_joint(parent, &object_inertia(), &placement)
        .unwrap();
    (Arc::new(held), Arc::new(welded))
}

fn evaluated(ode: &dyn Ode, x: &[f64], u: &[f64]) -> OdeData {
    let mut data = ode.create_data();
    ode.evaluate(x, u, &mut data);
    ode.jacobians(x, u, &mut data);
    data
}

/// A random state of `space` with the free flyer `joint`'s translation in `[-0.3, 0.3]`.
fn state_with_small_offset(space: &MultibodyPhaseSpace, joint: usize, rng: &mut SmallRng) -> Vec<f64> {
    let mut x = random_state(space, rng);
    let iq = space.model().joints()[joint].idx_q;
    x[iq..iq + 3].copy_from_slice(&random_vec(rng, 3, 0.3));
    x
}

#[test]
fn weld_of_a_root_free_flyer_equals_a_local_6d_contact_at_the_root() {
    let model = solo12();
    let space = space_of(&model);
    let act = Arc::new(Actuation::floating_base(&model).unwrap());
    let weld = MultibodyWeldFwdDynamics::new(space.clone(), act.clone(), "root_joint", KP, KD).unwrap();
    let mut contact = ContactModel::new(
        &model,
        ContactType::Contact6D,
        1,
        Se3::identity(),
        ReferenceFrame::Local,
    )
    .unwrap();
    contact.kp = KP;
    contact.kd = KD;
    let reference = MultibodyConstraintFwdDynamics::new(space.clone(), act, vec![contact]).unwrap();
    let mut rng = SmallRng::seed_from_u64(7);
    for _ in 0..5 {
        let x = state_with_small_offset(&space, 1, &mut rng);
        let u = random_vec(&mut rng, 12, 3.0);
        let (a, b) = (evaluated(&weld, &x, &u), evaluated(&reference, &x, &u));
        assert!(
            max_diff(a.xdot(), b.xdot()) < 1e-9,
            "xdot {}",
            max_diff(a.xdot(), b.xdot())
        );
        assert!(max_diff_mat(a.jx.as_ref(), b.jx.as_ref()) < 1e-8);
        assert!(max_diff_mat(a.ju.as_ref(), b.ju.as_ref()) < 1e-9);
        let mut wd = weld.create_weld_data();
        let mut cd = reference.create_contact_data();
        let (lw, lc) = (
            weld.constraint_wrench(&x, &u, &mut wd).unwrap(),
            reference.contact_forces(&x, &u, &mut cd).unwrap().to_vec(),
        );
        assert!(max_diff(&lw, &lc) < 1e-8, "{lw:?} vs {lc:?}");
    }
}

#[test]
fn weld_jacobians_match_finite_differences() {
    let (held, _) = ur5_with_object();
    let space = space_of(&held);
    let act = Actuation::dofs(&held, &(0..6).collect::<Vec<_>>()).unwrap();
    let weld = MultibodyWeldFwdDynamics::new(space.clone(), act, "object", KP, KD).unwrap();
    let mut rng = SmallRng::seed_from_u64(3);
    for _ in 0..4 {
        let x = state_with_small_offset(&space, 7, &mut rng);
        let u = random_vec(&mut rng, 6, 5.0);
        let report = check_ode(&weld, &x, &u, CheckOptions { eps: 1e-6, tol: 2e-6 });
        report.assert_ok();
        assert_acceleration_jacobians_are_the_bottom_rows(&weld, &x, &u);
    }
}

#[test]
fn a_held_object_moves_with_the_arm_as_a_composite_body() {
    let (held, welded) = ur5_with_object();
    let space = space_of(&held);
    let act = Actuation::dofs(&held, &(0..6).collect::<Vec<_>>()).unwrap();
    let weld = MultibodyWeldFwdDynamics::new(space.clone(), act, "object", KP, KD).unwrap();
    let mut rng = SmallRng::seed_from_u64(11);
    let mut wdata = welded.create_data();
    for _ in 0..4 {
        // The arm anywhere, the object at its grasp frame at rest relative to it.
        let mut x = random_state(&space, &mut rng);
        x[6..13].copy_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        x[13 + 6..].fill(0.0);
        let u = random_vec(&mut rng, 6, 5.0);
        let d = evaluated(&weld, &x, &u);
        let a_composite = aba(&welded, &mut wdata, &x[..6], &x[13..19], &u).unwrap().to_vec();
        let a = &d.xdot()[12..];
        assert!(
            max_diff(&a[..6], &a_composite) < 1e-9,
            "{:?} vs {a_composite:?}",
            &a[..6]
        );
        assert!(
            a[6..].iter().all(|v| v.abs() < 1e-9),
            "relative acceleration {:?}",
            &a[6..]
        );
    }
}

#[test]
fn quasi_static_torque_of_a_weld_is_the_composite_gravity_compensation() {
    let (held, welded) = ur5_with_object();
    let space = space_of(&held);
    let act = Actuation::dofs(&held, &(0..6).collect::<Vec<_>>()).unwrap();
    let weld = MultibodyWeldFwdDynamics::new(space.clone(), act, "object", KP, KD).unwrap();
    let q_arm = [0.3, -1.1, 1.4, -0.7, 0.5, 0.2];
    let q: Vec<f64> = q_arm
        .iter()
        .copied()
        .chain([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        .collect();
    let qs = weld.quasi_static_torque(&q).unwrap();
    let g_composite = gravity_compensation(&welded, &Actuation::full(&welded), &q_arm).unwrap();
    assert!(max_diff(&qs.u, &g_composite) < 1e-9, "{:?} vs {g_composite:?}", qs.u);
    // The object's weight, carried through the constraint: λ = g(q) on the object's dofs.
    let g = generalized_gravity(&held, &mut held.create_data(), &q)
        .unwrap()
        .to_vec();
    assert!(max_diff(&qs.lambda, &g[6..]) < 1e-9);
    assert!((g[6..9].iter().map(|f| f * f).sum::<f64>().sqrt() - 0.4 * 9.81).abs() < 1e-9);
    // Holding still: zero acceleration.
    let x: Vec<f64> = q.iter().copied().chain([0.0; 12]).collect();
    let d = evaluated(&weld, &x, &qs.u);
    assert!(d.xdot().iter().all(|v| v.abs() < 1e-9), "{:?}", d.xdot());
}

#[test]
fn bad_welds_are_construction_errors() {
    let (held, _) = ur5_with_object();
    let space = space_of(&held);
    let act = Arc::new(Actuation::dofs(&held, &(0..6).collect::<Vec<_>>()).unwrap());
    let err = |joint: &str, kp: f64, kd: f64| {
        MultibodyWeldFwdDynamics::new(space.clone(), act.clone(), joint, kp, kd)
            .unwrap_err()
            .to_string()
    };
    assert!(err("elbow_joint", 1.0, 1.0).contains("not a free flyer"));
    assert!(err("nope", 1.0, 1.0).contains("nope"));
    assert!(err("object", -1.0, 1.0).contains("kp"));
    assert!(err("object", 1.0, f64::NAN).contains("kd"));
    let short = Actuation::full(&ur5());
    assert!(MultibodyWeldFwdDynamics::new(space, short, "object", 1.0, 1.0).is_err());
}
