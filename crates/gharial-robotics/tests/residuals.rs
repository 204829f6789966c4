//! The robot residuals: Jacobians against finite differences on random states of the
//! UR5 (fixed base), Solo-12 and G1 (free flyers); values against Pinocchio's fixtures
//! and independent computations; friction and wrench cones against their geometric
//! definitions; joint limits against the URDF's numbers; bad input; no allocation.

mod common;

use common::*;

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

use std::sync::Arc;

use faer::Mat;
use gharial::Error;
use gharial::check::{CheckOptions, check_stage_function};
use gharial::constraints::{ConstraintSet, NegativeOrthant, SecondOrderCone};
use gharial::functions::{StageFunction, StageFunctionData, Unary, UnaryFunction};
use gharial::spaces::Manifold;
use gharial_multibody::spatial::{Mat3, Motion, Se3, Vec3};
use gharial_multibody::{
    ContactType, Model, ReferenceFrame, RootJoint, constraint_dynamics, exp3, exp6, forward_kinematics_placements,
    jacobian_center_of_mass, update_frame_placements,
};
use gharial_robotics::residuals::{
    CenterOfMassTranslationResidual, CenterOfMassVelocityResidual, ContactForceResidual, FlyHighResidual, ForceMap,
    FramePlacementResidual, FrameRotationResidual, FrameTranslationResidual, FrameVelocityResidual, FrictionCone,
    FrictionConeResidual, GravityCompensationResidual, RelativePlacementResidual, SmoothFrictionCone,
    SmoothFrictionConeResidual, StackedContactResidual, WrenchCone, WrenchConeResidual, effort_limits, position_limits,
    velocity_limits,
};
use gharial_robotics::{Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyPhaseSpace};
use rand::SeedableRng;
use rand::rngs::SmallRng;
use serde_json::Value;

const FD: CheckOptions = CheckOptions { eps: 1e-6, tol: 1e-6 };
const RF: [ReferenceFrame; 3] = [
    ReferenceFrame::Local,
    ReferenceFrame::World,
    ReferenceFrame::LocalWorldAligned,
];

// ---------------------------------------------------------------------------------
// Helpers.

fn se3f(v: &Value) -> Se3 {
    let m = matf(v);
    Se3::new(
        Mat3::from_fn(|i, j| m[(i, j)]),
        Vec3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
    )
}

fn random_motion(rng: &mut SmallRng, scale: f64) -> Motion {
    Motion::from_slice(&random_vec(rng, 6, scale))
}

/// `(r, ∂r/∂x)` of a state function.
fn value_and_jacobian(f: &dyn UnaryFunction, x: &[f64]) -> (Vec<f64>, Mat<f64>) {
    let mut d = StageFunctionData::new(f.ndx(), 0, f.nr(), f.create_workspace());
    f.evaluate(x, &mut d);
    f.jacobian(x, &mut d);
    (d.value().to_vec(), d.jx.clone())
}

/// `r(x)` of a state function.
fn value_of(f: &dyn UnaryFunction, x: &[f64]) -> Vec<f64> {
    let mut d = StageFunctionData::new(f.ndx(), 0, f.nr(), f.create_workspace());
    f.evaluate(x, &mut d);
    d.value().to_vec()
}

/// Finite-difference check of a state function lifted to a stage with 2 controls.
fn check_unary(f: Arc<dyn UnaryFunction>, space: &MultibodyPhaseSpace, x: &[f64], what: &str) {
    let g = Unary::new(f, 2);
    let rep = check_stage_function(&g, space, x, &[0.3, -0.2], None, FD);
    assert!(rep.passed(), "{what}: {:?}", rep.errors);
}

/// Finite-difference check of a stage function.
fn check_stage(f: &dyn StageFunction, space: &MultibodyPhaseSpace, x: &[f64], u: &[f64], what: &str) {
    let rep = check_stage_function(f, space, x, u, None, FD);
    assert!(rep.passed(), "{what}: {:?}", rep.errors);
}

/// World placement of frame `name` at configuration `q`, from the multibody crate.
fn frame_placement(model: &Model, name: &str, q: &[f64]) -> Se3 {
    let mut data = model.create_data();
    forward_kinematics_placements(model, &mut data, q).unwrap();
    update_frame_placements(model, &mut data).unwrap();
    *data.frame_placement(model.frame_id(name).unwrap())
}

/// Robots with two frames each (the second one on another branch where there is one).
fn robots() -> Vec<(&'static str, Arc<Model>, [&'static str; 2])> {
    vec![
        ("ur5", common::ur5(), ["tool0", "forearm_link"]),
        ("solo12", common::solo12(), ["FL_FOOT", "HR_FOOT"]),
        ("g1", common::g1(), ["left_ankle_roll_link", "right_rubber_hand"]),
    ]
}

// ---------------------------------------------------------------------------------
// Jacobians against finite differences.

#[test]
fn frame_residual_jacobians_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(1);
    for (robot, model, frames) in robots() {
        let space = space_of(&model);
        for _ in 0..3 {
            let x = random_state(&space, &mut rng);
            let q = &x[..space.nq()];
            for name in frames {
                let what = |r: &str| format!("{robot} {name}: {r}");
                // Targets near the current pose, so that the errors stay well inside the
                // domain of the logarithm.
                let o_mf = frame_placement(&model, name, q);
                let m_ref = o_mf.compose(&exp6(&random_motion(&mut rng, 0.5)));
                let f = Arc::new(FramePlacementResidual::new(&space, name, &m_ref).unwrap());
                check_unary(f, &space, &x, &what("placement"));
                let f = Arc::new(FrameTranslationResidual::new(&space, name, &random_vec(&mut rng, 3, 1.0)).unwrap());
                check_unary(f, &space, &x, &what("translation"));
                let r_ref = o_mf.rotation * exp3(&Vec3::from_column_slice(&random_vec(&mut rng, 3, 0.5)));
                let f = Arc::new(FrameRotationResidual::new(&space, name, &r_ref).unwrap());
                check_unary(f, &space, &x, &what("rotation"));
                for rf in RF {
                    let f = FrameVelocityResidual::new(&space, name, rf, &random_vec(&mut rng, 6, 1.0)).unwrap();
                    check_unary(Arc::new(f), &space, &x, &what(&format!("velocity {rf:?}")));
                }
                let f = Arc::new(FlyHighResidual::new(&space, name, 3.0).unwrap());
                check_unary(f.clone(), &space, &x, &what("fly-high"));
                f.set_ground(&[0.3, -0.2, 0.1]).unwrap();
                check_unary(f, &space, &x, &what("fly-high above a tilted plane"));
            }
            let m_ab = frame_placement(&model, frames[0], q).inv_compose(&frame_placement(&model, frames[1], q));
            let m_ref = m_ab.compose(&exp6(&random_motion(&mut rng, 0.5)));
            let f = Arc::new(RelativePlacementResidual::new(&space, frames[0], frames[1], &m_ref).unwrap());
            check_unary(f, &space, &x, &format!("{robot}: relative placement"));
        }
    }
}

