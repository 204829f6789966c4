//! The multibody ODEs against Pinocchio's values (the fixtures), the multibody crate's
//! algorithms, finite differences and hand computations of integrator steps; the
//! inverse-dynamics helpers against independent dense solves; bad input.

mod common;

use common::*;

use std::sync::Arc;

use faer::Mat;
use faer::linalg::solvers::Solve;
use gharial::Error;
use gharial::check::{CheckOptions, check_explicit_dynamics, check_ode, rel_error};
use gharial::dynamics::{ExplicitDynamics, ExplicitRungeKutta, Ode, OdeData, SemiImplicitEuler};
use gharial::spaces::Manifold;
use gharial_multibody::{
    ContactData, ContactType, Model, ReferenceFrame, aba, constraint_dynamics, crba, generalized_gravity, integrate,
    nonlinear_effects,
};
use gharial_robotics::dynamics::last_error;
use gharial_robotics::{
    Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics, MultibodyPhaseSpace,
    contacts_at_frames, gravity_compensation, set_contact_references,
};
use rand::SeedableRng;
use rand::rngs::SmallRng;
use serde_json::Value;

const FEET: [&str; 4] = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
const G1_FEET: [&str; 2] = ["left_ankle_roll_link", "right_ankle_roll_link"];
/// Agreement with Pinocchio (relative to `max(1, |value|)`), as the multibody crate's
/// fixture test.
const PIN_TOL: f64 = 1e-9;
/// Finite-difference checks: step and relative tolerance.
const FD: CheckOptions = CheckOptions { eps: 1e-6, tol: 2e-6 };

fn col(v: &[f64]) -> Mat<f64> {
    Mat::from_fn(v.len(), 1, |i, _| v[i])
}

/// `[[0, I], [dq, dv]]` and `[[0], [du]]`: the expected ODE Jacobians from the
/// acceleration's derivatives.
fn phase_jacobians(dq: &Mat<f64>, dv: &Mat<f64>, du: &Mat<f64>) -> (Mat<f64>, Mat<f64>) {
    let nv = dq.nrows();
    let jx = Mat::from_fn(2 * nv, 2 * nv, |i, j| match (i < nv, j < nv) {
        (true, _) => f64::from(j == nv + i),
        (false, true) => dq[(i - nv, j)],
        (false, false) => dv[(i - nv, j - nv)],
    });
    let ju = Mat::from_fn(2 * nv, du.ncols(), |i, j| if i < nv { 0.0 } else { du[(i - nv, j)] });
    (jx, ju)
}

fn evaluated(ode: &dyn Ode, x: &[f64], u: &[f64]) -> OdeData {
    let mut data = ode.create_data();
    ode.evaluate(x, u, &mut data);
    ode.jacobians(x, u, &mut data);
    data
}

/// The fixture samples' state, torque and sample JSON.
fn samples(json: &Value) -> impl Iterator<Item = (Vec<f64>, Vec<f64>, &Value)> {
    json["samples"].as_array().expect("samples").iter().map(|s| {
        let x = [vecf(&s["q"]), vecf(&s["v"])].concat();
        (x, vecf(&s["tau"]), s)
    })
}

#[test]
fn free_dynamics_equals_pinocchio_aba_and_its_derivatives() {
    let mut checked = 0;
    for fixture in common::FIXTURES {
        let (model, json) = common::fixture(fixture);
        let nv = model.nv();
        let ode = MultibodyFreeFwdDynamics::new(space_of(&model), Actuation::full(&model)).unwrap();
        for (x, tau, s) in samples(&json) {
            let data = evaluated(&ode, &x, &tau);
            let d = &s["aba_derivatives"];
            let xdot = [x[model.nq()..].to_vec(), vecf(&s["aba"])].concat();
            let (jx, ju) = phase_jacobians(&matf(&d["ddq_dq"]), &matf(&d["ddq_dv"]), &matf(&d["ddq_dtau"]));
            for (what, got, want) in [
                ("xdot", col(data.xdot()), col(&xdot)),
                ("jx", data.jx.clone(), jx),
                ("ju", data.ju.clone(), ju),
            ] {
                let err = rel_error(&got, &want);
                assert!(err < PIN_TOL, "{fixture} sample {}: {what} off by {err:e}", s["index"]);
            }
            assert_eq!(data.xdot().len(), 2 * nv);
            checked += 1;
        }
    }
    assert!(checked >= 60, "only {checked} samples");
}

