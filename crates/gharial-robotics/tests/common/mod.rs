//! Robot models and Pinocchio fixtures of the multibody crate's test data, shared by the
//! tests of this crate.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;

use gharial_multibody::{Model, RootJoint};
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