#[test]
fn com_and_gravity_jacobians_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(2);
    for (robot, model, _) in robots() {
        let space = space_of(&model);
        let actuation = Arc::new(match robot {
            "ur5" => Actuation::full(&model),
            _ => Actuation::floating_base(&model).unwrap(),
        });
        let nu = actuation.nu();
        for _ in 0..3 {
            let x = random_state(&space, &mut rng);
            let f = CenterOfMassTranslationResidual::new(&space, &random_vec(&mut rng, 3, 1.0)).unwrap();
            check_unary(Arc::new(f), &space, &x, &format!("{robot}: com"));
            let f = CenterOfMassVelocityResidual::new(&space, &random_vec(&mut rng, 3, 1.0)).unwrap();
            check_unary(Arc::new(f), &space, &x, &format!("{robot}: com velocity"));
            let g = GravityCompensationResidual::new(&space, actuation.clone()).unwrap();
            check_stage(
                &g,
                &space,
                &x,
                &random_vec(&mut rng, nu, 5.0),
                &format!("{robot}: gravity"),
            );
        }
    }
}

/// Solo-12 with four point contacts at the feet, in `rf`, with Baumgarte gains.
fn solo_dynamics(rf: ReferenceFrame) -> Arc<MultibodyConstraintFwdDynamics> {
    let model = common::solo12();
    let space = space_of(&model);
    let actuation = Actuation::floating_base(&model).unwrap();
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    let spec = ContactSpec::point(rf).with_gains(20.0, 5.0);
    Arc::new(MultibodyConstraintFwdDynamics::at_frames(space, actuation, &feet, spec).unwrap())
}

/// G1 with 6D LOCAL contacts at both ankles.
fn g1_dynamics() -> Arc<MultibodyConstraintFwdDynamics> {
    let model = common::g1();
    let space = space_of(&model);
    let actuation = Actuation::floating_base(&model).unwrap();
    let feet = ["left_ankle_roll_link", "right_ankle_roll_link"];
    let spec = ContactSpec::frame(ReferenceFrame::Local).with_gains(10.0, 2.0);
    Arc::new(MultibodyConstraintFwdDynamics::at_frames(space, actuation, &feet, spec).unwrap())
}

#[test]
fn contact_residual_jacobians_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(3);
    let tilted = FrictionCone::new(0.6, [0.1, -0.2, 1.0]).unwrap();
    for rf in [ReferenceFrame::LocalWorldAligned, ReferenceFrame::Local] {
        let dynamics = solo_dynamics(rf);
        let space = dynamics.phase_space().clone();
        let nu = dynamics.actuation().nu();
        for _ in 0..2 {
            let (x, u) = (random_state(&space, &mut rng), random_vec(&mut rng, nu, 2.0));
            for k in [0, 3] {
                let what = |r: &str| format!("solo12 {rf:?} contact {k}: {r}");
                let f = ContactForceResidual::new(dynamics.clone(), k, &random_vec(&mut rng, 3, 1.0)).unwrap();
                check_stage(&f, &space, &x, &u, &what("force"));
                let f = FrictionConeResidual::new(dynamics.clone(), k, tilted.clone()).unwrap();
                check_stage(&f, &space, &x, &u, &what("friction cone"));
                let smooth = SmoothFrictionCone::new(tilted.clone(), 0.1).unwrap();
                let f = SmoothFrictionConeResidual::new(dynamics.clone(), k, smooth).unwrap();
                check_stage(&f, &space, &x, &u, &what("smooth friction cone"));
            }
        }
    }
    let dynamics = g1_dynamics();
    let space = dynamics.phase_space().clone();
    let nu = dynamics.actuation().nu();
    let (x, u) = (random_state(&space, &mut rng), random_vec(&mut rng, nu, 2.0));
    for k in 0..2 {
        let f = WrenchConeResidual::new(dynamics.clone(), k, WrenchCone::new(0.7, 0.1, 0.05).unwrap()).unwrap();
        check_stage(&f, &space, &x, &u, &format!("g1 contact {k}: wrench cone"));
        let f = ContactForceResidual::new(dynamics.clone(), k, &random_vec(&mut rng, 6, 1.0)).unwrap();
        check_stage(&f, &space, &x, &u, &format!("g1 contact {k}: wrench"));
        let f = FrictionConeResidual::new(dynamics.clone(), k, FrictionCone::vertical(0.7).unwrap()).unwrap();
        check_stage(
            &f,
            &space,
            &x,
            &u,
            &format!("g1 contact {k}: friction cone of a 6D contact"),
        );
    }
}

/// A stack of contact residuals equals its parts, value and Jacobians, stacked (one
/// contact solve instead of one per part), and passes the finite-difference check;
/// residuals of different dynamics models are refused.
#[test]
fn stacked_contact_residuals_equal_their_parts() {
    let mut rng = SmallRng::seed_from_u64(11);
    let dynamics = solo_dynamics(ReferenceFrame::LocalWorldAligned);
    let space = dynamics.phase_space().clone();
    let nu = dynamics.actuation().nu();
    let cone = FrictionCone::vertical(0.8).unwrap();
    let parts = |d: &Arc<MultibodyConstraintFwdDynamics>| -> Vec<FrictionConeResidual> {
        [3, 0, 2]
            .iter()
            .map(|&k| FrictionConeResidual::new(d.clone(), k, cone.clone()).unwrap())
            .collect()
    };
    let stack = StackedContactResidual::new(parts(&dynamics)).unwrap();
    assert_eq!(stack.nr(), 9);
    for _ in 0..2 {
        let (x, u) = (random_state(&space, &mut rng), random_vec(&mut rng, nu, 2.0));
        let mut sd = StageFunctionData::new(stack.ndx(), nu, stack.nr(), stack.create_workspace());
        stack.evaluate(&x, &u, &mut sd);
        stack.jacobians(&x, &u, &mut sd);
        for (i, p) in parts(&dynamics).iter().enumerate() {
            let mut pd = StageFunctionData::new(p.ndx(), nu, 3, p.create_workspace());
            p.evaluate(&x, &u, &mut pd);
            p.jacobians(&x, &u, &mut pd);
            for r in 0..3 {
                assert_eq!(sd.value[3 * i + r], pd.value[r], "part {i} row {r}");
                for j in 0..p.ndx() {
                    assert_eq!(sd.jx[(3 * i + r, j)], pd.jx[(r, j)], "part {i} jx");
                }
                for j in 0..nu {
                    assert_eq!(sd.ju[(3 * i + r, j)], pd.ju[(r, j)], "part {i} ju");
                }
            }
        }
        check_stage(&stack, &space, &x, &u, "stacked friction cones");
    }
    let other = solo_dynamics(ReferenceFrame::Local);
    let mut mixed = parts(&dynamics);
    mixed.push(FrictionConeResidual::new(other, 1, cone.clone()).unwrap());
    let e = StackedContactResidual::new(mixed).unwrap_err().to_string();
    assert!(e.contains("residual 3"), "{e}");
    assert!(StackedContactResidual::<FrictionCone>::new(vec![]).is_err());
}

