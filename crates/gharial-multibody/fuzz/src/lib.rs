//! Entry points of the fuzz targets (`fuzz_targets/`), shared with the stable replay
//! and property tests of `tests/bad_input.rs`, which include this file as a module.
//!
//! The invariant every entry enforces: a reader or an algorithm returns `Ok` with finite
//! results or an `Err` with a message; anything else (a panic, an abort, `Ok` with NaN or
//! infinity, an empty message) is a failure, reported by panicking.

use faer::{Mat, MatRef};
use gharial_multibody::*;
use std::sync::OnceLock;

/// What became of one input.
#[derive(Debug, Default)]
pub struct Outcome {
    /// Whether the load with the default options succeeded.
    pub default_ok: bool,
    /// Number of successful loads or calls.
    pub ok: usize,
    /// Messages of the errors.
    pub errors: Vec<String>,
}

impl Outcome {
    /// Records `r`: an error must have a message; `Ok` must pass `finite`.
    pub fn record<T>(&mut self, what: &str, r: Result<T>, finite: impl FnOnce(&T) -> bool) -> Option<T> {
        match r {
            Ok(x) => {
                assert!(finite(&x), "{what}: Ok with a non-finite result");
                self.ok += 1;
                Some(x)
            }
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.len() > 10, "{what}: unclear error message `{msg}` ({e:?})");
                self.errors.push(format!("{what}: {msg}"));
                None
            }
        }
    }
}

/// All entries finite.
pub fn finite(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite())
}

/// All entries of a matrix finite.
pub fn finite_mat(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

/// Models of at most this many degrees of freedom are run through the algorithms (larger
/// ones only loaded), so that one input takes milliseconds.
const MAX_NV_EXERCISED: usize = 256;

/// Loads `bytes` as a URDF string with both root joints and both mimic policies, and
/// runs the algorithms on every model that loads ([`run_algorithms`], at the neutral
/// configuration and at a configuration moved from it).
pub fn urdf(bytes: &[u8]) -> Outcome {
    let mut out = Outcome::default();
    let Ok(text) = std::str::from_utf8(bytes) else {
        out.errors.push("not UTF-8".into());
        return out;
    };
    for root in [RootJoint::Fixed, RootJoint::FreeFlyer] {
        for mimic in [MimicPolicy::Independent, MimicPolicy::Refuse] {
            let r = Model::from_urdf_str_with(text, root, &UrdfOptions { mimic });
            let default = root == RootJoint::Fixed && mimic == MimicPolicy::Independent;
            out.default_ok |= default && r.is_ok();
            if let Some(model) = out.record("from_urdf_str_with", r, model_is_sound) {
                if mimic == MimicPolicy::Refuse {
                    assert!(model.mimic_joints().is_empty(), "Refuse loaded a mimic joint");
                }
                exercise(&model, &mut out);
            }
        }
    }
    out
}

/// Structural checks of a loaded model.
fn model_is_sound(m: &Model) -> bool {
    m.nv() <= Model::MAX_NV
        && m.joint_names().len() == m.njoints()
        && m.inertias().iter().all(|y| y.is_finite())
        && m.joint_placements().iter().all(|x| x.is_finite())
        && m.frames()
            .iter()
            .all(|f| f.placement.is_finite() && f.parent_joint < m.njoints())
        && m.mimic_joints()
            .iter()
            .all(|mj| mj.joint < m.njoints() && mj.mimicked < m.njoints())
}

/// [`run_algorithms`] at the neutral configuration and at `neutral ⊕ v`.
fn exercise(model: &Model, out: &mut Outcome) {
    if model.nv() > MAX_NV_EXERCISED {
        return;
    }
    let (nq, nv) = (model.nq(), model.nv());
    let q0 = neutral(model);
    let v: Vec<f64> = (0..nv).map(|k| 0.5 - 0.1 * (k % 7) as f64).collect();
    let mut q = vec![0.0; nq];
    if out
        .record("integrate", integrate(model, &q0, &v, &mut q), |_| finite(&q))
        .is_none()
    {
        q.copy_from_slice(&q0);
    }
    let mut data = model.create_data();
    for qs in [&q0, &q] {
        run_algorithms(model, &mut data, None, qs, &q0, &v, &v, out);
    }
}

/// The solo12 model (free flyer) against which SRDF inputs are read.
fn solo() -> &'static Model {
    static SOLO: OnceLock<Model> = OnceLock::new();
    SOLO.get_or_init(|| {
        Model::from_urdf_str(
            include_str!("../../tests/data/robots/solo12.urdf"),
            RootJoint::FreeFlyer,
        )
        .expect("solo12 loads")
    })
}