#[test]
fn constrained_dynamics_equals_pinocchio_constraint_dynamics() {
    let mut checked = 0;
    for fixture in common::FIXTURES {
        let (model, json) = common::fixture(fixture);
        let space = space_of(&model);
        for (x, tau, s) in samples(&json) {
            for setup in s["constraint_dynamics"].as_array().into_iter().flatten() {
                let kind = match setup["type"].as_str() {
                    Some("CONTACT_3D") => ContactType::Contact3D,
                    _ => ContactType::Contact6D,
                };
                let rf = match setup["reference_frame"].as_str() {
                    Some("LOCAL") => ReferenceFrame::Local,
                    _ => ReferenceFrame::LocalWorldAligned,
                };
                let b = &setup["baumgarte"];
                let spec = ContactSpec {
                    kind,
                    reference_frame: rf,
                    kp: 0.0,
                    kd: 0.0,
                }
                .with_gains(b["Kp"].as_f64().unwrap(), b["Kd"].as_f64().unwrap());
                let frames: Vec<&str> = setup["frames"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|f| f.as_str().unwrap())
                    .collect();
                let ode =
                    MultibodyConstraintFwdDynamics::at_frames(space.clone(), Actuation::full(&model), &frames, spec)
                        .unwrap();
                let data = evaluated(&ode, &x, &tau);
                let d = &setup["derivatives"];
                let xdot = [x[model.nq()..].to_vec(), vecf(&setup["ddq"])].concat();
                let (jx, ju) = phase_jacobians(&matf(&d["ddq_dq"]), &matf(&d["ddq_dv"]), &matf(&d["ddq_dtau"]));
                let lambda = MultibodyConstraintFwdDynamics::contact_data(&data)
                    .unwrap()
                    .lambda()
                    .to_vec();
                let mut cd = ode.create_contact_data();
                ode.contact_force_jacobians(&x, &tau, &mut cd).unwrap();
                let dl_dx = matf(&d["dlambda_dq"]);
                let dl_dx = Mat::from_fn(dl_dx.nrows(), 2 * model.nv(), |i, j| {
                    if j < model.nv() {
                        dl_dx[(i, j)]
                    } else {
                        matf(&d["dlambda_dv"])[(i, j - model.nv())]
                    }
                });
                let ctx = format!("{fixture} sample {} {}", s["index"], setup["name"]);
                for (what, got, want) in [
                    ("xdot", col(data.xdot()), col(&xdot)),
                    ("jx", data.jx.clone(), jx),
                    ("ju", data.ju.clone(), ju),
                    ("lambda", col(&lambda), col(&vecf(&setup["lambda"]))),
                    ("lambda (contact data)", col(cd.lambda()), col(&vecf(&setup["lambda"]))),
                    ("dlambda_dx", cd.dlambda_dx().to_owned(), dl_dx),
                    ("dlambda_du", cd.dlambda_du().to_owned(), matf(&d["dlambda_dtau"])),
                ] {
                    let err = rel_error(&got, &want);
                    assert!(err < PIN_TOL, "{ctx}: {what} off by {err:e}");
                }
                checked += 1;
            }
        }
    }
    // solo12: 2 setups x 10 samples, g1: 1 x 8.
    assert!(checked >= 28, "only {checked} setups");
}

/// The free ODE with armature and underactuation equals an independent dense solve
/// `(M + diag(armature)) a = B u − b` with `M` of the model without armature.
#[test]
fn free_dynamics_uses_armature_and_actuation_matrix() {
    let mut rng = SmallRng::seed_from_u64(5);
    for (model, actuation) in [
        (common::ur5(), None),
        (common::solo12(), Some("floating")),
        (common::g1(), Some("floating")),
        (common::ur5(), Some("dense")),
    ] {
        let nv = model.nv();
        let mut with_arm = (*model).clone();
        with_arm.armature = (0..nv).map(|k| 0.05 + 0.01 * k as f64).collect();
        let with_arm = Arc::new(with_arm);
        let b = match actuation {
            None => Actuation::full(&with_arm),
            Some("floating") => Actuation::floating_base(&with_arm).unwrap(),
            _ => Actuation::matrix(
                &with_arm,
                Mat::from_fn(nv, 3, |i, j| ((i + 2 * j) % 5) as f64 - 2.0).as_ref(),
            )
            .unwrap(),
        };
        let bm = b.to_matrix();
        let space = space_of(&with_arm);
        let ode = MultibodyFreeFwdDynamics::new(space.clone(), b).unwrap();
        let x = random_state(&space, &mut rng);
        let u = random_vec(&mut rng, ode.nu(), 2.0);
        let data = evaluated(&ode, &x, &u);
        // Reference.
        let (q, v) = x.split_at(model.nq());
        let mut md = model.create_data();
        let m = crba(&model, &mut md, q).unwrap().to_owned();
        let nle = nonlinear_effects(&model, &mut md, q, v).unwrap().to_vec();
        let marm = Mat::from_fn(nv, nv, |i, j| {
            m[(i, j)] + if i == j { with_arm.armature[i] } else { 0.0 }
        });
        let rhs = Mat::from_fn(nv, 1, |i, _| {
            (0..u.len()).map(|j| bm[(i, j)] * u[j]).sum::<f64>() - nle[i]
        });
        let a = marm.partial_piv_lu().solve(&rhs);
        let err = rel_error(&col(&data.xdot()[nv..]), &a);
        assert!(err < 1e-10, "{}: a off by {err:e}", model.name);
        // ∂a/∂u = M⁻¹ B.
        let minv_b = marm.partial_piv_lu().solve(&bm);
        let err = rel_error(&data.ju.as_ref().subrows(nv, nv).to_owned(), &minv_b);
        assert!(err < 1e-10, "{}: ∂a/∂u off by {err:e}", model.name);
        check_ode(&ode, &x, &u, FD).assert_ok();
    }
}

