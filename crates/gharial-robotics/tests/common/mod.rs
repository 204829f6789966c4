//! Robot models and Pinocchio fixtures of the multibody crate's test data, shared by the
//! tests of this crate.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;

use faer::Mat;
use gharial::spaces::Manifold;
use gharial_multibody::{Model, RootJoint};
use gharial_robotics::MultibodyPhaseSpace;
use rand::Rng;
use rand::rngs::SmallRng;
use serde_json::Value;

/// The fixtures of `gharial-multibody/tests/data/fixtures/pinocchio`.
pub const FIXTURES: [&str; 7] = [
    "ur5",
    "ur10",
    "solo12",
    "hector",
    "double_pendulum",
    "double_pendulum_continuous",
    "g1",
];

/// The multibody crate's test data directory.
pub fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../gharial-multibody/tests/data")
}

/// A robot of the test data by URDF file name.
pub fn robot(urdf: &str, root: RootJoint) -> Arc<Model> {
    let path = data_dir().join("robots").join(urdf);
    Arc::new(Model::from_urdf_file(&path, root).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

/// The model (built as the fixture's `source` says) and the fixture's JSON.
pub fn fixture(name: &str) -> (Arc<Model>, Value) {
    let path = data_dir().join("fixtures/pinocchio").join(format!("{name}.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let json: Value = serde_json::from_str(&text).expect("fixture JSON");
    let source = &json["source"];
    let urdf = source["urdf"].as_str().expect("source.urdf");
    let root = match source["root_joint"].as_str() {
        Some("JointModelFreeFlyer") => RootJoint::FreeFlyer,
        _ => RootJoint::Fixed,
    };
    let file = urdf.rsplit('/').next().expect("file name");
    (robot(file, root), json)
}

/// Solo-12 with a free flyer.
pub fn solo12() -> Arc<Model> {
    robot("solo12.urdf", RootJoint::FreeFlyer)
}

/// The UR5, fixed base.
pub fn ur5() -> Arc<Model> {
    robot("ur5_robot.urdf", RootJoint::Fixed)
}

/// The G1 humanoid with a free flyer.
pub fn g1() -> Arc<Model> {
    robot("g1_29dof_rev_1_0.urdf", RootJoint::FreeFlyer)
}

/// A JSON array of numbers.
pub fn vecf(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// A JSON array of rows.
pub fn matf(v: &Value) -> Mat<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().expect("rows").iter().map(vecf).collect();
    Mat::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

/// `max |a_i - b_i|`.
pub fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
}

/// `max |a_ij - b_ij|`.
pub fn max_diff_mat(a: faer::MatRef<'_, f64>, b: faer::MatRef<'_, f64>) -> f64 {
    assert_eq!((a.nrows(), a.ncols()), (b.nrows(), b.ncols()));
    (0..a.nrows())
        .flat_map(|i| (0..a.ncols()).map(move |j| (i, j)))
        .fold(0.0_f64, |m, (i, j)| m.max((a[(i, j)] - b[(i, j)]).abs()))
}

/// The phase space of `model`.
pub fn space_of(model: &Arc<Model>) -> Arc<MultibodyPhaseSpace> {
    Arc::new(MultibodyPhaseSpace::new(model.clone()))
}

/// A random state `(q, v)` (configuration within the limits, `|v_i| ≤ 1`).
pub fn random_state(space: &MultibodyPhaseSpace, rng: &mut SmallRng) -> Vec<f64> {
    let mut x = vec![0.0; space.nx()];
    space.random(rng, &mut x);
    x
}

/// `n` numbers uniform in `[-scale, scale]`.
pub fn random_vec(rng: &mut SmallRng, n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|_| scale * rng.random_range(-1.0..1.0)).collect()
}

/// `Ode::acceleration_jacobians` at `(x, u)`: the rows past `ndx / 2` of `jacobians`, bit
/// for bit, and the first rows left as they were (a mark).
pub fn assert_acceleration_jacobians_are_the_bottom_rows(ode: &dyn gharial::dynamics::Ode, x: &[f64], u: &[f64]) {
    let mut full = ode.create_data();
    ode.evaluate(x, u, &mut full);
    ode.jacobians(x, u, &mut full);
    let mut part = ode.create_data();
    ode.evaluate(x, u, &mut part);
    part.jx.fill(7.0);
    part.ju.fill(7.0);
    ode.acceleration_jacobians(x, u, &mut part);
    let half = ode.space().ndx() / 2;
    for (name, a, b) in [("jx", &full.jx, &part.jx), ("ju", &full.ju, &part.ju)] {
        for j in 0..a.ncols() {
            for i in 0..a.nrows() {
                let expected = if i < half { 7.0 } else { a[(i, j)] };
                assert_eq!(b[(i, j)].to_bits(), expected.to_bits(), "{name}({i}, {j})");
            }
        }
    }
}