#[test]
fn limit_functions_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(4);
    for (robot, model, _) in robots() {
        let space = space_of(&model);
        let x = random_state(&space, &mut rng);
        let u = random_vec(&mut rng, model.nv() - if robot == "ur5" { 0 } else { 6 }, 1.0);
        let dofs: Vec<usize> = (model.nv() - u.len()..model.nv()).collect();
        for c in [
            position_limits(&space, u.len()).unwrap(),
            velocity_limits(&space, u.len()).unwrap(),
            effort_limits(&space, &dofs).unwrap(),
        ] {
            check_stage(c.func.as_ref(), &space, &x, &u, &format!("{robot}: {}", c.name));
            assert!(c.func.jacobians_are_constant());
        }
    }
}

// ---------------------------------------------------------------------------------
// Values against Pinocchio's fixtures and independent computations.

/// The first three samples of a fixture with the model: `(q, v, sample)`.
fn fixture_samples(name: &str) -> (Arc<Model>, Value, Vec<Value>) {
    let (model, json) = common::fixture(name);
    let samples = json["samples"].as_array().expect("samples")[..3].to_vec();
    (model, json, samples)
}

#[test]
fn kinematic_values_equal_pinocchio() {
    const TOL: f64 = 1e-10;
    let mut rng = SmallRng::seed_from_u64(5);
    for robot in ["ur5", "solo12", "g1"] {
        let (model, json, samples) = fixture_samples(robot);
        let space = space_of(&model);
        let frames: Vec<String> = json["frames_used"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap().to_string())
            .collect();
        for s in &samples {
            let x: Vec<f64> = vecf(&s["q"]).into_iter().chain(vecf(&s["v"])).collect();
            let o_mf = |name: &str| se3f(&s["oMf"][model.frame_id(name).unwrap()]);
            for name in &frames {
                let ctx = |r: &str| format!("{robot} {name}: {r}");
                let p_ref = random_vec(&mut rng, 3, 1.0);
                let r = value_of(&FrameTranslationResidual::new(&space, name, &p_ref).unwrap(), &x);
                let p: Vec<f64> = r.iter().zip(&p_ref).map(|(a, b)| a + b).collect();
                assert!(
                    max_diff(&p, o_mf(name).translation.as_slice()) < TOL,
                    "{}",
                    ctx("translation")
                );

                // log6 of a known placement: M_ref = oMf exp6(−ξ) gives r = ξ.
                let xi = random_motion(&mut rng, 1.0);
                let m_ref = o_mf(name).compose(&exp6(&(-xi)));
                let r = value_of(&FramePlacementResidual::new(&space, name, &m_ref).unwrap(), &x);
                assert!(max_diff(&r, &xi.to_array()) < TOL, "{}: {r:?} {xi:?}", ctx("placement"));
                let phi = Vec3::from_column_slice(&random_vec(&mut rng, 3, 1.5));
                let r_ref = o_mf(name).rotation * exp3(&(-phi));
                let r = value_of(&FrameRotationResidual::new(&space, name, &r_ref).unwrap(), &x);
                assert!(max_diff(&r, phi.as_slice()) < TOL, "{}", ctx("rotation"));

                for (rf, key) in RF.into_iter().zip(["LOCAL", "WORLD", "LOCAL_WORLD_ALIGNED"]) {
                    let v_ref = random_vec(&mut rng, 6, 1.0);
                    let r = value_of(&FrameVelocityResidual::new(&space, name, rf, &v_ref).unwrap(), &x);
                    let v: Vec<f64> = r.iter().zip(&v_ref).map(|(a, b)| a + b).collect();
                    let pin = vecf(&s["frame_velocity"][name][key]);
                    assert!(max_diff(&v, &pin) < TOL, "{}", ctx(&format!("velocity {key}")));
                }
                let slope = 4.0;
                let r = value_of(&FlyHighResidual::new(&space, name, slope).unwrap(), &x);
                let v = vecf(&s["frame_velocity"][name]["LOCAL_WORLD_ALIGNED"]);
                let e = (-slope * o_mf(name).translation.z).exp();
                assert!(max_diff(&r, &[e * v[0], e * v[1]]) < TOL, "{}", ctx("fly-high"));
                // Measured from the plane z = a + b x + c y under the frame.
                let f = FlyHighResidual::new(&space, name, slope).unwrap();
                let (a, b, c) = (-0.2, 0.1, -0.05);
                f.set_ground(&[a, b, c]).unwrap();
                let r = value_of(&f, &x);
                let p = o_mf(name).translation;
                let e = (-slope * (p.z - (a + b * p.x + c * p.y))).exp();
                assert!(max_diff(&r, &[e * v[0], e * v[1]]) < TOL, "{}", ctx("fly-high, ground"));
            }
            let (a, b) = (&frames[0], &frames[1]);
            let xi = random_motion(&mut rng, 1.0);
            let m_ref = o_mf(a).inv_compose(&o_mf(b)).compose(&exp6(&(-xi)));
            let r = value_of(&RelativePlacementResidual::new(&space, a, b, &m_ref).unwrap(), &x);
            assert!(max_diff(&r, &xi.to_array()) < TOL, "{robot}: relative placement");

            let c_ref = random_vec(&mut rng, 3, 1.0);
            let r = value_of(&CenterOfMassTranslationResidual::new(&space, &c_ref).unwrap(), &x);
            let c: Vec<f64> = r.iter().zip(&c_ref).map(|(a, b)| a + b).collect();
            assert!(max_diff(&c, &vecf(&s["com"]["com"])) < TOL, "{robot}: com");
            let r = value_of(&CenterOfMassVelocityResidual::new(&space, &[0.0; 3]).unwrap(), &x);
            assert!(max_diff(&r, &vecf(&s["com"]["vcom"])) < TOL, "{robot}: com velocity");
        }
    }
}

