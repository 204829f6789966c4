//! Analytical derivatives against central finite differences (q perturbed with
//! `integrate`) on random states, on a synthetic model with every joint type and armature
//! and on the robots of `tests/data`, including contacts with Baumgarte gains.

use faer::{Mat, MatRef};
use gharial_multibody::spatial::{Inertia, Mat3, Motion, Se3, Vec3};
use gharial_multibody::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::path::Path;

const EPS: f64 = 1e-6;
/// Central differences with ε = 1e-6: truncation ~ε², roundoff ~1e-16/ε.
const FD_TOL: f64 = 2e-6;

fn rel_err(got: MatRef<'_, f64>, want: MatRef<'_, f64>) -> f64 {
    assert_eq!((got.nrows(), got.ncols()), (want.nrows(), want.ncols()));
    let mut scale = 1.0f64;
    let mut diff = 0.0f64;
    for i in 0..got.nrows() {
        for j in 0..got.ncols() {
            scale = scale.max(want[(i, j)].abs());
            diff = diff.max((got[(i, j)] - want[(i, j)]).abs());
        }
    }
    diff / scale
}

fn assert_close(what: &str, got: MatRef<'_, f64>, want: MatRef<'_, f64>, tol: f64) {
    let e = rel_err(got, want);
    println!("{what:<50} rel err {e:.2e}");
    assert!(e < tol, "{what}: relative error {e:.3e} >= {tol:.0e}");
}

/// Central finite-difference Jacobian of `f` (m outputs) along the tangent directions of q.
fn fd_q(model: &Model, q: &[f64], m: usize, mut f: impl FnMut(&[f64], &mut [f64])) -> Mat<f64> {
    let nv = model.nv();
    let mut out = Mat::zeros(m, nv);
    let (mut qp, mut qm) = (vec![0.0; model.nq()], vec![0.0; model.nq()]);
    let (mut fp, mut fm) = (vec![0.0; m], vec![0.0; m]);
    for j in 0..nv {
        let mut dv = vec![0.0; nv];
        dv[j] = EPS;
        integrate(model, q, &dv, &mut qp).unwrap();
        dv[j] = -EPS;
        integrate(model, q, &dv, &mut qm).unwrap();
        f(&qp, &mut fp);
        f(&qm, &mut fm);
        for i in 0..m {
            out[(i, j)] = (fp[i] - fm[i]) / (2.0 * EPS);
        }
    }
    out
}

/// Central finite-difference Jacobian of `f` with respect to a vector argument.
fn fd_x(x: &[f64], m: usize, mut f: impl FnMut(&[f64], &mut [f64])) -> Mat<f64> {
    let n = x.len();
    let mut out = Mat::zeros(m, n);
    let (mut fp, mut fm) = (vec![0.0; m], vec![0.0; m]);
    let mut xp = x.to_vec();
    for j in 0..n {
        xp[j] = x[j] + EPS;
        f(&xp, &mut fp);
        xp[j] = x[j] - EPS;
        f(&xp, &mut fm);
        xp[j] = x[j];
        for i in 0..m {
            out[(i, j)] = (fp[i] - fm[i]) / (2.0 * EPS);
        }
    }
    out
}

fn col(x: &[f64]) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(x, x.len(), 1)
}

fn random_vec(rng: &mut SmallRng, n: usize) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(-1.0..1.0)).collect()
}

fn random_placement(rng: &mut SmallRng) -> Se3 {
    let phi = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    let p = Vec3::new(
        rng.random_range(-0.3..0.3),
        rng.random_range(-0.3..0.3),
        rng.random_range(-0.3..0.3),
    );
    Se3::new(exp3(&phi), p)
}

fn random_inertia(rng: &mut SmallRng) -> Inertia {
    let r = exp3(&Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    ));
    let d = Mat3::from_diagonal(&Vec3::new(
        rng.random_range(0.01..0.1),
        rng.random_range(0.01..0.1),
        rng.random_range(0.01..0.1),
    ));
    let c = Vec3::new(
        rng.random_range(-0.1..0.1),
        rng.random_range(-0.1..0.1),
        rng.random_range(-0.1..0.1),
    );
    Inertia::from_com(rng.random_range(0.5..2.0), c, r * d * r.transpose())
}