/// A column selection and the same `B` as a dense matrix give the same dynamics, and
/// the selection's `a` is ABA with `τ = B u` written out.
#[test]
fn selection_and_dense_actuation_agree() {
    let model = common::solo12();
    let space = space_of(&model);
    let joints = ["FL_KFE", "HR_HAA", "FR_HFE"];
    let sel = Actuation::joints(&model, &joints).unwrap();
    let dense = Actuation::matrix(&model, sel.to_matrix().as_ref()).unwrap();
    assert!(dense.actuated_dofs().is_none());
    let mut rng = SmallRng::seed_from_u64(8);
    let x = random_state(&space, &mut rng);
    let u = [0.3, -1.2, 0.7];
    let contacts = contacts_at_frames(&model, &FEET[..2], ContactSpec::point(ReferenceFrame::Local)).unwrap();
    let pairs: [(Box<dyn Ode>, Box<dyn Ode>); 2] = [
        (
            Box::new(MultibodyFreeFwdDynamics::new(space.clone(), sel.clone()).unwrap()),
            Box::new(MultibodyFreeFwdDynamics::new(space.clone(), dense.clone()).unwrap()),
        ),
        (
            Box::new(MultibodyConstraintFwdDynamics::new(space.clone(), sel, contacts.clone()).unwrap()),
            Box::new(MultibodyConstraintFwdDynamics::new(space.clone(), dense, contacts).unwrap()),
        ),
    ];
    for (a, b) in &pairs {
        let (da, db) = (evaluated(a.as_ref(), &x, &u), evaluated(b.as_ref(), &x, &u));
        assert!(rel_error(&col(da.xdot()), &col(db.xdot())) < 1e-14);
        assert!(rel_error(&da.jx, &db.jx) < 1e-14);
        assert!(rel_error(&da.ju, &db.ju) < 1e-14);
    }
    let mut tau = vec![0.0; model.nv()];
    for (name, uk) in joints.iter().zip(u) {
        tau[model.joints()[model.joint_id(name).unwrap()].idx_v] = uk;
    }
    let (q, v) = x.split_at(model.nq());
    let a = aba(&model, &mut model.create_data(), q, v, &tau).unwrap().to_vec();
    let d = evaluated(pairs[0].0.as_ref(), &x, &u);
    assert!(rel_error(&col(&d.xdot()[model.nv()..]), &col(&a)) < 1e-14);
}

/// A model of the derivative checks: free dynamics, or contacts with nonzero Baumgarte
/// gains and references away from the sampled states, underactuated floating bases.
struct Case {
    name: String,
    space: Arc<MultibodyPhaseSpace>,
    free: Option<Arc<MultibodyFreeFwdDynamics>>,
    contact: Option<Arc<MultibodyConstraintFwdDynamics>>,
}

impl Case {
    fn ode(&self) -> Arc<dyn Ode> {
        match (&self.free, &self.contact) {
            (Some(f), _) => f.clone(),
            (_, Some(c)) => c.clone(),
            _ => unreachable!("a case has one ODE"),
        }
    }
}

fn cases() -> Vec<Case> {
    let mut rng = SmallRng::seed_from_u64(21);
    let ur5 = common::ur5();
    let s = space_of(&ur5);
    let mut cases = vec![Case {
        name: "ur5 free".into(),
        free: Some(Arc::new(
            MultibodyFreeFwdDynamics::new(s.clone(), Actuation::full(&ur5)).unwrap(),
        )),
        space: s,
        contact: None,
    }];
    for (model, feet, kind) in [
        (common::solo12(), &FEET[..], ContactType::Contact3D),
        (common::g1(), &G1_FEET[..], ContactType::Contact6D),
    ] {
        let s = space_of(&model);
        let b = Arc::new(Actuation::floating_base(&model).unwrap());
        cases.push(Case {
            name: format!("{} free", model.name),
            space: s.clone(),
            free: Some(Arc::new(MultibodyFreeFwdDynamics::new(s.clone(), b.clone()).unwrap())),
            contact: None,
        });
        for rf in [ReferenceFrame::LocalWorldAligned, ReferenceFrame::Local] {
            let spec = ContactSpec {
                kind,
                reference_frame: rf,
                kp: 0.0,
                kd: 0.0,
            }
            .with_gains(30.0, 6.0);
            let mut contacts = contacts_at_frames(&model, feet, spec).unwrap();
            let q_ref = random_state(&s, &mut rng)[..model.nq()].to_vec();
            set_contact_references(&model, &mut contacts, &q_ref).unwrap();
            let ode = MultibodyConstraintFwdDynamics::new(s.clone(), b.clone(), contacts).unwrap();
            cases.push(Case {
                name: format!("{} {kind:?} {rf:?}", model.name),
                space: s.clone(),
                free: None,
                contact: Some(Arc::new(ode)),
            });
        }
    }
    cases
}