#[test]
fn kinematic_jacobians_equal_pinocchio() {
    const TOL: f64 = 1e-10;
    for robot in ["ur5", "solo12", "g1"] {
        let (model, json, samples) = fixture_samples(robot);
        let (space, nv) = (space_of(&model), model.nv());
        let deriv_frames: Vec<&str> = json["deriv_frames_used"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap())
            .collect();
        for s in &samples {
            let x: Vec<f64> = vecf(&s["q"]).into_iter().chain(vecf(&s["v"])).collect();
            for name in &deriv_frames {
                let (_, j) = value_and_jacobian(&FrameTranslationResidual::new(&space, name, &[0.0; 3]).unwrap(), &x);
                let pin = matf(&s["frame_jacobian"][name]["LOCAL_WORLD_ALIGNED"]);
                assert!(
                    max_diff_mat(j.subcols(0, nv), pin.subrows(0, 3)) < TOL,
                    "{robot} {name}: translation J"
                );
                assert!(max_diff_mat(j.subcols(nv, nv), Mat::zeros(3, nv).as_ref()) == 0.0);

                // LOCAL: Pinocchio's derivatives. LWA: Pinocchio's dv/dq differentiates the
                // linear velocity at a fixed point; the residual adds ω × ∂p/∂q.
                let deriv = &s["kinematics_derivatives"][name];
                let f = FrameVelocityResidual::new(&space, name, ReferenceFrame::Local, &[0.0; 6]).unwrap();
                let (_, j) = value_and_jacobian(&f, &x);
                let (dq, dv) = (matf(&deriv["LOCAL"]["dv_dq"]), matf(&deriv["LOCAL"]["dv_dv"]));
                assert!(
                    max_diff_mat(j.subcols(0, nv), dq.as_ref()) < TOL,
                    "{robot} {name}: LOCAL dv/dq"
                );
                assert!(
                    max_diff_mat(j.subcols(nv, nv), dv.as_ref()) < TOL,
                    "{robot} {name}: LOCAL dv/dv"
                );
                let lwa = FrameVelocityResidual::new(&space, name, ReferenceFrame::LocalWorldAligned, &[0.0; 6]);
                let (v, j) = value_and_jacobian(&lwa.unwrap(), &x);
                let (dq, dv) = (
                    matf(&deriv["LOCAL_WORLD_ALIGNED"]["dv_dq"]),
                    matf(&deriv["LOCAL_WORLD_ALIGNED"]["dv_dv"]),
                );
                let omega = Vec3::new(v[3], v[4], v[5]);
                let expected = Mat::from_fn(6, nv, |i, c| {
                    let dp = Vec3::new(dv[(0, c)], dv[(1, c)], dv[(2, c)]);
                    dq[(i, c)] + if i < 3 { omega.cross(&dp)[i] } else { 0.0 }
                });
                assert!(
                    max_diff_mat(j.subcols(0, nv), expected.as_ref()) < TOL,
                    "{robot} {name}: LWA dv/dq"
                );
                assert!(
                    max_diff_mat(j.subcols(nv, nv), dv.as_ref()) < TOL,
                    "{robot} {name}: LWA dv/dv"
                );
            }
            let (_, j) = value_and_jacobian(&CenterOfMassTranslationResidual::new(&space, &[0.0; 3]).unwrap(), &x);
            let pin = matf(&s["com"]["jacobian"]);
            assert!(max_diff_mat(j.subcols(0, nv), pin.as_ref()) < TOL, "{robot}: Jcom");
            let (_, j) = value_and_jacobian(&CenterOfMassVelocityResidual::new(&space, &[0.0; 3]).unwrap(), &x);
            assert!(max_diff_mat(j.subcols(nv, nv), pin.as_ref()) < TOL, "{robot}: dvcom/dv");
        }
    }
}

#[test]
fn gravity_compensation_equals_pinocchio_and_the_com_jacobian() {
    let mut rng = SmallRng::seed_from_u64(6);
    for robot in ["ur5", "solo12", "g1"] {
        let (model, _, samples) = fixture_samples(robot);
        let space = space_of(&model);
        let actuation = Arc::new(match robot {
            "ur5" => Actuation::full(&model),
            _ => Actuation::floating_base(&model).unwrap(),
        });
        let b = actuation.to_matrix();
        let f = GravityCompensationResidual::new(&space, actuation.clone()).unwrap();
        let mut d = f.create_data();
        for s in &samples {
            let q = vecf(&s["q"]);
            let x: Vec<f64> = q.iter().copied().chain(vecf(&s["v"])).collect();
            let u = random_vec(&mut rng, actuation.nu(), 3.0);
            f.evaluate(&x, &u, &mut d);
            let g = vecf(&s["generalized_gravity"]);
            // g(q) = ∂V/∂q with V = m g₀ c_z: m g₀ times the z row of Jcom.
            let mut data = model.create_data();
            let jcom = jacobian_center_of_mass(&model, &mut data, &q).unwrap().to_owned();
            let m = model.total_mass();
            for i in 0..model.nv() {
                let bu: f64 = (0..u.len()).map(|j| b[(i, j)] * u[j]).sum();
                assert!((d.value()[i] - (bu - g[i])).abs() < 1e-9, "{robot}: B u − g, row {i}");
                assert!(
                    (g[i] - m * 9.81 * jcom[(2, i)]).abs() < 1e-9,
                    "{robot}: g = m g₀ Jcom_z, row {i}"
                );
            }
        }
    }
}

#[test]
fn contact_force_values_equal_the_constrained_dynamics() {
    let mut rng = SmallRng::seed_from_u64(7);
    let dynamics = solo_dynamics(ReferenceFrame::LocalWorldAligned);
    let space = dynamics.phase_space().clone();
    let model = space.model().clone();
    let b = dynamics.actuation().to_matrix();
    let x = random_state(&space, &mut rng);
    let u = random_vec(&mut rng, b.ncols(), 2.0);
    // λ straight from the multibody crate.
    let tau: Vec<f64> = (0..model.nv())
        .map(|i| (0..u.len()).map(|j| b[(i, j)] * u[j]).sum())
        .collect();
    let mut data = model.create_data();
    let mut cdata = gharial_multibody::ContactData::new(&model, dynamics.contacts()).unwrap();
    let (q, v) = x.split_at(space.nq());
    constraint_dynamics(&model, &mut data, dynamics.contacts(), &mut cdata, q, v, &tau).unwrap();
    let cone = FrictionCone::new(0.5, [0.0, 0.3, 1.0]).unwrap();
    for k in 0..4 {
        let lambda = &cdata.lambda()[3 * k..3 * k + 3];
        let target = random_vec(&mut rng, 3, 1.0);
        let f = ContactForceResidual::new(dynamics.clone(), k, &target).unwrap();
        let mut d = f.create_data();
        f.evaluate(&x, &u, &mut d);
        let expected: Vec<f64> = lambda.iter().zip(&target).map(|(l, t)| l - t).collect();
        assert!(max_diff(d.value(), &expected) < 1e-12, "contact {k}");
        let f = FrictionConeResidual::new(dynamics.clone(), k, cone.clone()).unwrap();
        let mut d = f.create_data();
        f.evaluate(&x, &u, &mut d);
        let mut m = [0.0; 3];
        cone.value(lambda, &mut m);
        assert_eq!(d.value(), &m, "contact {k}: friction cone");
    }
}