/// A tree with every joint type, random placements and inertias, armature, and frames.
fn synthetic_model(seed: u64) -> Model {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut m = Model::new("synthetic");
    let unaligned = Axis::Unaligned(Vec3::new(0.3, -0.5, 0.8).normalize());
    let chain = [
        (0usize, JointType::FreeFlyer),
        (1, JointType::Spherical),
        (2, JointType::Planar),
        (3, JointType::Revolute(unaligned)),
        (4, JointType::Prismatic(unaligned)),
        (1, JointType::Translation),
        (6, JointType::RevoluteUnbounded(Axis::Z)),
        (7, JointType::Prismatic(Axis::X)),
        (8, JointType::Revolute(Axis::Y)),
        (8, JointType::RevoluteUnbounded(unaligned)),
    ];
    for (k, (parent, kind)) in chain.iter().enumerate() {
        let placement = if k == 0 {
            Se3::identity()
        } else {
            random_placement(&mut rng)
        };
        let mut limits = JointLimits::unbounded(kind);
        for (lo, hi) in limits.lower.iter_mut().zip(limits.upper.iter_mut()) {
            if *hi > 1e10 {
                *lo = -1.0;
                *hi = 1.0;
            }
        }
        let id = m
            .add_joint(*parent, *kind, placement, &format!("j{k}"), limits)
            .unwrap();
        let y = random_inertia(&mut rng);
        m.append_body_to_joint(id, &y, &Se3::identity()).unwrap();
        let fp = random_placement(&mut rng);
        m.add_frame(Frame {
            name: format!("f{k}"),
            kind: FrameType::OpFrame,
            parent_joint: id,
            parent_frame: 0,
            placement: fp,
        })
        .unwrap();
    }
    for a in m.armature.iter_mut() {
        *a = rng.random_range(0.0..0.2);
    }
    m
}

fn robot(file: &str, root: RootJoint) -> Model {
    Model::from_urdf_file(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/robots")
            .join(file),
        root,
    )
    .unwrap()
}

struct State {
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    tau: Vec<f64>,
}

fn random_state(model: &Model, rng: &mut SmallRng) -> State {
    let mut lo = model.lower_position_limit.clone();
    let mut hi = model.upper_position_limit.clone();
    for (l, h) in lo.iter_mut().zip(hi.iter_mut()) {
        if *h - *l > 1e10 || !(*h - *l).is_finite() || *h <= *l {
            *l = -1.0;
            *h = 1.0;
        }
    }
    let q = random_configuration(model, rng, &lo, &hi).unwrap();
    let nv = model.nv();
    State {
        q,
        v: random_vec(rng, nv),
        a: random_vec(rng, nv),
        tau: random_vec(rng, nv),
    }
}

fn models() -> Vec<Model> {
    let mut solo = robot("solo12.urdf", RootJoint::FreeFlyer);
    for a in solo.armature.iter_mut().skip(6) {
        *a = 0.05;
    }
    vec![synthetic_model(7), solo, robot("ur5_robot.urdf", RootJoint::Fixed)]
}