#[test]
fn ode_and_integrator_jacobians_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(4);
    for case in cases() {
        let (name, ode) = (&case.name, case.ode());
        let config: Arc<dyn Manifold> = case.space.configuration().clone();
        let dt = 0.01;
        let integrators: Vec<(&str, Box<dyn ExplicitDynamics>)> = vec![
            (
                "semi-implicit Euler",
                Box::new(SemiImplicitEuler::new(ode.clone(), config, dt).unwrap()),
            ),
            ("Euler", Box::new(ExplicitRungeKutta::euler(ode.clone(), dt).unwrap())),
            ("RK4", Box::new(ExplicitRungeKutta::rk4(ode.clone(), dt).unwrap())),
        ];
        for trial in 0..2 {
            let x = random_state(&case.space, &mut rng);
            let u = random_vec(&mut rng, ode.nu(), 3.0);
            let rep = check_ode(ode.as_ref(), &x, &u, FD);
            assert!(rep.passed(), "{name} trial {trial}: ODE {:?}", rep.errors);
            assert_acceleration_jacobians_are_the_bottom_rows(ode.as_ref(), &x, &u);
            for (iname, d) in &integrators {
                let rep = check_explicit_dynamics(d.as_ref(), &x, &u, FD);
                assert!(rep.passed(), "{name} trial {trial}: {iname} {:?}", rep.errors);
            }
        }
    }
}

/// Central differences of `λ(x ⊕ δ, u)` and `λ(x, u + δ)`.
fn fd_lambda(ode: &MultibodyConstraintFwdDynamics, x: &[f64], u: &[f64], eps: f64) -> (Mat<f64>, Mat<f64>) {
    let space = ode.phase_space();
    let (nc, ndx, nu) = (ode.nc(), space.ndx(), u.len());
    let mut d = ode.create_contact_data();
    let mut lambda = |x: &[f64], u: &[f64]| ode.contact_forces(x, u, &mut d).unwrap().to_vec();
    let (mut jx, mut ju) = (Mat::zeros(nc, ndx), Mat::zeros(nc, nu));
    let mut xp = vec![0.0; x.len()];
    for j in 0..ndx {
        let mut plus_minus = [vec![], vec![]];
        for (k, s) in [1.0, -1.0].into_iter().enumerate() {
            let mut dx = vec![0.0; ndx];
            dx[j] = s * eps;
            space.integrate(x, &dx, &mut xp);
            plus_minus[k] = lambda(&xp, u);
        }
        for i in 0..nc {
            jx[(i, j)] = (plus_minus[0][i] - plus_minus[1][i]) / (2.0 * eps);
        }
    }
    for j in 0..nu {
        let (mut up, mut um) = (u.to_vec(), u.to_vec());
        up[j] += eps;
        um[j] -= eps;
        let (lp, lm) = (lambda(x, &up), lambda(x, &um));
        for i in 0..nc {
            ju[(i, j)] = (lp[i] - lm[i]) / (2.0 * eps);
        }
    }
    (jx, ju)
}

#[test]
fn contact_force_jacobians_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(12);
    for case in cases() {
        let Some(ode) = &case.contact else { continue };
        let x = random_state(&case.space, &mut rng);
        let u = random_vec(&mut rng, ode.nu(), 3.0);
        let mut d = ode.create_contact_data();
        ode.contact_force_jacobians(&x, &u, &mut d).unwrap();
        let (jx, ju) = fd_lambda(ode, &x, &u, 1e-6);
        let (ex, eu) = (
            rel_error(&d.dlambda_dx().to_owned(), &jx),
            rel_error(&d.dlambda_du().to_owned(), &ju),
        );
        assert!(
            ex < FD.tol && eu < FD.tol,
            "{}: dλ/dx off by {ex:e}, dλ/du by {eu:e}",
            case.name
        );
        // The ODE's evaluation exposes the same λ.
        let mut od = ode.create_data();
        ode.evaluate(&x, &u, &mut od);
        let shared = MultibodyConstraintFwdDynamics::contact_data(&od).unwrap();
        assert_eq!(shared.lambda(), d.lambda());
        let m = ode.contacts()[0].size();
        assert_eq!(ode.contact_rows(1), m..2 * m);
        assert_eq!(ode.nc(), m * ode.contacts().len());
    }
}