// ---------------------------------------------------------------------------------
// Cones.

/// A unit vector orthogonal to `n`, independent of the cone's own basis.
fn orthogonal(n: &Vec3, seed: Vec3) -> Vec3 {
    (seed - n * n.dot(&seed)).normalize()
}

#[test]
fn friction_cones_classify_inside_boundary_and_outside() {
    let mu = 0.7;
    let normal = Vec3::new(0.2, -0.1, 1.0).normalize();
    let cone = FrictionCone::new(mu, [0.2, -0.1, 1.0]).unwrap();
    let soc = SecondOrderCone::new(3).unwrap();
    let exact = SmoothFrictionCone::new(cone.clone(), 0.0).unwrap();
    let eps = 0.05;
    let smooth = SmoothFrictionCone::new(cone.clone(), eps).unwrap();
    for seed in [Vec3::x(), Vec3::new(0.3, 1.0, -0.2), Vec3::new(-1.0, -0.5, 0.4)] {
        let t = orthogonal(&normal, seed);
        for fn_ in [0.5, 3.0] {
            let force = |ratio: f64| normal * fn_ + t * (ratio * mu * fn_);
            for (ratio, inside) in [(0.0, true), (0.5, true), (1.0, true), (1.5, false)] {
                let f = force(ratio);
                let mut r = [0.0; 3];
                cone.value(f.as_slice(), &mut r);
                assert!((r[0] - mu * fn_).abs() < 1e-12);
                assert!(((r[1] * r[1] + r[2] * r[2]).sqrt() - ratio * mu * fn_).abs() < 1e-12);
                let viol = soc.violation(&r);
                let mut s = [0.0; 2];
                exact.value(f.as_slice(), &mut s);
                assert!((s[0] + fn_).abs() < 1e-12);
                assert!((s[1] - (ratio - 1.0) * mu * fn_).abs() < 1e-12);
                let mut se = [0.0; 2];
                smooth.value(f.as_slice(), &mut se);
                if ratio == 1.0 {
                    assert!(viol < 1e-12 && s[1].abs() < 1e-12, "boundary");
                    assert!(se[1] <= 0.0 && se[1] >= -eps, "smoothed boundary {}", se[1]);
                } else if inside {
                    assert_eq!(viol, 0.0);
                    assert!(NegativeOrthant.violation(&s) == 0.0 && NegativeOrthant.violation(&se) == 0.0);
                } else {
                    assert!(viol > 0.1 * fn_, "outside: {viol}");
                    assert!(NegativeOrthant.violation(&s) > 0.1 * fn_);
                    // The smoothed cone is larger by at most eps.
                    assert!(se[1] >= s[1] - eps && se[1] <= s[1]);
                }
            }
        }
        // A pulling force is outside both.
        let f = -normal + t * 0.1;
        let mut r = [0.0; 3];
        cone.value(f.as_slice(), &mut r);
        assert!(soc.penalty(&r).is_infinite());
        let mut s = [0.0; 2];
        exact.value(f.as_slice(), &mut s);
        assert!(s[0] > 0.0);
    }
}

/// Determinant of a square matrix by Gaussian elimination with partial pivoting.
fn det(mut m: Vec<Vec<f64>>) -> f64 {
    let n = m.len();
    let mut d = 1.0;
    for c in 0..n {
        let p = (c..n).max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs())).unwrap();
        if m[p][c] == 0.0 {
            return 0.0;
        }
        if p != c {
            m.swap(p, c);
            d = -d;
        }
        d *= m[c][c];
        for r in c + 1..n {
            let k = m[r][c] / m[c][c];
            for j in c..n {
                m[r][j] -= k * m[c][j];
            }
        }
    }
    d
}

/// The normal of the hyperplane through the origin spanned by five 6-vectors (the
/// generalised cross product), zero if they are dependent.
fn normal5(v: &[[f64; 6]]) -> [f64; 6] {
    let mut n = [0.0; 6];
    for (i, ni) in n.iter_mut().enumerate() {
        let minor: Vec<Vec<f64>> = v
            .iter()
            .map(|r| (0..6).filter(|&j| j != i).map(|j| r[j]).collect())
            .collect();
        *ni = if i % 2 == 0 { 1.0 } else { -1.0 } * det(minor);
    }
    n
}

fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn unit6(a: &[f64; 6]) -> [f64; 6] {
    let n = dot6(a, a).sqrt();
    a.map(|x| x / n)
}

#[test]
fn wrench_cone_is_the_cone_of_the_corner_friction_pyramids() {
    let (mu, hl, hw) = (0.6, 0.11, 0.05);
    let a = *WrenchCone::new(mu, hl, hw).unwrap().matrix();
    // Generators: the edges (±μ, ±μ, 1) of the friction pyramid |f_x|, |f_y| ≤ μ f_z at
    // each corner, as wrenches at the centre: (f, p × f).
    let mut gens = Vec::new();
    for (px, py) in [(hl, hw), (hl, -hw), (-hl, hw), (-hl, -hw)] {
        let p = Vec3::new(px, py, 0.0);
        for f in [
            Vec3::new(mu, mu, 1.0),
            Vec3::new(mu, -mu, 1.0),
            Vec3::new(-mu, mu, 1.0),
            Vec3::new(-mu, -mu, 1.0),
        ] {
            let t = p.cross(&f);
            gens.push([f.x, f.y, f.z, t.x, t.y, t.z]);
        }
    }
    // Every row holds on every generator.
    for (i, row) in a.iter().enumerate() {
        for g in &gens {
            assert!(dot6(row, g) <= 1e-12, "row {i} violated by a generator");
        }
    }
    // The facets of the generated cone, by enumeration of 5-subsets of generators.
    let mut facets: Vec<[f64; 6]> = Vec::new();
    let n = gens.len();
    let mut idx = [0, 1, 2, 3, 4];
    loop {
        let sub: Vec<[f64; 6]> = idx.iter().map(|&i| gens[i]).collect();
        let nrm = normal5(&sub);
        if dot6(&nrm, &nrm).sqrt() > 1e-9 {
            let nrm = unit6(&nrm);
            let side: Vec<f64> = gens.iter().map(|g| dot6(&nrm, g)).collect();
            let outward = if side.iter().all(|&s| s <= 1e-12) {
                Some(nrm)
            } else if side.iter().all(|&s| s >= -1e-12) {
                Some(nrm.map(|x| -x))
            } else {
                None
            };
            if let Some(f) = outward
                && !facets.iter().any(|g| dot6(g, &f) > 1.0 - 1e-9)
            {
                facets.push(f);
            }
        }
        // Next combination of 5 out of n.
        let mut k = 4;
        while idx[k] == n - 5 + k {
            if k == 0 {
                break;
            }
            k -= 1;
        }
        if idx[k] == n - 5 + k {
            break;
        }
        idx[k] += 1;
        for j in k + 1..5 {
            idx[j] = idx[j - 1] + 1;
        }
    }
    assert_eq!(facets.len(), 16, "the cone has 16 facets");
    // Rows 1..17 are exactly the facets; row 0 (f_z ≥ 0) is implied.
    for (i, row) in a.iter().enumerate().skip(1) {
        let r = unit6(row);
        assert!(
            facets.iter().any(|f| dot6(f, &r) > 1.0 - 1e-9),
            "row {i} is not a facet"
        );
    }
    let distinct = (1..17).all(|i| (i + 1..17).all(|j| dot6(&unit6(&a[i]), &unit6(&a[j])) < 1.0 - 1e-9));
    assert!(distinct);

    // A wrench of the cone is inside; shifting its centre of pressure off the sole, or
    // twisting it beyond the friction limit, puts it outside.
    let cone = WrenchCone::new(mu, hl, hw).unwrap();
    let mut rng = SmallRng::seed_from_u64(8);
    let w: Vec<f64> = (0..6)
        .map(|j| {
            gens.iter()
                .map(|g| g[j])
                .zip(random_vec(&mut rng, 16, 1.0))
                .map(|(g, c)| g * c.abs())
                .sum()
        })
        .collect();
    let mut r = [0.0; 17];
    cone.value(&w, &mut r);
    assert_eq!(NegativeOrthant.violation(&r), 0.0);
    let fz = w[2];
    for (j, off) in [
        (3, 1.01 * hw * fz),
        (4, 1.01 * hl * fz),
        (5, 1.01 * mu * (hl + hw) * fz),
    ] {
        let mut out = [0.0, 0.0, fz, 0.0, 0.0, 0.0];
        out[j] = off;
        cone.value(&out, &mut r);
        assert!(NegativeOrthant.violation(&r) > 0.0, "coordinate {j}");
        out[j] = 0.99 * off;
        cone.value(&out, &mut r);
        assert_eq!(NegativeOrthant.violation(&r), 0.0, "coordinate {j} inside");
    }
}

