//! Robots, contacts and random samples shared by the criterion benchmarks and the
//! instruction-count example (`examples/count_instructions.rs`).
//!
//! Samples are drawn like the Pinocchio harness of `shared/peers` ("Micro-benchmarks"):
//! q uniform within the joint limits (free-flyer translation in [−1, 1]³ and a uniform
//! quaternion), v, a, tau uniform in [−1, 1]. Contacts: solo12 4 × 3D LWA at the feet,
//! g1 2 × 6D LWA at the ankles.

use gharial_multibody::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::path::Path;

/// One random state and input.
pub struct Sample {
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub tau: Vec<f64>,
}

/// `k` random samples for `model`.
pub fn samples(model: &Model, k: usize, seed: u64) -> Vec<Sample> {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut lower = model.lower_position_limit.clone();
    let mut upper = model.upper_position_limit.clone();
    for (lo, hi) in lower.iter_mut().zip(upper.iter_mut()) {
        if !(*hi - *lo).is_finite() || *hi - *lo > 1e10 {
            *lo = -1.0;
            *hi = 1.0;
        }
    }
    let nv = model.nv();
    let u = |rng: &mut SmallRng| (0..nv).map(|_| rng.random_range(-1.0..1.0)).collect::<Vec<f64>>();
    (0..k)
        .map(|_| {
            let q = random_configuration(model, &mut rng, &lower, &upper).expect("random configuration");
            Sample {
                q,
                v: u(&mut rng),
                a: u(&mut rng),
                tau: u(&mut rng),
            }
        })
        .collect()
}

fn load(file: &str, root: RootJoint) -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/robots")
        .join(file);
    Model::from_urdf_file(path, root).expect("URDF")
}

fn contacts(model: &Model, kind: ContactType, frames: &[&str]) -> Vec<ContactModel> {
    frames
        .iter()
        .map(|f| {
            let id = model.frame_id(f).expect("frame");
            ContactModel::from_frame(model, kind, id, ReferenceFrame::LocalWorldAligned).expect("contact")
        })
        .collect()
}

/// The benchmarked robots: (name, model, contacts).
pub fn robots() -> Vec<(&'static str, Model, Vec<ContactModel>)> {
    let ur5 = load("ur5_robot.urdf", RootJoint::Fixed);
    let solo = load("solo12.urdf", RootJoint::FreeFlyer);
    let sc = contacts(
        &solo,
        ContactType::Contact3D,
        &["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
    );
    let g1 = load("g1_29dof_rev_1_0.urdf", RootJoint::FreeFlyer);
    let gc = contacts(
        &g1,
        ContactType::Contact6D,
        &["left_ankle_roll_link", "right_ankle_roll_link"],
    );
    vec![("ur5", ur5, Vec::new()), ("solo12", solo, sc), ("g1", g1, gc)]
}