/// One integrator step against the step written out with the multibody functions.
#[test]
fn integrator_steps_equal_hand_computations() {
    let mut rng = SmallRng::seed_from_u64(31);
    let dt = 0.02;
    for case in cases() {
        let model = case.space.model().clone();
        let (nq, nv) = (model.nq(), model.nv());
        let ode = case.ode();
        let x = random_state(&case.space, &mut rng);
        let u = random_vec(&mut rng, ode.nu(), 2.0);
        let (q, v) = x.split_at(nq);
        // a(x, u) by the multibody crate: τ = [0; u] (floating base) or u.
        let mut tau = vec![0.0; nv];
        tau[nv - u.len()..].copy_from_slice(&u);
        let mut md = model.create_data();
        let a = match &case.contact {
            None => aba(&model, &mut md, q, v, &tau).unwrap().to_vec(),
            Some(c) => {
                let mut cd = ContactData::new(&model, c.contacts()).unwrap();
                constraint_dynamics(&model, &mut md, c.contacts(), &mut cd, q, v, &tau).unwrap();
                cd.ddq().to_vec()
            }
        };
        let step = |vel: &[f64]| {
            let mut out = vec![0.0; nq];
            integrate(&model, q, &vel.iter().map(|w| dt * w).collect::<Vec<_>>(), &mut out).unwrap();
            out
        };
        let v_next: Vec<f64> = (0..nv).map(|i| v[i] + dt * a[i]).collect();
        let config = case.space.configuration().clone();
        let integrators: [(&str, Box<dyn ExplicitDynamics>, Vec<f64>); 2] = [
            // v' = v + dt a, q' = q ⊕ dt v'.
            (
                "semi-implicit Euler",
                Box::new(SemiImplicitEuler::new(ode.clone(), config, dt).unwrap()),
                [step(&v_next), v_next.clone()].concat(),
            ),
            // q' = q ⊕ dt v, v' = v + dt a.
            (
                "Euler",
                Box::new(ExplicitRungeKutta::euler(ode.clone(), dt).unwrap()),
                [step(v), v_next.clone()].concat(),
            ),
        ];
        for (iname, d, want) in integrators {
            let mut data = d.create_data();
            d.forward(&x, &u, &mut data);
            let err = rel_error(&col(data.xnext()), &col(&want));
            assert!(err < 1e-13, "{}: {iname} step off by {err:e}", case.name);
        }
    }
}

/// Without contacts, the constrained ODE is the free one.
#[test]
fn empty_contact_set_is_the_free_dynamics() {
    let model = common::solo12();
    let space = space_of(&model);
    let b = Arc::new(Actuation::floating_base(&model).unwrap());
    let free = MultibodyFreeFwdDynamics::new(space.clone(), b.clone()).unwrap();
    let none = MultibodyConstraintFwdDynamics::new(space.clone(), b, vec![]).unwrap();
    assert_eq!(none.nc(), 0);
    let mut rng = SmallRng::seed_from_u64(2);
    let x = random_state(&space, &mut rng);
    let u = random_vec(&mut rng, 12, 1.0);
    let (a, b) = (evaluated(&free, &x, &u), evaluated(&none, &x, &u));
    assert!(rel_error(&col(a.xdot()), &col(b.xdot())) < 1e-12);
    assert!(rel_error(&a.jx, &b.jx) < 1e-10);
    assert!(rel_error(&a.ju, &b.ju) < 1e-12);
}

/// Minimum-norm solution of `A z = g` for `A` of full row rank, `z = Aᵀ (A Aᵀ)⁻¹ g`:
/// an independent reference for the SVD of the helpers.
fn min_norm_reference(a: &Mat<f64>, g: &[f64]) -> Vec<f64> {
    let aat = a * a.transpose();
    let y = aat.partial_piv_lu().solve(&col(g));
    let z = a.transpose() * y;
    (0..z.nrows()).map(|i| z[(i, 0)]).collect()
}

#[test]
fn gravity_compensation_holds_a_fixed_base_robot_at_rest() {
    let model = common::ur5();
    let space = space_of(&model);
    let mut rng = SmallRng::seed_from_u64(9);
    let x = random_state(&space, &mut rng);
    let q = &x[..model.nq()];
    let ode = MultibodyFreeFwdDynamics::new(space.clone(), Actuation::full(&model)).unwrap();
    let u = ode.gravity_compensation(q).unwrap();
    let g = generalized_gravity(&model, &mut model.create_data(), q)
        .unwrap()
        .to_vec();
    assert!(rel_error(&col(&u), &col(&g)) < 1e-14);
    let rest = [q.to_vec(), vec![0.0; model.nv()]].concat();
    let d = evaluated(&ode, &rest, &u);
    assert!(d.xdot().iter().all(|a| a.abs() < 1e-9), "{:?}", d.xdot());
    // Three actuated joints of six, B = [e_1 e_2 e_3]: g has weight on the others.
    let three = Actuation::dofs(&model, &[0, 1, 2]).unwrap();
    let err = gravity_compensation(&model, &three, q).unwrap_err();
    assert!(err.to_string().contains("no solution"), "{err}");
}