#[test]
fn lie_group_jacobians_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(11);
    for model in models() {
        for _ in 0..3 {
            let s = random_state(&model, &mut rng);
            let q1 = random_state(&model, &mut rng).q;
            let (nq, nv) = (model.nq(), model.nv());
            // integrate(q, v) and its Jacobians, measured in the tangent space at the result.
            let mut r = vec![0.0; nq];
            integrate(&model, &s.q, &s.v, &mut r).unwrap();
            let mut back = vec![0.0; nv];
            difference(&model, &s.q, &r, &mut back).unwrap();
            assert_close("difference(q, integrate(q, v)) = v", col(&back), col(&s.v), 1e-12);
            let mut jac = Mat::zeros(nv, nv);
            dintegrate(&model, &s.q, &s.v, ArgumentPosition::Arg0, jac.as_mut()).unwrap();
            let fd = fd_q(&model, &s.q, nv, |q, out| {
                let mut x = vec![0.0; nq];
                integrate(&model, q, &s.v, &mut x).unwrap();
                difference(&model, &r, &x, out).unwrap();
            });
            assert_close(
                &format!("{} dintegrate/dq", model.name),
                jac.as_ref(),
                fd.as_ref(),
                FD_TOL,
            );
            dintegrate(&model, &s.q, &s.v, ArgumentPosition::Arg1, jac.as_mut()).unwrap();
            let fd = fd_x(&s.v, nv, |v, out| {
                let mut x = vec![0.0; nq];
                integrate(&model, &s.q, v, &mut x).unwrap();
                difference(&model, &r, &x, out).unwrap();
            });
            assert_close(
                &format!("{} dintegrate/dv", model.name),
                jac.as_ref(),
                fd.as_ref(),
                FD_TOL,
            );
            // difference(q0, q1) and its Jacobians.
            for (arg, which) in [(ArgumentPosition::Arg0, 0), (ArgumentPosition::Arg1, 1)] {
                ddifference(&model, &s.q, &q1, arg, jac.as_mut()).unwrap();
                let base = if which == 0 { s.q.clone() } else { q1.clone() };
                let fd = fd_q(&model, &base, nv, |q, out| {
                    let (a, b) = if which == 0 {
                        (q, q1.as_slice())
                    } else {
                        (s.q.as_slice(), q)
                    };
                    difference(&model, a, b, out).unwrap();
                });
                assert_close(
                    &format!("{} ddifference/dq{which}", model.name),
                    jac.as_ref(),
                    fd.as_ref(),
                    FD_TOL,
                );
            }
        }
    }
}

#[test]
fn dynamics_derivatives_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(12);
    for model in models() {
        let nv = model.nv();
        let mut data = model.create_data();
        let mut tmp = model.create_data();
        for _ in 0..2 {
            let s = random_state(&model, &mut rng);
            compute_rnea_derivatives(&model, &mut data, &s.q, &s.v, &s.a).unwrap();
            let fd = fd_q(&model, &s.q, nv, |q, out| {
                out.copy_from_slice(rnea(&model, &mut tmp, q, &s.v, &s.a).unwrap())
            });
            assert_close(&format!("{} dtau_dq", model.name), data.dtau_dq(), fd.as_ref(), FD_TOL);
            let fd = fd_x(&s.v, nv, |v, out| {
                out.copy_from_slice(rnea(&model, &mut tmp, &s.q, v, &s.a).unwrap())
            });
            assert_close(&format!("{} dtau_dv", model.name), data.dtau_dv(), fd.as_ref(), FD_TOL);
            let fd = fd_x(&s.a, nv, |a, out| {
                out.copy_from_slice(rnea(&model, &mut tmp, &s.q, &s.v, a).unwrap())
            });
            assert_close(
                &format!("{} dtau_da = M", model.name),
                data.mass_matrix(),
                fd.as_ref(),
                FD_TOL,
            );
            let m = crba(&model, &mut tmp, &s.q).unwrap().to_owned();
            assert_close(
                &format!("{} crba = dtau_da", model.name),
                m.as_ref(),
                data.mass_matrix(),
                1e-12,
            );

            compute_aba_derivatives(&model, &mut data, &s.q, &s.v, &s.tau).unwrap();
            let fd = fd_q(&model, &s.q, nv, |q, out| {
                out.copy_from_slice(aba(&model, &mut tmp, q, &s.v, &s.tau).unwrap())
            });
            assert_close(&format!("{} ddq_dq", model.name), data.ddq_dq(), fd.as_ref(), FD_TOL);
            let fd = fd_x(&s.v, nv, |v, out| {
                out.copy_from_slice(aba(&model, &mut tmp, &s.q, v, &s.tau).unwrap())
            });
            assert_close(&format!("{} ddq_dv", model.name), data.ddq_dv(), fd.as_ref(), FD_TOL);
            let fd = fd_x(&s.tau, nv, |t, out| {
                out.copy_from_slice(aba(&model, &mut tmp, &s.q, &s.v, t).unwrap())
            });
            assert_close(
                &format!("{} ddq_dtau = Minv", model.name),
                data.minv(),
                fd.as_ref(),
                FD_TOL,
            );
            // ABA is the inverse of RNEA, Minv the inverse of M.
            let ddq = data.ddq().to_vec();
            let back = rnea(&model, &mut tmp, &s.q, &s.v, &ddq).unwrap().to_vec();
            assert_close(
                &format!("{} rnea(aba(tau)) = tau", model.name),
                col(&back),
                col(&s.tau),
                1e-11,
            );
            let minv = compute_minverse(&model, &mut tmp, &s.q).unwrap().to_owned();
            let prod = &minv * &m;
            assert_close(
                &format!("{} Minv M = I", model.name),
                prod.as_ref(),
                Mat::<f64>::identity(nv, nv).as_ref(),
                1e-11,
            );
        }
    }
}

