//! Bad input never panics and never gives `Ok` with NaN: the fuzz corpus replayed through
//! the fuzz targets' own entry functions, overflowing states (1e200 velocities) through
//! every family of algorithms, the quaternion policy, and property tests of random,
//! broken robot states on ur5, solo12 and g1.

#[path = "../fuzz/src/lib.rs"]
mod fuzz_entry;

use fuzz_entry::{Outcome, run_algorithms};
use gharial_multibody::*;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use rand::SeedableRng;
use rand::rngs::SmallRng;
use std::cell::Cell;
use std::path::{Path, PathBuf};

fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn load(file: &str, root: RootJoint) -> Model {
    Model::from_urdf_file(crate_dir().join("tests/data/robots").join(file), root).unwrap()
}

/// Replays every file of `fuzz/corpus/<kind>` through `entry`, catching panics: a file
/// named `ok_*` must load with the default options, one named `err_*` must be refused.
fn replay(kind: &str, entry: fn(&[u8]) -> Outcome) -> usize {
    let dir = crate_dir().join("fuzz/corpus").join(kind);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    let mut failures = Vec::new();
    for f in &files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let bytes = std::fs::read(f).unwrap();
        match std::panic::catch_unwind(|| entry(&bytes)) {
            Err(_) => failures.push(format!("{name}: panicked")),
            Ok(out) => {
                let loaded = out.default_ok;
                if name.starts_with("ok_") != loaded {
                    let first: Vec<&String> = out.errors.iter().take(3).collect();
                    failures.push(format!("{name}: default load ok = {loaded}; first errors {first:?}"));
                }
                println!("{name:<45} {} ok, {} errors", out.ok, out.errors.len());
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    files.len()
}

#[test]
fn urdf_corpus_gives_ok_or_clear_errors() {
    let n = replay("urdf", fuzz_entry::urdf);
    assert!(n >= 40, "only {n} URDF corpus files");
}

#[test]
fn srdf_corpus_gives_ok_or_clear_errors() {
    let n = replay("srdf", fuzz_entry::srdf);
    assert!(n >= 20, "only {n} SRDF corpus files");
}

fn is_overflow<T: std::fmt::Debug>(what: &str, r: Result<T>) {
    match r {
        Err(Error::NonFiniteResult { .. }) => {}
        other => panic!("{what}: expected a NonFiniteResult error, got {other:?}"),
    }
}

/// Velocities near the largest double overflow in the first sums: the frame velocity
/// derivatives of what the failed pass left in `data` are an error, not infinities.
#[test]
fn overflowed_velocity_data_gives_a_frame_velocity_derivative_error() {
    let model = load("solo12.urdf", RootJoint::FreeFlyer);
    let (nq, nv) = (model.nq(), model.nv());
    let mut data = model.create_data();
    let q = random_configuration(&model, &mut SmallRng::seed_from_u64(2), &vec![-1.0; nq], &vec![1.0; nq]).unwrap();
    let v = vec![1.5e308; nv];
    let z = vec![0.0; nv];
    is_overflow(
        "compute_forward_kinematics_derivatives",
        compute_forward_kinematics_derivatives(&model, &mut data, &q, &v, &z),
    );
    let foot = model.frame_id("FL_FOOT").unwrap();
    let (mut m0, mut m1) = (faer::Mat::zeros(6, nv), faer::Mat::zeros(6, nv));
    for rf in [
        ReferenceFrame::LocalWorldAligned,
        ReferenceFrame::Local,
        ReferenceFrame::World,
    ] {
        is_overflow(
            "frame_velocity_derivatives",
            frame_velocity_derivatives(&model, &data, foot, rf, m0.as_mut(), m1.as_mut()),
        );
    }
}

/// Velocities of 1e200 are finite, but their squares overflow: every algorithm that
/// takes v must say so instead of returning NaN.
#[test]
fn huge_velocities_give_overflow_errors() {
    let model = load("solo12.urdf", RootJoint::FreeFlyer);
    let (nq, nv) = (model.nq(), model.nv());
    let mut data = model.create_data();
    let q = random_configuration(&model, &mut SmallRng::seed_from_u64(1), &vec![-1.0; nq], &vec![1.0; nq]).unwrap();
    let (v, z) = (vec![1e200; nv], vec![0.0; nv]);
    let foot = model.frame_id("FL_FOOT").unwrap();
    let rf = ReferenceFrame::LocalWorldAligned;
    is_overflow("forward_kinematics", forward_kinematics(&model, &mut data, &q, &v, &z));
    // What a failed pass left in `data` is not returned as a result either (the
    // velocities, 1e200, are finite; the accelerations are not).
    assert!(frame_velocity(&model, &data, foot, rf).is_ok());
    is_overflow("frame_acceleration", frame_acceleration(&model, &data, foot, rf));
    is_overflow("joint_acceleration", joint_acceleration(&data, 4, rf));
    is_overflow("center_of_mass", center_of_mass(&model, &mut data, &q, &v, &z));
    is_overflow("rnea", rnea(&model, &mut data, &q, &v, &z));
    is_overflow("nonlinear_effects", nonlinear_effects(&model, &mut data, &q, &v));
    is_overflow("aba", aba(&model, &mut data, &q, &v, &z));
    is_overflow(
        "compute_forward_kinematics_derivatives",
        compute_forward_kinematics_derivatives(&model, &mut data, &q, &v, &z),
    );
    let mut m: Vec<faer::Mat<f64>> = (0..4).map(|_| faer::Mat::zeros(6, nv)).collect();
    let [m0, m1, m2, m3] = &mut m[..] else { unreachable!() };
    assert!(frame_velocity_derivatives(&model, &data, foot, rf, m0.as_mut(), m1.as_mut()).is_ok());
    is_overflow(
        "frame_acceleration_derivatives",
        frame_acceleration_derivatives(
            &model,
            &data,
            foot,
            rf,
            m0.as_mut(),
            m1.as_mut(),
            m2.as_mut(),
            m3.as_mut(),
        ),
    );
    is_overflow(
        "compute_rnea_derivatives",
        compute_rnea_derivatives(&model, &mut data, &q, &v, &z),
    );
    is_overflow(
        "compute_aba_derivatives",
        compute_aba_derivatives(&model, &mut data, &q, &v, &z),
    );
    let contacts: Vec<ContactModel> = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
        .iter()
        .map(|f| ContactModel::from_frame(&model, ContactType::Contact3D, model.frame_id(f).unwrap(), rf).unwrap())
        .collect();
    let mut cdata = ContactData::new(&model, &contacts).unwrap();
    is_overflow(
        "constraint_dynamics",
        constraint_dynamics(&model, &mut data, &contacts, &mut cdata, &q, &v, &z),
    );
    // The derivatives are not taken at a failed solution.
    let r = compute_constraint_dynamics_derivatives(&model, &mut data, &contacts, &mut cdata);
    assert!(matches!(r, Err(Error::Invalid(ref m)) if m.contains("failed")), "{r:?}");
    // A huge velocity gain does not enter the solution at v = 0, but its derivative
    // with respect to v overflows.
    let stiff: Vec<ContactModel> = contacts
        .iter()
        .map(|c| ContactModel { kd: 1e308, ..c.clone() })
        .collect();
    let mut cdata = ContactData::new(&model, &stiff).unwrap();
    constraint_dynamics(&model, &mut data, &stiff, &mut cdata, &q, &z, &z).unwrap();
    is_overflow(
        "compute_constraint_dynamics_derivatives",
        compute_constraint_dynamics_derivatives(&model, &mut data, &stiff, &mut cdata),
    );
    let mut out = vec![0.0; nq];
    let big_q: Vec<f64> = q
        .iter()
        .enumerate()
        .map(|(k, &x)| if (3..7).contains(&k) { x } else { 1e308 })
        .collect();
    is_overflow("integrate", integrate(&model, &big_q, &vec![1e308; nv], &mut out));
}

/// Two prismatic joints along x and a revolute joint: q = 1e308 for both prismatic
/// joints puts the last bodies at 2e308 = inf.
const PRISMATIC_CHAIN: &str = r#"<robot name="p">
  <link name="l0"/>
  <link name="l1"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="l2"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="l3"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="p1" type="prismatic"><parent link="l0"/><child link="l1"/><axis xyz="1 0 0"/><limit effort="1" velocity="1"/></joint>
  <joint name="p2" type="prismatic"><parent link="l1"/><child link="l2"/><axis xyz="1 0 0"/><limit effort="1" velocity="1"/></joint>
  <joint name="r3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit effort="1" velocity="1"/></joint>
</robot>"#;

/// Finite but huge configurations overflow the placements: the algorithms that take
/// only q must say so too.
#[test]
fn huge_configurations_give_overflow_errors() {
    let model = Model::from_urdf_str(PRISMATIC_CHAIN, RootJoint::Fixed).unwrap();
    let mut data = model.create_data();
    let (q, z) = ([1e308, 1e308, 0.5], [0.0; 3]);
    let last = model.nframes() - 1;
    let mut j = faer::Mat::<f64>::zeros(6, 3);
    is_overflow(
        "forward_kinematics_placements",
        forward_kinematics_placements(&model, &mut data, &q),
    );
    is_overflow("update_frame_placements", update_frame_placements(&model, &mut data));
    is_overflow(
        "compute_joint_jacobians",
        compute_joint_jacobians(&model, &mut data, &q),
    );
    is_overflow(
        "frame_jacobian",
        frame_jacobian(&model, &data, last, ReferenceFrame::Local, j.as_mut()),
    );
    is_overflow("generalized_gravity", generalized_gravity(&model, &mut data, &q));
    is_overflow("crba", crba(&model, &mut data, &q));
    is_overflow("compute_minverse", compute_minverse(&model, &mut data, &q));
    is_overflow(
        "jacobian_center_of_mass",
        jacobian_center_of_mass(&model, &mut data, &q),
    );
    is_overflow("aba", aba(&model, &mut data, &q, &z, &z));
    let mut out = [0.0; 3];
    is_overflow("difference", difference(&model, &[-1e308; 3], &[1e308; 3], &mut out));
    // The same model at moderate q works.
    assert!(aba(&model, &mut data, &[1.0, 2.0, 0.5], &z, &z).is_ok());
}

/// solo12's configuration with its free-flyer quaternion scaled by `s`.
fn solo_q_scaled(model: &Model, s: f64) -> Vec<f64> {
    let nq = model.nq();
    let mut q = random_configuration(model, &mut SmallRng::seed_from_u64(2), &vec![-1.0; nq], &vec![1.0; nq]).unwrap();
    q[3..7].iter_mut().for_each(|x| *x *= s);
    q
}

fn not_normalized_at(what: &str, r: Result<impl std::fmt::Debug>, joint: &str) {
    match r {
        Err(Error::NotNormalized { joint: j, .. }) if j == joint => {}
        other => panic!("{what}: expected NotNormalized naming {joint}, got {other:?}"),
    }
}

#[test]
fn non_unit_quaternions_are_rejected_naming_the_joint() {
    let model = load("solo12.urdf", RootJoint::FreeFlyer);
    let nv = model.nv();
    let mut data = model.create_data();
    let q = solo_q_scaled(&model, 3.0);
    let good = solo_q_scaled(&model, 1.0);
    let (v, z) = (vec![0.1; nv], vec![0.0; nv]);
    let err = aba(&model, &mut data, &q, &v, &z).unwrap_err();
    assert!(
        matches!(&err, Error::NotNormalized { joint, norm, .. } if joint == "root_joint" && (norm - 3.0).abs() < 1e-12),
        "{err:?}"
    );
    assert!(err.to_string().contains("`root_joint`"), "{err}");
    let mut j = faer::Mat::<f64>::zeros(nv, nv);
    let mut qo = vec![0.0; model.nq()];
    let mut vo = vec![0.0; nv];
    let rj = "root_joint";
    not_normalized_at(
        "forward_kinematics",
        forward_kinematics(&model, &mut data, &q, &v, &z),
        rj,
    );
    not_normalized_at(
        "forward_kinematics_placements",
        forward_kinematics_placements(&model, &mut data, &q),
        rj,
    );
    not_normalized_at(
        "compute_joint_jacobians",
        compute_joint_jacobians(&model, &mut data, &q),
        rj,
    );
    not_normalized_at("rnea", rnea(&model, &mut data, &q, &v, &z), rj);
    not_normalized_at("nonlinear_effects", nonlinear_effects(&model, &mut data, &q, &v), rj);
    not_normalized_at("generalized_gravity", generalized_gravity(&model, &mut data, &q), rj);
    not_normalized_at("crba", crba(&model, &mut data, &q), rj);
    not_normalized_at("compute_minverse", compute_minverse(&model, &mut data, &q), rj);
    not_normalized_at("center_of_mass", center_of_mass(&model, &mut data, &q, &v, &z), rj);
    not_normalized_at(
        "jacobian_center_of_mass",
        jacobian_center_of_mass(&model, &mut data, &q),
        rj,
    );
    not_normalized_at(
        "compute_forward_kinematics_derivatives",
        compute_forward_kinematics_derivatives(&model, &mut data, &q, &v, &z),
        rj,
    );
    not_normalized_at(
        "compute_rnea_derivatives",
        compute_rnea_derivatives(&model, &mut data, &q, &v, &z),
        rj,
    );
    not_normalized_at(
        "compute_aba_derivatives",
        compute_aba_derivatives(&model, &mut data, &q, &v, &z),
        rj,
    );
    let contacts = vec![
        ContactModel::from_frame(
            &model,
            ContactType::Contact3D,
            model.frame_id("FL_FOOT").unwrap(),
            ReferenceFrame::Local,
        )
        .unwrap(),
    ];
    let mut cdata = ContactData::new(&model, &contacts).unwrap();
    not_normalized_at(
        "constraint_dynamics",
        constraint_dynamics(&model, &mut data, &contacts, &mut cdata, &q, &v, &z),
        rj,
    );
    not_normalized_at("integrate", integrate(&model, &q, &v, &mut qo), rj);
    not_normalized_at("difference q0", difference(&model, &q, &good, &mut vo), rj);
    not_normalized_at("difference q1", difference(&model, &good, &q, &mut vo), rj);
    for arg in [ArgumentPosition::Arg0, ArgumentPosition::Arg1] {
        not_normalized_at("dintegrate", dintegrate(&model, &q, &v, arg, j.as_mut()), rj);
        not_normalized_at("ddifference", ddifference(&model, &good, &q, arg, j.as_mut()), rj);
    }
    // A (cos, sin) pair of norm 3 is refused the same way.
    let pendulum = load("double_pendulum_continuous.urdf", RootJoint::Fixed);
    let mut pd = pendulum.create_data();
    let name = pendulum.joint_names()[2].clone();
    not_normalized_at(
        "rnea",
        rnea(&pendulum, &mut pd, &[1.0, 0.0, 0.0, 3.0], &[0.0; 2], &[0.0; 2]),
        &name,
    );
    // `normalize` accepts it and repairs it.
    let mut qn = q.clone();
    normalize(&model, &mut qn).unwrap();
    assert!(aba(&model, &mut data, &qn, &v, &z).is_ok());
}

fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// Inside the tolerance the entries are used as given (Pinocchio's behaviour): a
/// quaternion of norm 1 + 1e-9 gives the normalized result to about 2e-9.
#[test]
fn nearly_unit_quaternions_are_accepted() {
    let model = load("solo12.urdf", RootJoint::FreeFlyer);
    let nv = model.nv();
    let mut data = model.create_data();
    let q = solo_q_scaled(&model, 1.0 + 1e-9);
    let mut qn = q.clone();
    normalize(&model, &mut qn).unwrap();
    let v: Vec<f64> = (0..nv).map(|k| (k as f64 * 0.3).sin()).collect();
    let tau: Vec<f64> = (0..nv).map(|k| (k as f64 * 0.7).cos()).collect();
    let got = aba(&model, &mut data, &q, &v, &tau).unwrap().to_vec();
    let want = aba(&model, &mut data, &qn, &v, &tau).unwrap().to_vec();
    assert!(rel_err(&got, &want) < 1e-8, "aba: {:e}", rel_err(&got, &want));
    let got = rnea(&model, &mut data, &q, &v, &tau).unwrap().to_vec();
    let want = rnea(&model, &mut data, &qn, &v, &tau).unwrap().to_vec();
    assert!(rel_err(&got, &want) < 1e-8, "rnea: {:e}", rel_err(&got, &want));
    let mut got = vec![0.0; model.nq()];
    let mut want = got.clone();
    integrate(&model, &q, &v, &mut got).unwrap();
    integrate(&model, &qn, &v, &mut want).unwrap();
    assert!(rel_err(&got, &want) < 1e-8, "integrate: {:e}", rel_err(&got, &want));
    // Unbounded revolute joints likewise.
    let pendulum = load("double_pendulum_continuous.urdf", RootJoint::Fixed);
    let mut pd = pendulum.create_data();
    let s = 1.0 + 1e-9;
    let (c1, s1, c2, s2) = (0.6f64, 0.8f64, 0.28f64, -0.96f64);
    let q = [c1 * s, s1 * s, c2 * s, s2 * s];
    let got = aba(&pendulum, &mut pd, &q, &[0.3, -0.2], &[0.1, 0.4]).unwrap().to_vec();
    let want = aba(&pendulum, &mut pd, &[c1, s1, c2, s2], &[0.3, -0.2], &[0.1, 0.4])
        .unwrap()
        .to_vec();
    assert!(rel_err(&got, &want) < 1e-8, "pendulum aba: {:e}", rel_err(&got, &want));
    // Just outside the tolerance: refused.
    let q = solo_q_scaled(&model, 1.0 + 2.0 * Model::UNIT_NORM_TOLERANCE);
    not_normalized_at("aba", aba(&model, &mut data, &q, &v, &tau), "root_joint");
}

/// One robot of the property test: model, contacts (may be empty).
struct Robot {
    name: &'static str,
    model: Model,
    contacts: Vec<ContactModel>,
}

fn robots() -> Vec<Robot> {
    let frames = |m: &Model, kind, names: &[&str], rf| -> Vec<ContactModel> {
        names
            .iter()
            .map(|f| ContactModel::from_frame(m, kind, m.frame_id(f).unwrap(), rf).unwrap())
            .collect()
    };
    let ur5 = load("ur5_robot.urdf", RootJoint::Fixed);
    let solo = load("solo12.urdf", RootJoint::FreeFlyer);
    let g1 = load("g1_29dof_rev_1_0.urdf", RootJoint::FreeFlyer);
    let ur5_c = frames(&ur5, ContactType::Contact3D, &["tool0"], ReferenceFrame::Local);
    let solo_c = frames(
        &solo,
        ContactType::Contact3D,
        &["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
        ReferenceFrame::LocalWorldAligned,
    );
    let g1_c = frames(
        &g1,
        ContactType::Contact6D,
        &["left_ankle_roll_link", "right_ankle_roll_link"],
        ReferenceFrame::Local,
    );
    vec![
        Robot {
            name: "ur5",
            model: ur5,
            contacts: ur5_c,
        },
        Robot {
            name: "solo12",
            model: solo,
            contacts: solo_c,
        },
        Robot {
            name: "g1",
            model: g1,
            contacts: g1_c,
        },
    ]
}

/// How one input vector of a random state is broken.
#[derive(Clone, Debug)]
struct Damage {
    /// Change of length (0 most of the time).
    len_delta: i8,
    /// Magnitude of the entries (1 most of the time; up to 1e300).
    magnitude: f64,
    /// An entry replaced by a special value (NaN, ±inf, huge, tiny), at an index taken
    /// modulo the length.
    special: Option<(usize, f64)>,
    /// Factor applied to every quaternion and (cos, sin) pair of q (1 most of the time).
    unit_scale: f64,
}

fn damage() -> impl Strategy<Value = Damage> {
    let len_delta = prop_oneof![12 => Just(0i8), 1 => Just(1), 1 => Just(-1), 1 => Just(-100)];
    let magnitude = prop_oneof![8 => Just(1.0), 1 => Just(1e3), 1 => Just(1e100), 1 => Just(1e200), 1 => Just(1e300)];
    let value = prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(1e308),
        Just(-1e250),
        Just(1e-310)
    ];
    let special = prop_oneof![6 => Just(None), 1 => (any::<usize>(), value).prop_map(Some)];
    let unit_scale = prop_oneof![8 => Just(1.0), 1 => Just(1.0 + 1e-9), 1 => Just(1.0 + 1e-5), 1 => Just(3.0), 1 => Just(0.0), 1 => Just(-1.0)];
    (len_delta, magnitude, special, unit_scale).prop_map(|(len_delta, magnitude, special, unit_scale)| Damage {
        len_delta,
        magnitude,
        special,
        unit_scale,
    })
}

impl Damage {
    /// Applies the length change and the special entry.
    fn apply(&self, mut x: Vec<f64>) -> Vec<f64> {
        let n = (x.len() as i64 + self.len_delta as i64).max(0) as usize;
        x.resize(n, 0.25);
        if let Some((k, val)) = self.special
            && !x.is_empty()
        {
            let n = x.len();
            x[k % n] = val;
        }
        x
    }
}

/// A random state: a configuration within [−1, 1] (uniform rotations), v, a of the
/// damaged magnitude, each vector damaged.
fn state(model: &Model, seed: u64, dq: &Damage, dv: &Damage, da: &Damage) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let (nq, nv) = (model.nq(), model.nv());
    let mut rng = SmallRng::seed_from_u64(seed);
    let (lo, hi) = (vec![-1.0; nq], vec![1.0; nq]);
    let mut q = random_configuration(model, &mut rng, &lo, &hi).unwrap();
    let q1 = random_configuration(model, &mut rng, &lo, &hi).unwrap();
    for jm in model.joints() {
        if let Some((start, len)) = jm.kind.unit_block() {
            let b = &mut q[jm.idx_q + start..jm.idx_q + start + len];
            b.iter_mut().for_each(|x| *x *= dq.unit_scale);
        }
        for k in jm.idx_q..jm.idx_q + jm.nq {
            if jm
                .kind
                .unit_block()
                .is_none_or(|(s, l)| !(s..s + l).contains(&(k - jm.idx_q)))
            {
                q[k] *= dq.magnitude;
            }
        }
    }
    let wave =
        |n: usize, f: f64, m: f64| -> Vec<f64> { (0..n).map(|k| m * (f * (k as f64 + seed as f64)).sin()).collect() };
    let v = dv.apply(wave(nv, 0.37, dv.magnitude));
    let a = da.apply(wave(nv, 0.91, da.magnitude));
    (dq.apply(q), q1, v, a)
}

/// Random, broken states (wrong lengths, NaN / inf entries, huge values, non-unit
/// quaternions) through every public algorithm of the crate: each call gives `Ok` with
/// finite results or a clear error, never a panic.
#[test]
fn random_broken_states_give_ok_finite_or_clear_errors() {
    const CASES: u32 = 1024;
    let mut total = 0;
    for robot in robots() {
        let model = &robot.model;
        let config = Config {
            cases: CASES,
            failure_persistence: None,
            ..Config::default()
        };
        let mut runner = TestRunner::new_with_rng(config, TestRng::deterministic_rng(RngAlgorithm::ChaCha));
        let (cases, oks, errs) = (Cell::new(0usize), Cell::new(0usize), Cell::new(0usize));
        let strategy = (any::<u64>(), damage(), damage(), damage());
        runner
            .run(&strategy, |(seed, dq, dv, da)| {
                let (q, q1, v, a) = state(model, seed, &dq, &dv, &da);
                let mut data = model.create_data();
                let mut cdata = ContactData::new(model, &robot.contacts).unwrap();
                let mut out = Outcome::default();
                run_algorithms(
                    model,
                    &mut data,
                    Some((&robot.contacts, &mut cdata)),
                    &q,
                    &q1,
                    &v,
                    &a,
                    &mut out,
                );
                cases.set(cases.get() + 1);
                oks.set(oks.get() + out.ok);
                errs.set(errs.get() + out.errors.len());
                Ok(())
            })
            .unwrap_or_else(|e| panic!("{}: {e}", robot.name));
        println!(
            "{}: {} cases, {} calls Ok (finite), {} clear errors",
            robot.name,
            cases.get(),
            oks.get(),
            errs.get()
        );
        // Both outcomes occur: the damage is neither always fatal nor always harmless.
        assert!(oks.get() > 0 && errs.get() > 0);
        total += cases.get();
    }
    println!("{total} random states in total");
}

/// The branch-free finiteness test finds a NaN or infinity at any position of slices of
/// every length around its chunk size.
#[test]
fn all_finite_finds_every_non_finite_entry() {
    for n in 0..11 {
        let x: Vec<f64> = (0..n).map(|k| k as f64 - 3.5).collect();
        assert!(spatial::all_finite(&x));
        for k in 0..n {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut y = x.clone();
                y[k] = bad;
                assert!(!spatial::all_finite(&y), "n = {n}, entry {k} = {bad}");
            }
        }
    }
    assert!(spatial::all_finite(&[
        f64::MAX,
        -f64::MAX,
        f64::MIN_POSITIVE,
        -0.0,
        5e-324
    ]));
}

#[test]
fn huge_numbers_in_messages_are_printed_compactly() {
    let mut model = load("ur5_robot.urdf", RootJoint::Fixed);
    let y = gharial_multibody::spatial::Inertia::from_com(
        -1e300,
        gharial_multibody::spatial::Vec3::zeros(),
        gharial_multibody::spatial::Mat3::identity(),
    );
    let e = model
        .set_inertia(1, y)
        .expect_err("a negative mass is refused")
        .to_string();
    assert!(e.contains("-1e300") && e.len() < 200, "{e}");
}