#[test]
fn gravity_compensation_of_an_unsupported_floating_base_is_an_error() {
    let model = common::solo12();
    let q = gharial_multibody::neutral(&model);
    let err = gravity_compensation(&model, &Actuation::floating_base(&model).unwrap(), &q).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("gravity_compensation") && msg.contains("root_joint"),
        "{msg}"
    );
}

#[test]
fn quasi_static_torque_balances_gravity_with_minimum_norm() {
    let mut rng = SmallRng::seed_from_u64(17);
    for (model, feet, spec) in [
        (
            common::solo12(),
            &FEET[..],
            ContactSpec::point(ReferenceFrame::LocalWorldAligned),
        ),
        (common::solo12(), &FEET[..], ContactSpec::point(ReferenceFrame::Local)),
        (common::g1(), &G1_FEET[..], ContactSpec::frame(ReferenceFrame::Local)),
    ] {
        let space = space_of(&model);
        let b = Actuation::floating_base(&model).unwrap();
        let ode = MultibodyConstraintFwdDynamics::at_frames(space.clone(), b.clone(), feet, spec).unwrap();
        let x = random_state(&space, &mut rng);
        let q = &x[..model.nq()];
        let qs = ode.quasi_static_torque(q).unwrap();
        assert_eq!((qs.u.len(), qs.lambda.len()), (ode.nu(), ode.nc()));
        // Reference: A = [B, Jcᵀ] of full row rank, z = Aᵀ (A Aᵀ)⁻¹ g.
        let mut md = model.create_data();
        let g = generalized_gravity(&model, &mut md, q).unwrap().to_vec();
        let mut cd = ContactData::new(&model, ode.contacts()).unwrap();
        let zeros = vec![0.0; model.nv()];
        constraint_dynamics(&model, &mut md, ode.contacts(), &mut cd, q, &zeros, &zeros).unwrap();
        let (jc, bm) = (cd.constraint_jacobian().to_owned(), b.to_matrix());
        let (nu, nc) = (ode.nu(), ode.nc());
        let a = Mat::from_fn(
            model.nv(),
            nu + nc,
            |i, j| if j < nu { bm[(i, j)] } else { jc[(j - nu, i)] },
        );
        let z = min_norm_reference(&a, &g);
        let got = [qs.u.clone(), qs.lambda.clone()].concat();
        let err = rel_error(&col(&got), &col(&z));
        assert!(
            err < 1e-9,
            "{}: (u, λ) off the minimum-norm solution by {err:e}",
            model.name
        );
        // At rest with these controls the constrained dynamics give a = 0 and these λ.
        let rest = [q.to_vec(), zeros.clone()].concat();
        let mut d = ode.create_contact_data();
        let lambda = ode.contact_forces(&rest, &qs.u, &mut d).unwrap().to_vec();
        let scale = g.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        assert!(
            d.acceleration().iter().all(|a| a.abs() < 1e-9 * scale),
            "{:?}",
            d.acceleration()
        );
        assert!(rel_error(&col(&lambda), &col(&qs.lambda)) < 1e-9);
    }
}

#[test]
fn quasi_static_torque_on_one_foot_is_infeasible() {
    let model = common::solo12();
    let space = space_of(&model);
    let b = Actuation::floating_base(&model).unwrap();
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned);
    let ode = MultibodyConstraintFwdDynamics::at_frames(space, b, &FEET[..1], spec).unwrap();
    let q = gharial_multibody::neutral(&model);
    let err = ode.quasi_static_torque(&q).unwrap_err();
    assert!(
        err.to_string()
            .contains("quasi_static_torque: B u + Jcᵀ λ = g(q) has no solution"),
        "{err}"
    );
}

/// A solo12 floating-base state with contacts, and the ODEs for the bad-input tests.
fn solo_odes() -> (Arc<Model>, Vec<f64>, Vec<Box<dyn Ode>>) {
    let model = common::solo12();
    let space = space_of(&model);
    let b = Arc::new(Actuation::floating_base(&model).unwrap());
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned);
    let odes: Vec<Box<dyn Ode>> = vec![
        Box::new(MultibodyFreeFwdDynamics::new(space.clone(), b.clone()).unwrap()),
        Box::new(MultibodyConstraintFwdDynamics::at_frames(space.clone(), b, &FEET, spec).unwrap()),
    ];
    let x = random_state(&space, &mut SmallRng::seed_from_u64(1));
    (model, x, odes)
}

fn all_nan(m: &Mat<f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_nan()))
}

