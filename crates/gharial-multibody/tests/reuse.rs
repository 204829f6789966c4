//! The `_reusing_` variants equal the plain algorithms bit for bit, reuse only what the
//! last algorithm left at the same inputs, and recompute otherwise.

use faer::MatRef;
use gharial_multibody::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn robots() -> Vec<Model> {
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/robots");
    vec![
        Model::from_urdf_file(dir.join("ur5_robot.urdf"), RootJoint::Fixed).unwrap(),
        Model::from_urdf_file(dir.join("solo12.urdf"), RootJoint::FreeFlyer).unwrap(),
    ]
}

fn state(model: &Model, rng: &mut SmallRng) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let q = random_configuration(model, rng, &vec![-1.0; model.nq()], &vec![1.0; model.nq()]).unwrap();
    let mut vec = || {
        (0..model.nv())
            .map(|_| rng.random_range(-1.0..1.0))
            .collect::<Vec<f64>>()
    };
    (q, vec(), vec())
}

fn same(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> bool {
    (0..a.nrows()).all(|i| (0..a.ncols()).all(|j| a[(i, j)].to_bits() == b[(i, j)].to_bits()))
}

/// The ABA derivatives of a fresh data.
fn reference(model: &Model, q: &[f64], v: &[f64], tau: &[f64]) -> Data {
    let mut d = model.create_data();
    compute_aba_derivatives(model, &mut d, q, v, tau).unwrap();
    d
}

fn assert_same_derivatives(what: &str, a: &Data, b: &Data) {
    assert!(
        same(a.ddq_dq(), b.ddq_dq()) && same(a.ddq_dv(), b.ddq_dv()) && same(a.minv(), b.minv()),
        "{what}"
    );
    assert_eq!(a.ddq(), b.ddq(), "{what}");
}

#[test]
fn aba_derivatives_reuse_the_aba_of_the_same_point_only() {
    let mut rng = SmallRng::seed_from_u64(4);
    for model in robots() {
        let mut d = model.create_data();
        for _ in 0..5 {
            let (q, v, tau) = state(&model, &mut rng);
            let want = reference(&model, &q, &v, &tau);
            // After an ABA at the same point.
            aba(&model, &mut d, &q, &v, &tau).unwrap();
            compute_aba_derivatives_reusing_aba(&model, &mut d, &q, &v, &tau).unwrap();
            assert_same_derivatives("after aba", &d, &want);
            // After an ABA at another torque: recomputed.
            let tau2: Vec<f64> = tau.iter().map(|t| t + 0.5).collect();
            aba(&model, &mut d, &q, &v, &tau2).unwrap();
            compute_aba_derivatives_reusing_aba(&model, &mut d, &q, &v, &tau).unwrap();
            assert_same_derivatives("after aba elsewhere", &d, &want);
            // After an ABA at the point, then another algorithm overwriting the kinematics.
            aba(&model, &mut d, &q, &v, &tau).unwrap();
            let (q2, v2, a2) = state(&model, &mut rng);
            rnea(&model, &mut d, &q2, &v2, &a2).unwrap();
            compute_aba_derivatives_reusing_aba(&model, &mut d, &q, &v, &tau).unwrap();
            assert_same_derivatives("after rnea", &d, &want);
            // After a failed ABA: recomputed (and still right).
            aba(&model, &mut d, &q, &v, &tau).unwrap();
            assert!(aba(&model, &mut d, &q, &v, &[f64::NAN; 1]).is_err());
            compute_aba_derivatives_reusing_aba(&model, &mut d, &q, &v, &tau).unwrap();
            assert_same_derivatives("after a failed call", &d, &want);
        }
    }
}

#[test]
fn joint_jacobians_reuse_the_placements_of_the_same_configuration_only() {
    let mut rng = SmallRng::seed_from_u64(9);
    for model in robots() {
        let mut d = model.create_data();
        for _ in 0..5 {
            let (q, v, tau) = state(&model, &mut rng);
            let mut want = model.create_data();
            compute_joint_jacobians(&model, &mut want, &q).unwrap();
            let columns_equal = |d: &Data| {
                (0..model.nv()).all(|k| d.joint_jacobian_column(k) == want.joint_jacobian_column(k))
                    && (0..model.njoints()).all(|i| d.joint_placement(i) == want.joint_placement(i))
            };
            forward_kinematics_placements(&model, &mut d, &q).unwrap();
            compute_joint_jacobians_reusing_placements(&model, &mut d, &q).unwrap();
            assert!(columns_equal(&d), "after the placements");
            aba(&model, &mut d, &q, &v, &tau).unwrap();
            compute_joint_jacobians_reusing_placements(&model, &mut d, &q).unwrap();
            assert!(columns_equal(&d), "after aba");
            let (q2, _, _) = state(&model, &mut rng);
            forward_kinematics_placements(&model, &mut d, &q2).unwrap();
            compute_joint_jacobians_reusing_placements(&model, &mut d, &q).unwrap();
            assert!(columns_equal(&d), "after placements elsewhere");
            forward_kinematics_placements(&model, &mut d, &q).unwrap();
            crba(&model, &mut d, &q2).unwrap();
            compute_joint_jacobians_reusing_placements(&model, &mut d, &q).unwrap();
            assert!(columns_equal(&d), "after crba elsewhere");
        }
    }
}