/// Reads `bytes` as an SRDF into solo12 with every choice of [`SrdfOptions`]. A load
/// that fails must leave the model unchanged; one that succeeds must give reference
/// configurations of length nq that the algorithms accept and a finite, nonnegative
/// armature, and the dynamics at every reference configuration must be `Ok` (finite) or
/// a clear error.
pub fn srdf(bytes: &[u8]) -> Outcome {
    let mut out = Outcome::default();
    let Ok(text) = std::str::from_utf8(bytes) else {
        out.errors.push("not UTF-8".into());
        return out;
    };
    let base = solo();
    for (refs, rotors) in [(true, true), (true, false), (false, true)] {
        let mut model = base.clone();
        let options = SrdfOptions {
            reference_configurations: refs,
            rotor_parameters: rotors,
        };
        let r = model.load_srdf_str_with(text, &options);
        out.default_ok |= options == SrdfOptions::default() && r.is_ok();
        if out.record("load_srdf_str_with", r, |_| true).is_none() {
            assert!(
                model.reference_configurations == base.reference_configurations && model.armature == base.armature,
                "a failed SRDF load changed the model"
            );
            continue;
        }
        assert!(
            model.armature.iter().all(|a| a.is_finite() && *a >= 0.0),
            "SRDF gave armature {:?}",
            model.armature
        );
        assert!(
            refs || model.reference_configurations.is_empty(),
            "reference configurations read unasked"
        );
        assert!(
            rotors || model.armature == base.armature,
            "rotor parameters read unasked"
        );
        let mut data = model.create_data();
        let zeros = vec![0.0; model.nv()];
        for (name, q) in &model.reference_configurations {
            assert_eq!(q.len(), model.nq(), "reference configuration {name}");
            match aba(&model, &mut data, q, &zeros, &zeros) {
                Err(Error::NotNormalized { .. }) => panic!("reference configuration {name} is not normalized"),
                r => {
                    out.record("aba at a reference configuration", r.map(|x| x.to_vec()), |x| finite(x));
                }
            }
        }
    }
    out
}

/// Calls every public algorithm of the crate at (q, v, a) (with `q1` for `difference`,
/// `a` also as `tau`, and the contacts if given), recording each result in `out`: each
/// must be `Ok` with finite results or an error with a message. The results are read
/// back through the public accessors and checked here, independently of the crate's own
/// checks.
#[allow(clippy::too_many_arguments)]
pub fn run_algorithms(
    model: &Model,
    data: &mut Data,
    contacts: Option<(&[ContactModel], &mut ContactData)>,
    q: &[f64],
    q1: &[f64],
    v: &[f64],
    a: &[f64],
    out: &mut Outcome,
) {
    configuration_ops(model, q, q1, v, out);
    kinematics(model, data, q, v, a, out);
    dynamics(model, data, q, v, a, out);
    derivatives(model, data, q, v, a, out);
    if let Some((contacts, cdata)) = contacts {
        let r = constraint_dynamics(model, data, contacts, cdata, q, v, a);
        out.record("constraint_dynamics", r, |_| {
            finite(cdata.ddq()) && finite(cdata.lambda())
        });
        let r = compute_constraint_dynamics_derivatives(model, data, contacts, cdata);
        out.record("compute_constraint_dynamics_derivatives", r, |_| {
            [
                cdata.ddq_dq(),
                cdata.ddq_dv(),
                cdata.ddq_dtau(),
                cdata.dlambda_dq(),
                cdata.dlambda_dv(),
                cdata.dlambda_dtau(),
            ]
            .into_iter()
            .all(finite_mat)
        });
    }
}

fn configuration_ops(model: &Model, q: &[f64], q1: &[f64], v: &[f64], out: &mut Outcome) {
    let (nq, nv) = (model.nq(), model.nv());
    let mut qo = vec![0.0; nq];
    let mut vo = vec![0.0; nv];
    let mut j = Mat::<f64>::zeros(nv, nv);
    let r = integrate(model, q, v, &mut qo);
    out.record("integrate", r, |_| finite(&qo));
    let r = difference(model, q, q1, &mut vo);
    out.record("difference", r, |_| finite(&vo));
    for arg in [ArgumentPosition::Arg0, ArgumentPosition::Arg1] {
        let r = dintegrate(model, q, v, arg, j.as_mut());
        out.record("dintegrate", r, |_| finite_mat(j.as_ref()));
        let r = ddifference(model, q, q1, arg, j.as_mut());
        out.record("ddifference", r, |_| finite_mat(j.as_ref()));
    }
    let mut qn = q.to_vec();
    let r = normalize(model, &mut qn);
    out.record("normalize", r, |_| finite(&qn));
}