/// Bad `(x, u)` in `evaluate` and `jacobians`: NaN outputs, the error kept in the data.
#[test]
fn bad_inputs_give_nan_outputs_and_a_named_error() {
    let (model, x, odes) = solo_odes();
    let nq = model.nq();
    let u = vec![0.1; 12];
    let mut unnormalised = x.clone();
    unnormalised[6] *= 1.01; // qw of the base quaternion
    let mut nan_x = x.clone();
    nan_x[nq + 2] = f64::NAN;
    let bad: [(&str, &[f64], &[f64], &str); 5] = [
        ("short x", &x[1..], &u, "dimension mismatch in"),
        ("NaN in x", &nan_x, &u, "non-finite value in"),
        ("infinite u", &x, &[f64::INFINITY; 12], "control u"),
        ("wrong u size", &x, &u[1..], "control u (nu)"),
        ("unnormalised quaternion", &unnormalised, &u, "joint `root_joint`"),
    ];
    for ode in &odes {
        // Good data first: the failures must overwrite it.
        let mut data = evaluated(ode.as_ref(), &x, &u);
        assert!(last_error(&data).is_none());
        for (what, xb, ub, msg) in bad {
            ode.evaluate(xb, ub, &mut data);
            assert!(data.xdot().iter().all(|v| v.is_nan()), "{what}: xdot not NaN");
            let err = last_error(&data)
                .unwrap_or_else(|| panic!("{what}: no error kept"))
                .to_string();
            assert!(err.contains(msg), "{what}: {err}");
            ode.jacobians(xb, ub, &mut data);
            assert!(all_nan(&data.jx) && all_nan(&data.ju), "{what}: Jacobians not NaN");
            // Good input again: finite outputs, no error.
            ode.evaluate(&x, &u, &mut data);
            assert!(data.xdot().iter().all(|v| v.is_finite()) && last_error(&data).is_none());
        }
    }
    let free = MultibodyFreeFwdDynamics::new(space_of(&model), Actuation::floating_base(&model).unwrap()).unwrap();
    assert!(matches!(free.check_inputs(&x[1..], &u), Err(Error::Dimension { .. })));
    assert!(matches!(free.check_inputs(&nan_x, &u), Err(Error::NonFinite { .. })));
    assert!(matches!(
        free.check_inputs(&unnormalised, &u),
        Err(Error::InvalidModel(_))
    ));
    assert!(free.check_inputs(&x, &u).is_ok());
}

#[test]
fn bad_models_are_construction_errors() {
    let model = common::solo12();
    let space = space_of(&model);
    let spec = ContactSpec::point(ReferenceFrame::Local);
    let full = Actuation::full(&model);
    // Unknown contact frame: named.
    let err = MultibodyConstraintFwdDynamics::at_frames(space.clone(), full.clone(), &["FL_FOOT", "NOSE"], spec)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("contact 1 (frame `NOSE`)") && err.contains("not found"),
        "{err}"
    );
    // World frame, negative and NaN gains.
    for bad in [
        ContactSpec::point(ReferenceFrame::World),
        spec.with_gains(-1.0, 0.0),
        spec.with_gains(0.0, f64::NAN),
    ] {
        assert!(
            MultibodyConstraintFwdDynamics::at_frames(space.clone(), full.clone(), &FEET, bad).is_err(),
            "{bad:?}"
        );
    }
    let mut c = contacts_at_frames(&model, &FEET, spec).unwrap();
    c[2].kd = -3.0;
    let err = MultibodyConstraintFwdDynamics::new(space.clone(), full.clone(), c.clone())
        .unwrap_err()
        .to_string();
    assert!(err.contains("contact 2") && err.contains("kd"), "{err}");
    c[2].kd = 0.0;
    c[3].joint = 99;
    assert!(MultibodyConstraintFwdDynamics::new(space.clone(), full, c).is_err());
    // B of the wrong shape: rows, non-finite entries, another model's actuation.
    let err = Actuation::matrix(&model, Mat::zeros(17, 3).as_ref()).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Dimension {
                expected: 18,
                got: 17,
                ..
            }
        ),
        "{err}"
    );
    let mut b = Mat::zeros(18, 2);
    b[(4, 1)] = f64::NAN;
    assert!(matches!(
        Actuation::matrix(&model, b.as_ref()),
        Err(Error::NonFinite { .. })
    ));
    let ur5 = common::ur5();
    let err = MultibodyFreeFwdDynamics::new(space.clone(), Actuation::full(&ur5)).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Dimension {
                expected: 18,
                got: 6,
                ..
            }
        ),
        "{err}"
    );
    assert!(
        Actuation::dofs(&model, &[3, 18])
            .unwrap_err()
            .to_string()
            .contains("dof 18")
    );
    assert!(
        Actuation::joints(&model, &["FL_HAA", "TAIL"])
            .unwrap_err()
            .to_string()
            .contains("TAIL")
    );
    assert!(
        Actuation::floating_base(&ur5)
            .unwrap_err()
            .to_string()
            .contains("not a free flyer")
    );
}