#[test]
fn kinematics_derivatives_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(13);
    for model in models() {
        let nv = model.nv();
        let mut data = model.create_data();
        let mut tmp = model.create_data();
        let s = random_state(&model, &mut rng);
        compute_forward_kinematics_derivatives(&model, &mut data, &s.q, &s.v, &s.a).unwrap();
        let frame = model.nframes() - 1;
        let mats: Vec<Mat<f64>> = (0..5).map(|_| Mat::zeros(6, nv)).collect();
        let [mut dvq, mut dvv, mut daq, mut dav, mut daa] = <[Mat<f64>; 5]>::try_from(mats).unwrap();
        for rf in [
            ReferenceFrame::Local,
            ReferenceFrame::World,
            ReferenceFrame::LocalWorldAligned,
        ] {
            frame_velocity_derivatives(&model, &data, frame, rf, dvq.as_mut(), dvv.as_mut()).unwrap();
            frame_acceleration_derivatives(
                &model,
                &data,
                frame,
                rf,
                dvq.as_mut(),
                daq.as_mut(),
                dav.as_mut(),
                daa.as_mut(),
            )
            .unwrap();
            let vel = |tmp: &mut Data, q: &[f64], v: &[f64], a: &[f64], out: &mut [f64], acc: bool| {
                forward_kinematics(&model, tmp, q, v, a).unwrap();
                let m = if acc {
                    frame_acceleration(&model, tmp, frame, rf)
                } else {
                    frame_velocity(&model, tmp, frame, rf)
                };
                out.copy_from_slice(&m.unwrap().to_array());
            };
            let mut fq_v = fd_q(&model, &s.q, 6, |q, out| vel(&mut tmp, q, &s.v, &s.a, out, false));
            let mut fq_a = fd_q(&model, &s.q, 6, |q, out| vel(&mut tmp, q, &s.v, &s.a, out, true));
            if rf == ReferenceFrame::LocalWorldAligned {
                // Pinocchio's LWA convention: remove the term of the moving origin,
                // [ω × J_lin, 0] and [α × J_lin, 0].
                forward_kinematics(&model, &mut tmp, &s.q, &s.v, &s.a).unwrap();
                let w = frame_velocity(&model, &tmp, frame, rf).unwrap().angular;
                let al = frame_acceleration(&model, &tmp, frame, rf).unwrap().angular;
                for j in 0..nv {
                    let jl = Vec3::new(daa[(0, j)], daa[(1, j)], daa[(2, j)]);
                    let (cv, ca) = (w.cross(&jl), al.cross(&jl));
                    for r in 0..3 {
                        fq_v[(r, j)] -= cv[r];
                        fq_a[(r, j)] -= ca[r];
                    }
                }
            }
            let name = format!("{} {:?}", model.name, rf);
            assert_close(&format!("{name} dv_dq"), dvq.as_ref(), fq_v.as_ref(), FD_TOL);
            assert_close(&format!("{name} da_dq"), daq.as_ref(), fq_a.as_ref(), FD_TOL);
            let fd = fd_x(&s.v, 6, |v, out| vel(&mut tmp, &s.q, v, &s.a, out, false));
            assert_close(&format!("{name} dv_dv"), dvv.as_ref(), fd.as_ref(), FD_TOL);
            let fd = fd_x(&s.v, 6, |v, out| vel(&mut tmp, &s.q, v, &s.a, out, true));
            assert_close(&format!("{name} da_dv"), dav.as_ref(), fd.as_ref(), FD_TOL);
            let fd = fd_x(&s.a, 6, |a, out| vel(&mut tmp, &s.q, &s.v, a, out, true));
            assert_close(&format!("{name} da_da"), daa.as_ref(), fd.as_ref(), FD_TOL);
            // Frame Jacobian: J v = frame velocity.
            compute_joint_jacobians(&model, &mut tmp, &s.q).unwrap();
            let mut jac = Mat::zeros(6, nv);
            frame_jacobian(&model, &tmp, frame, rf, jac.as_mut()).unwrap();
            let jv = &jac * col(&s.v);
            forward_kinematics(&model, &mut tmp, &s.q, &s.v, &s.a).unwrap();
            let fv = frame_velocity(&model, &tmp, frame, rf).unwrap().to_array();
            assert_close(&format!("{name} J v = frame velocity"), jv.as_ref(), col(&fv), 1e-12);
        }
        // Centre-of-mass Jacobian against finite differences of the centre of mass.
        let jcom = jacobian_center_of_mass(&model, &mut data, &s.q).unwrap().to_owned();
        let zeros = vec![0.0; nv];
        let fd = fd_q(&model, &s.q, 3, |q, out| {
            out.copy_from_slice(center_of_mass(&model, &mut tmp, q, &zeros, &zeros).unwrap().as_slice())
        });
        assert_close(
            &format!("{} com jacobian", model.name),
            jcom.as_ref(),
            fd.as_ref(),
            FD_TOL,
        );
    }
}