fn kinematics(model: &Model, data: &mut Data, q: &[f64], v: &[f64], a: &[f64], out: &mut Outcome) {
    let (nj, nv) = (model.njoints(), model.nv());
    let placements_finite = |d: &Data| (0..nj).all(|i| d.joint_placement(i).is_finite());
    let jacobian_finite = |d: &Data| (0..nv).all(|k| d.joint_jacobian_column(k).is_finite());
    let r = forward_kinematics_placements(model, data, q);
    out.record("forward_kinematics_placements", r, |_| placements_finite(data));
    let r = compute_joint_jacobians(model, data, q);
    out.record("compute_joint_jacobians", r, |_| {
        placements_finite(data) && jacobian_finite(data)
    });
    let r = forward_kinematics(model, data, q, v, a);
    out.record("forward_kinematics", r, |_| {
        placements_finite(data) && jacobian_finite(data)
    });
    let r = update_frame_placements(model, data);
    out.record("update_frame_placements", r, |_| {
        (0..model.nframes()).all(|f| data.frame_placement(f).is_finite())
    });
    let mut j6 = Mat::<f64>::zeros(6, nv);
    let frame = model.nframes() - 1;
    let joint = nj - 1;
    for rf in [
        ReferenceFrame::Local,
        ReferenceFrame::World,
        ReferenceFrame::LocalWorldAligned,
    ] {
        let r = frame_jacobian(model, data, frame, rf, j6.as_mut());
        out.record("frame_jacobian", r, |_| finite_mat(j6.as_ref()));
        let r = joint_jacobian(model, data, joint, rf, j6.as_mut());
        out.record("joint_jacobian", r, |_| finite_mat(j6.as_ref()));
        out.record("joint_velocity", joint_velocity(data, joint, rf), |m| m.is_finite());
        out.record("joint_acceleration", joint_acceleration(data, joint, rf), |m| {
            m.is_finite()
        });
        out.record("frame_velocity", frame_velocity(model, data, frame, rf), |m| {
            m.is_finite()
        });
        let r = frame_acceleration(model, data, frame, rf);
        out.record("frame_acceleration", r, |m| m.is_finite());
        let r = frame_classical_acceleration(model, data, frame, rf);
        out.record("frame_classical_acceleration", r, |m| m.is_finite());
    }
}

fn dynamics(model: &Model, data: &mut Data, q: &[f64], v: &[f64], a: &[f64], out: &mut Outcome) {
    let nj = model.njoints();
    let r = rnea(model, data, q, v, a).map(|t| t.to_vec());
    out.record("rnea", r, |t| {
        finite(t) && (0..nj).all(|i| data.joint_force_local(i).is_finite())
    });
    let r = nonlinear_effects(model, data, q, v).map(|t| t.to_vec());
    out.record("nonlinear_effects", r, |t| finite(t));
    let r = generalized_gravity(model, data, q).map(|t| t.to_vec());
    out.record("generalized_gravity", r, |t| finite(t));
    let r = crba(model, data, q).map(finite_mat);
    out.record("crba", r, |ok| *ok);
    let r = aba(model, data, q, v, a).map(|t| t.to_vec());
    out.record("aba", r, |t| finite(t));
    let r = compute_minverse(model, data, q).map(finite_mat);
    out.record("compute_minverse", r, |ok| *ok);
    let r = center_of_mass(model, data, q, v, a).copied();
    out.record("center_of_mass", r, |c| {
        c.iter()
            .chain(data.vcom().iter())
            .chain(data.acom().iter())
            .all(|x| x.is_finite())
            && data.total_mass().is_finite()
    });
    let r = jacobian_center_of_mass(model, data, q).map(finite_mat);
    out.record("jacobian_center_of_mass", r, |ok| *ok);
}

fn derivatives(model: &Model, data: &mut Data, q: &[f64], v: &[f64], a: &[f64], out: &mut Outcome) {
    let nv = model.nv();
    let r = compute_forward_kinematics_derivatives(model, data, q, v, a);
    out.record("compute_forward_kinematics_derivatives", r, |_| {
        (0..nv).all(|k| data.joint_jacobian_column(k).is_finite())
    });
    let mut m: [Mat<f64>; 4] = std::array::from_fn(|_| Mat::zeros(6, nv));
    let frame = model.nframes() - 1;
    for rf in [
        ReferenceFrame::Local,
        ReferenceFrame::World,
        ReferenceFrame::LocalWorldAligned,
    ] {
        let [m0, m1, m2, m3] = &mut m;
        let r = frame_velocity_derivatives(model, data, frame, rf, m0.as_mut(), m1.as_mut());
        out.record("frame_velocity_derivatives", r, |_| {
            finite_mat(m0.as_ref()) && finite_mat(m1.as_ref())
        });
        let r = frame_acceleration_derivatives(
            model,
            data,
            frame,
            rf,
            m0.as_mut(),
            m1.as_mut(),
            m2.as_mut(),
            m3.as_mut(),
        );
        out.record("frame_acceleration_derivatives", r, |_| {
            m.iter().all(|x| finite_mat(x.as_ref()))
        });
    }
    let r = compute_rnea_derivatives(model, data, q, v, a);
    out.record("compute_rnea_derivatives", r, |_| {
        finite(data.tau())
            && [data.dtau_dq(), data.dtau_dv(), data.mass_matrix()]
                .into_iter()
                .all(finite_mat)
    });
    let r = compute_aba_derivatives(model, data, q, v, a);
    out.record("compute_aba_derivatives", r, |_| {
        finite(data.ddq()) && [data.ddq_dq(), data.ddq_dv(), data.minv()].into_iter().all(finite_mat)
    });
}