/// A contact set with a rank-deficient Jacobian (the same foot twice, or two points of
/// one link): refused when the dynamics are made, naming both contacts, instead of a
/// singular KKT system at every evaluation.
#[test]
fn singular_contact_sets_are_refused_at_construction() {
    let model = common::solo12();
    let space = space_of(&model);
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned);
    let b = Actuation::floating_base(&model).unwrap();
    let err = MultibodyConstraintFwdDynamics::at_frames(space.clone(), b.clone(), &["FL_FOOT", "FL_FOOT"], spec)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("MultibodyConstraintFwdDynamics") && err.contains("contacts 0 and 1 both move with joint"),
        "{err}"
    );
    let mut contacts = contacts_at_frames(&model, &["FL_FOOT", "HR_FOOT"], spec).unwrap();
    contacts[1].joint = contacts[0].joint;
    assert!(MultibodyConstraintFwdDynamics::new(space.clone(), b.clone(), contacts).is_err());
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    assert!(MultibodyConstraintFwdDynamics::at_frames(space, b, &feet, spec).is_ok());
}

/// Spaces appear in error messages (e.g. of the integrators): their `Debug` names the
/// model and the sizes instead of printing the whole model (about 100 kB for g1).
#[test]
fn spaces_print_the_model_name_and_sizes() {
    let space = space_of(&common::g1());
    let text = format!("{space:?}");
    assert!(
        text.len() < 200 && text.contains("nq: 36") && text.contains("nv: 35"),
        "{text}"
    );
    let text = format!("{:?}", space.configuration());
    assert!(text.len() < 200 && text.contains("MultibodyConfiguration"), "{text}");
}

/// Implicit Euler on stiff contact dynamics (Solo-12 standing on three feet, `kd = 50`,
/// `dt = 0.02`, the four-feet quasi-static torques): one step is solved near the start.
/// Full Newton steps once carried the state to a spurious root of the step equation
/// (the base 5e6 m away) that the rollout returned as converged; the damped iteration
/// gives the physical step, checked by the step equation written out independently
/// (`q⁺ ⊖ q = dt v⁺`, `v⁺ - v = dt a(q⁺, v⁺, u)`).
#[test]
fn implicit_euler_steps_of_stiff_contact_dynamics_stay_near_the_start() {
    use gharial::dynamics::{Dynamics, ImplicitEuler};
    use gharial::problem::{Problem, ProblemData, StageModel};
    let mut model = (*common::solo12()).clone();
    model
        .load_srdf_file(common::data_dir().join("robots/solo.srdf"))
        .unwrap();
    let model = Arc::new(model);
    let q0 = model.reference_configuration("standing").unwrap().to_vec();
    let space = space_of(&model);
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned).with_gains(0.0, 50.0);
    let b = Actuation::floating_base(&model).unwrap();
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    let four = MultibodyConstraintFwdDynamics::at_frames(space.clone(), b.clone(), &feet, spec).unwrap();
    let u = four.quasi_static_torque(&q0).unwrap().u;
    let three = Arc::new(MultibodyConstraintFwdDynamics::at_frames(space.clone(), b, &feet[..3], spec).unwrap());
    let dt = 0.02;
    let step = Arc::new(ImplicitEuler::new(three.clone(), dt).unwrap());
    let manifold: Arc<dyn Manifold> = space.clone();
    let x0 = [q0.clone(), vec![0.0; model.nv()]].concat();
    let w = vec![1.0; manifold.ndx()];
    let cost = Arc::new(gharial::costs::QuadraticStateCost::diagonal(manifold.clone(), &x0, &w, 12).unwrap());
    let terminal = Arc::new(gharial::costs::QuadraticStateCost::diagonal(manifold.clone(), &x0, &w, 0).unwrap());
    let stage = StageModel::new(cost, Dynamics::Implicit(step)).unwrap();
    let problem = Problem::new(&x0, vec![stage], terminal).unwrap();
    let mut xs = vec![x0.clone(); 2];
    ProblemData::new(&problem, 1)
        .unwrap()
        .rollout(&problem, &mut xs, std::slice::from_ref(&u))
        .unwrap();
    let (x1, nq, nv) = (&xs[1], model.nq(), model.nv());
    assert!(
        (0..3).all(|i| (x1[i] - x0[i]).abs() < 0.01),
        "base moved to {:?}",
        &x1[..3]
    );
    let mut dq = vec![0.0; nv];
    gharial_multibody::difference(&model, &x0[..nq], &x1[..nq], &mut dq).unwrap();
    let mut data = three.create_data();
    three.evaluate(x1, &u, &mut data);
    for i in 0..nv {
        assert!((dq[i] - dt * x1[nq + i]).abs() < 1e-9, "q: {i}");
        assert!(
            (x1[nq + i] - x0[nq + i] - dt * data.xdot()[nv + i]).abs() < 1e-9,
            "v: {i}"
        );
    }
}