fn contact_setups(
    model: &Model,
    frames: &[&str],
    kind: ContactType,
    rf: ReferenceFrame,
    gains: bool,
) -> Vec<ContactModel> {
    frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let mut c = ContactModel::from_frame(model, kind, model.frame_id(f).unwrap(), rf).unwrap();
            if gains {
                c.kp = 10.0 + k as f64;
                c.kd = 3.0;
                c.reference = Se3::new(exp3(&Vec3::new(0.1, -0.2, 0.3)), Vec3::new(0.2, 0.1, -0.3));
            }
            c
        })
        .collect()
}

#[test]
fn constraint_dynamics_derivatives_match_finite_differences() {
    let mut rng = SmallRng::seed_from_u64(14);
    let mut solo = robot("solo12.urdf", RootJoint::FreeFlyer);
    for a in solo.armature.iter_mut().skip(6) {
        *a = 0.01;
    }
    let g1 = robot("g1_29dof_rev_1_0.urdf", RootJoint::FreeFlyer);
    let synth = synthetic_model(5);
    let cases: Vec<(&Model, Vec<&str>, ContactType)> = vec![
        (
            &solo,
            vec!["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
            ContactType::Contact3D,
        ),
        (
            &g1,
            vec!["left_ankle_roll_link", "right_ankle_roll_link"],
            ContactType::Contact6D,
        ),
        (&synth, vec!["f4", "f9"], ContactType::Contact3D),
        (&synth, vec!["f4", "f9"], ContactType::Contact6D),
    ];
    for (model, frames, kind) in cases {
        let nv = model.nv();
        for rf in [ReferenceFrame::Local, ReferenceFrame::LocalWorldAligned] {
            for gains in [false, true] {
                let contacts = contact_setups(model, &frames, kind, rf, gains);
                let name = format!("{} {:?} {:?} gains={gains}", model.name, kind, rf);
                let s = random_state(model, &mut rng);
                let mut data = model.create_data();
                let mut cd = ContactData::new(model, &contacts).unwrap();
                let nc = cd.nc();
                constraint_dynamics(model, &mut data, &contacts, &mut cd, &s.q, &s.v, &s.tau).unwrap();
                check_constraint_residuals(model, &contacts, &cd, &s, &name);
                compute_constraint_dynamics_derivatives(model, &mut data, &contacts, &mut cd).unwrap();
                let mut tmp = model.create_data();
                let mut tcd = ContactData::new(model, &contacts).unwrap();
                let mut solve = |q: &[f64], v: &[f64], t: &[f64], out: &mut [f64]| {
                    constraint_dynamics(model, &mut tmp, &contacts, &mut tcd, q, v, t).unwrap();
                    out[..nv].copy_from_slice(tcd.ddq());
                    out[nv..].copy_from_slice(tcd.lambda());
                };
                let fq = fd_q(model, &s.q, nv + nc, |q, out| solve(q, &s.v, &s.tau, out));
                let fv = fd_x(&s.v, nv + nc, |v, out| solve(&s.q, v, &s.tau, out));
                let ft = fd_x(&s.tau, nv + nc, |t, out| solve(&s.q, &s.v, t, out));
                let tol = FD_TOL;
                assert_close(&format!("{name} ddq_dq"), cd.ddq_dq(), fq.as_ref().subrows(0, nv), tol);
                assert_close(&format!("{name} ddq_dv"), cd.ddq_dv(), fv.as_ref().subrows(0, nv), tol);
                assert_close(
                    &format!("{name} ddq_dtau"),
                    cd.ddq_dtau(),
                    ft.as_ref().subrows(0, nv),
                    tol,
                );
                assert_close(
                    &format!("{name} dlambda_dq"),
                    cd.dlambda_dq(),
                    fq.as_ref().subrows(nv, nc),
                    tol,
                );
                assert_close(
                    &format!("{name} dlambda_dv"),
                    cd.dlambda_dv(),
                    fv.as_ref().subrows(nv, nc),
                    tol,
                );
                assert_close(
                    &format!("{name} dlambda_dtau"),
                    cd.dlambda_dtau(),
                    ft.as_ref().subrows(nv, nc),
                    tol,
                );
            }
        }
    }
}

/// `M ddq + nle = tau + Jcᵀ λ` and `a_c + Kd v_c + Kp e = 0`, recomputed with the
/// kinematics functions.
fn check_constraint_residuals(model: &Model, contacts: &[ContactModel], cd: &ContactData, s: &State, name: &str) {
    let nv = model.nv();
    let mut d = model.create_data();
    let m = crba(model, &mut d, &s.q).unwrap().to_owned();
    let nle = nonlinear_effects(model, &mut d, &s.q, &s.v).unwrap().to_vec();
    let lhs = &m * col(cd.ddq());
    let jtl = cd.constraint_jacobian().transpose() * col(cd.lambda());
    let res: Vec<f64> = (0..nv).map(|i| lhs[(i, 0)] + nle[i] - s.tau[i] - jtl[(i, 0)]).collect();
    let scale = s.tau.iter().chain(nle.iter()).fold(1.0f64, |m, x| m.max(x.abs()));
    let r = res.iter().fold(0.0f64, |m, x| m.max(x.abs())) / scale;
    println!("{name:<50} dynamics residual {r:.2e}");
    assert!(r < 1e-10, "{name}: dynamics residual {r:.3e}");
    let fscale = cd.ddq().iter().fold(1.0f64, |m, x| m.max(x.abs()));
    for c in contacts {
        let frame = model.nframes();
        let mut fm = model.clone();
        fm.add_frame(Frame {
            name: "c".into(),
            kind: FrameType::OpFrame,
            parent_joint: c.joint,
            parent_frame: 0,
            placement: c.placement,
        })
        .unwrap();
        let rf = c.reference_frame;
        let mut d = fm.create_data();
        forward_kinematics(&fm, &mut d, &s.q, &s.v, cd.ddq()).unwrap();
        let v = frame_velocity(&fm, &d, frame, rf).unwrap();
        update_frame_placements(&fm, &mut d).unwrap();
        let o_mc = *d.frame_placement(frame);
        let gval: Motion = match c.kind {
            ContactType::Contact3D => {
                let a = frame_classical_acceleration(&fm, &d, frame, rf).unwrap();
                let e = o_mc.translation - c.reference.translation;
                let e = if rf == ReferenceFrame::Local {
                    o_mc.rotation.transpose() * e
                } else {
                    e
                };
                Motion::new(a.linear + v.linear * c.kd + e * c.kp, Vec3::zeros())
            }
            ContactType::Contact6D => {
                let a = frame_acceleration(&fm, &d, frame, rf).unwrap();
                let e = log6(&c.reference.inv_compose(&o_mc));
                let e = if rf == ReferenceFrame::Local {
                    e
                } else {
                    Motion::new(o_mc.rotation * e.linear, o_mc.rotation * e.angular)
                };
                a + v * c.kd + e * c.kp
            }
        };
        let r = gval.amax() / fscale;
        assert!(r < 1e-10, "{name}: constraint residual {r:.3e}");
    }
}