// ---------------------------------------------------------------------------------
// Joint limits.

/// The `<limit>` attributes of every joint of a URDF file that has one, in file order.
fn urdf_limits(file: &str) -> Vec<[f64; 4]> {
    let text = std::fs::read_to_string(common::data_dir().join("robots").join(file)).unwrap();
    let attr = |tag: &str, name: &str| -> f64 {
        let start = tag.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        tag[start..].split('"').next().unwrap().parse().unwrap()
    };
    text.split("<limit ")
        .skip(1)
        .map(|t| {
            let tag = &t[..t.find("/>").unwrap()];
            [
                attr(tag, "lower"),
                attr(tag, "upper"),
                attr(tag, "velocity"),
                attr(tag, "effort"),
            ]
        })
        .collect()
}

#[test]
fn ur5_limits_are_the_urdf_numbers() {
    let model = common::ur5();
    let space = space_of(&model);
    let lim = urdf_limits("ur5_robot.urdf");
    assert_eq!(lim.len(), 6);
    let pos = position_limits(&space, 6).unwrap();
    let vel = velocity_limits(&space, 6).unwrap();
    let eff = effort_limits(&space, &Actuation::full(&model).actuated_dofs().unwrap()).unwrap();
    assert_eq!((pos.nr(), vel.nr(), eff.nr()), (6, 6, 6));
    let mut rng = SmallRng::seed_from_u64(9);
    let x = random_state(&space, &mut rng);
    let u = random_vec(&mut rng, 6, 1.0);
    // The sets accept the bounds themselves and reject just beyond them.
    for (c, lo, hi, z) in [(&pos, 0, 1, &x[..6]), (&vel, 2, 2, &x[6..]), (&eff, 3, 3, &u[..])] {
        let mut d = c.func.create_data();
        c.func.evaluate(&x, &u, &mut d);
        assert_eq!(d.value(), z, "{}: the selected coordinates", c.name);
        let lower: Vec<f64> = lim.iter().map(|l| if lo == hi { -l[lo] } else { l[lo] }).collect();
        let upper: Vec<f64> = lim.iter().map(|l| l[hi]).collect();
        assert_eq!(c.set.penalty(&lower), 0.0, "{}", c.name);
        assert_eq!(c.set.penalty(&upper), 0.0, "{}", c.name);
        for i in 0..6 {
            let (mut below, mut above) = (lower.clone(), upper.clone());
            below[i] -= 1e-9;
            above[i] += 1e-9;
            assert!(c.set.penalty(&below).is_infinite(), "{} lower {i}", c.name);
            assert!(c.set.penalty(&above).is_infinite(), "{} upper {i}", c.name);
        }
    }
}

#[test]
fn free_flyer_limits_skip_the_base() {
    for (model, nq_base) in [(common::solo12(), 7), (common::g1(), 7)] {
        let space = space_of(&model);
        let (nq, nv) = (model.nq(), model.nv());
        let pos = position_limits(&space, nv - 6).unwrap();
        assert_eq!(pos.nr(), nv - 6, "{}: one row per actuated joint", model.name);
        let vel = velocity_limits(&space, nv - 6).unwrap();
        assert_eq!(vel.nr(), nv - 6, "{}: the base velocity has no limit", model.name);
        let eff = effort_limits(
            &space,
            &Actuation::floating_base(&model).unwrap().actuated_dofs().unwrap(),
        )
        .unwrap();
        assert_eq!(eff.nr(), nv - 6);
        // Rows read q[7..] and v[6..].
        let x: Vec<f64> = (0..nq + nv).map(|i| i as f64).collect();
        let mut d = pos.func.create_data();
        pos.func.evaluate(&x, &[0.0; 64][..nv - 6], &mut d);
        assert_eq!(d.value(), &x[nq_base..nq]);
        pos.func.jacobians(&x, &[0.0; 64][..nv - 6], &mut d);
        for k in 0..nv - 6 {
            assert_eq!(d.jx[(k, 6 + k)], 1.0);
        }
        let mut d = vel.func.create_data();
        vel.func.evaluate(&x, &[0.0; 64][..nv - 6], &mut d);
        assert_eq!(d.value(), &x[nq + 6..]);
    }
}

#[test]
fn limits_error_without_limits_in_the_urdf() {
    let urdf = r#"<robot name="free"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint>
      <joint name="j2" type="continuous"><parent link="b"/><child link="c"/></joint></robot>"#;
    let model = Arc::new(Model::from_urdf_str(urdf, RootJoint::Fixed).unwrap());
    let space = space_of(&model);
    for res in [
        position_limits(&space, 2),
        velocity_limits(&space, 2),
        effort_limits(&space, &[0, 1]),
    ] {
        let msg = res.err().expect("an error").to_string();
        assert!(msg.contains("no finite limit") && msg.contains("`free`"), "{msg}");
    }
    let err = effort_limits(&space, &[0, 2]).err().expect("an error").to_string();
    assert!(err.contains("dof 2") && err.contains("nv = 2"), "{err}");
}

// ---------------------------------------------------------------------------------
// Bad input.

#[test]
fn bad_input_gives_clear_errors() {
    let model = common::ur5();
    let space = space_of(&model);
    let err = FrameTranslationResidual::new(&space, "nope", &[0.0; 3])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("FrameTranslationResidual") && err.contains("nope"),
        "{err}"
    );
    let err = FramePlacementResidual::new(&space, "tool1", &Se3::identity())
        .unwrap_err()
        .to_string();
    assert!(err.contains("tool1"), "{err}");
    let err = FrameTranslationResidual::new(&space, "tool0", &[0.0; 2]).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Dimension {
                expected: 3,
                got: 2,
                ..
            }
        ),
        "{err}"
    );
    let err = FrameVelocityResidual::new(&space, "tool0", ReferenceFrame::Local, &[0.0; 3]).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Dimension {
                expected: 6,
                got: 3,
                ..
            }
        ),
        "{err}"
    );
    assert!(matches!(
        CenterOfMassTranslationResidual::new(&space, &[0.0, f64::NAN, 0.0]),
        Err(Error::NonFinite { .. })
    ));
    let sheared = Se3::new(Mat3::new(1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), Vec3::zeros());
    let err = FramePlacementResidual::new(&space, "tool0", &sheared)
        .unwrap_err()
        .to_string();
    assert!(err.contains("not orthonormal"), "{err}");
    let reflection = Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
    assert!(FrameRotationResidual::new(&space, "tool0", &reflection).is_err());
    assert!(RelativePlacementResidual::new(&space, "tool0", "tool0", &Se3::identity()).is_err());
    assert!(FlyHighResidual::new(&space, "tool0", f64::INFINITY).is_err());
    let f = FlyHighResidual::new(&space, "tool0", 1.0).unwrap();
    assert!(f.set_ground(&[0.0, f64::NAN, 0.0]).is_err());
    assert!(f.set_ground(&[0.0; 2]).is_err());
    assert_eq!(f.ground(), [0.0; 3]);

    // Rejected targets leave the old one.
    let f = FrameTranslationResidual::new(&space, "tool0", &[1.0, 2.0, 3.0]).unwrap();
    assert!(f.set_target(&[0.0; 4]).is_err());
    assert!(f.set_target(&[0.0, f64::INFINITY, 0.0]).is_err());
    assert_eq!(f.target(), vec![1.0, 2.0, 3.0]);
    f.set_target(&[0.5, 0.5, 0.5]).unwrap();
    assert_eq!(f.target(), vec![0.5; 3]);
    let p = FramePlacementResidual::new(&space, "tool0", &Se3::identity()).unwrap();
    assert!(p.set_target(&sheared).is_err());
    assert_eq!(p.target(), Se3::identity());

    // A non-finite state gives NaN, not a panic.
    let x = vec![f64::NAN; space.nx()];
    let (r, j) = value_and_jacobian(&f, &x);
    assert!(r.iter().all(|v| v.is_nan()) && j.col(0).iter().all(|v| v.is_nan()));
    let (r, _) = value_and_jacobian(&CenterOfMassVelocityResidual::new(&space, &[0.0; 3]).unwrap(), &x);
    assert!(r.iter().all(|v| v.is_nan()));

    // Gravity compensation with the actuation of another model.
    let solo = common::solo12();
    let err = GravityCompensationResidual::new(&space, Arc::new(Actuation::full(&solo))).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Dimension {
                expected: 6,
                got: 18,
                ..
            }
        ),
        "{err}"
    );

    // Contacts.
    let dynamics = solo_dynamics(ReferenceFrame::LocalWorldAligned);
    let cone = FrictionCone::vertical(0.5).unwrap();
    let err = FrictionConeResidual::new(dynamics.clone(), 4, cone.clone())
        .unwrap_err()
        .to_string();
    assert!(err.contains("contact index 4") && err.contains("4 contacts"), "{err}");
    let err = ContactForceResidual::new(dynamics.clone(), 0, &[0.0; 6]).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Dimension {
                expected: 3,
                got: 6,
                ..
            }
        ),
        "{err}"
    );
    let err = WrenchConeResidual::new(dynamics.clone(), 0, WrenchCone::new(0.5, 0.1, 0.1).unwrap()).unwrap_err();
    assert!(err.to_string().contains("6D contact in Local"), "{err}");
    assert!(FrictionCone::new(-0.1, [0.0, 0.0, 1.0]).is_err());
    assert!(FrictionCone::new(0.5, [0.0, 0.0, 0.0]).is_err());
    assert!(SmoothFrictionCone::new(cone.clone(), -1.0).is_err());
    assert!(WrenchCone::new(0.5, f64::NAN, 0.1).is_err());
    let g1 = g1_dynamics();
    assert_eq!(g1.contacts()[0].kind, ContactType::Contact6D);
    let f = FrictionConeResidual::new(dynamics, 0, cone).unwrap();
    let mut d = f.create_data();
    let x = vec![f64::NAN; f.nx()];
    f.evaluate(&x, &vec![0.0; f.nu()], &mut d);
    assert!(d.value().iter().all(|v| v.is_nan()));
}

// ---------------------------------------------------------------------------------
// No allocation.

fn allocations_of(f: &dyn StageFunction, x: &[f64], u: &[f64]) -> usize {
    let mut d = f.create_data();
    counting_alloc::allocations(|| {
        f.evaluate(x, u, &mut d);
        f.jacobians(x, u, &mut d);
    })
}

#[test]
fn residuals_do_not_allocate() {
    let mut rng = SmallRng::seed_from_u64(10);
    let model = common::ur5();
    let space = space_of(&model);
    let x = random_state(&space, &mut rng);
    let f = Unary::new(
        Arc::new(FrameTranslationResidual::new(&space, "tool0", &[0.3, 0.2, 0.1]).unwrap()),
        6,
    );
    assert_eq!(allocations_of(&f, &x, &[0.0; 6]), 0, "frame translation on ur5");

    let dynamics = solo_dynamics(ReferenceFrame::LocalWorldAligned);
    let space = dynamics.phase_space().clone();
    let x = random_state(&space, &mut rng);
    let u = random_vec(&mut rng, dynamics.actuation().nu(), 1.0);
    let cone = FrictionCone::vertical(0.7).unwrap();
    let f = FrictionConeResidual::new(dynamics.clone(), 1, cone.clone()).unwrap();
    assert_eq!(allocations_of(&f, &x, &u), 0, "friction cone on solo12");
    let f = SmoothFrictionConeResidual::new(dynamics, 1, SmoothFrictionCone::new(cone, 0.01).unwrap()).unwrap();
    assert_eq!(allocations_of(&f, &x, &u), 0, "smooth friction cone on solo12");

    // The others, on solo12.
    let nu = u.len();
    let o_mf = frame_placement(space.model(), "FL_FOOT", &x[..space.nq()]);
    let unary: Vec<Arc<dyn UnaryFunction>> = vec![
        Arc::new(FramePlacementResidual::new(&space, "FL_FOOT", &o_mf).unwrap()),
        Arc::new(FrameRotationResidual::new(&space, "FL_FOOT", &o_mf.rotation).unwrap()),
        Arc::new(FrameVelocityResidual::new(&space, "FL_FOOT", ReferenceFrame::LocalWorldAligned, &[0.0; 6]).unwrap()),
        Arc::new(RelativePlacementResidual::new(&space, "FL_FOOT", "HR_FOOT", &o_mf).unwrap()),
        Arc::new(FlyHighResidual::new(&space, "FL_FOOT", 2.0).unwrap()),
        Arc::new(CenterOfMassTranslationResidual::new(&space, &[0.0; 3]).unwrap()),
        Arc::new(CenterOfMassVelocityResidual::new(&space, &[0.0; 3]).unwrap()),
    ];
    for f in unary {
        assert_eq!(allocations_of(&Unary::new(f, nu), &x, &u), 0);
    }
    let actuation = Arc::new(Actuation::floating_base(space.model()).unwrap());
    let g = GravityCompensationResidual::new(&space, actuation).unwrap();
    assert_eq!(allocations_of(&g, &x, &u), 0, "gravity compensation");
}

/// Inside a stage-data scope the ODE and the contact residuals of one dynamics model share
/// one contact solve (one object); calls at interleaved points still give every model's
/// own, unshared values and Jacobians bit for bit (the shared solve is keyed by the point).
#[test]
fn shared_contact_solve_gives_the_unshared_results() {
    use gharial::dynamics::{Ode, OdeData};
    use gharial::functions::with_shared_data;
    let mut rng = SmallRng::seed_from_u64(5);
    let dynamics = solo_dynamics(ReferenceFrame::LocalWorldAligned);
    let space = dynamics.phase_space().clone();
    let nu = dynamics.actuation().nu();
    let force = ContactForceResidual::new(dynamics.clone(), 1, &[0.0, 0.0, 5.0]).unwrap();
    let cone = FrictionConeResidual::new(dynamics.clone(), 2, FrictionCone::vertical(0.7).unwrap()).unwrap();
    let (mut ode_s, mut force_s, mut cone_s) =
        with_shared_data(|| (dynamics.create_data(), force.create_data(), cone.create_data()));
    let points: Vec<_> = (0..3)
        .map(|_| (random_state(&space, &mut rng), random_vec(&mut rng, nu, 2.0)))
        .collect();
    // (model, point) pairs in an order that switches points between models.
    let order = [(0, 0), (1, 0), (2, 1), (0, 1), (1, 2), (2, 0), (0, 2), (2, 2), (1, 1)];
    for (m, p) in order {
        let (x, u) = (&points[p].0, &points[p].1);
        match m {
            0 => {
                let mut fresh: OdeData = dynamics.create_data();
                for d in [&mut ode_s, &mut fresh] {
                    dynamics.evaluate(x, u, d);
                    dynamics.jacobians(x, u, d);
                }
                assert_eq!(ode_s.xdot, fresh.xdot, "ode value at point {p}");
                assert_eq!(ode_s.jx, fresh.jx, "ode jx at point {p}");
                assert_eq!(ode_s.ju, fresh.ju, "ode ju at point {p}");
            }
            _ => {
                let (f, shared): (&dyn StageFunction, &mut StageFunctionData) = if m == 1 {
                    (&force, &mut force_s)
                } else {
                    (&cone, &mut cone_s)
                };
                let mut fresh = f.create_data();
                for d in [&mut *shared, &mut fresh] {
                    f.evaluate(x, u, d);
                    f.jacobians(x, u, d);
                }
                assert_eq!(shared.value, fresh.value, "model {m} value at point {p}");
                assert_eq!(shared.jx, fresh.jx, "model {m} jx at point {p}");
                assert_eq!(shared.ju, fresh.ju, "model {m} ju at point {p}");
            }
        }
    }
    // One solve: after the force residual's evaluation at a point where the ODE was not
    // evaluated last, the ODE's data holds that point's λ.
    let (x, u) = &points[0];
    force.evaluate(x, u, &mut force_s);
    let lambda = MultibodyConstraintFwdDynamics::contact_data(&ode_s)
        .unwrap()
        .lambda()
        .to_vec();
    let mut d = dynamics.create_contact_data();
    assert_eq!(lambda, dynamics.contact_forces(x, u, &mut d).unwrap());
}

/// The velocity residuals of one stage share one kinematic pass per state (the data
/// created in one `with_shared_data` scope): evaluated and differentiated in an
/// interleaved order at two states, each returns exactly what it returns with its own
/// data, so the memo is invalidated whenever the state changes.
#[test]
fn velocity_residuals_sharing_a_stage_pass_equal_their_unshared_values() {
    let mut rng = SmallRng::seed_from_u64(7);
    let model = common::solo12();
    let space = space_of(&model);
    let fly = FlyHighResidual::new(&space, "FL_FOOT", 3.0).unwrap();
    let vel = FrameVelocityResidual::new(&space, "HR_FOOT", ReferenceFrame::World, &[0.0; 6]).unwrap();
    let fs: [&dyn UnaryFunction; 2] = [&fly, &vel];
    let data = |f: &dyn UnaryFunction| StageFunctionData::new(f.ndx(), 0, f.nr(), f.create_workspace());
    let mut shared = gharial::functions::with_shared_data(|| [data(fs[0]), data(fs[1])]);
    let xs = [random_state(&space, &mut rng), random_state(&space, &mut rng)];
    // (function, state, evaluate, differentiate)
    let order = [
        (0, 0, true, false),
        (1, 0, true, true),
        (1, 1, true, false),
        (0, 0, true, true),
        (0, 1, true, true),
        (1, 1, true, true),
        (1, 0, true, false),
        (0, 1, false, true),
        (1, 1, true, false),
        (0, 0, false, true),
    ];
    for (k, (i, s, evaluate, jacobian)) in order.into_iter().enumerate() {
        let (f, x, d) = (fs[i], &xs[s], &mut shared[i]);
        if evaluate {
            f.evaluate(x, d);
        }
        if jacobian {
            f.jacobian(x, d);
        }
        let own = value_and_jacobian(f, x);
        if evaluate {
            assert_eq!(d.value(), &own.0[..], "step {k}: value");
        }
        if jacobian {
            assert_eq!(d.jx, own.1, "step {k}: Jacobian");
        }
    }
}
