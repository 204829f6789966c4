//! Rigid-body dynamics micro-benchmarks on ur5, solo12 and g1, in ns per call.
//!
//! Each iteration calls the function on the next of K = 100 random (q, v, a, tau) samples
//! (q uniform within the joint limits, free-flyer translation in [−1, 1]³ and a uniform
//! quaternion; v, a, tau uniform in [−1, 1]), like the Pinocchio harness of
//! `shared/peers` ("Micro-benchmarks"). Contacts: solo12 4 × 3D LWA at the feet, g1
//! 2 × 6D LWA at the ankles.

use criterion::{Criterion, criterion_group, criterion_main};
use gharial_multibody::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

struct Sample {
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    tau: Vec<f64>,
}

fn samples(model: &Model, k: usize, seed: u64) -> Vec<Sample> {
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

fn bench_robot(c: &mut Criterion, name: &str, model: &Model, contacts: &[ContactModel]) {
    let s = samples(model, 100, 1);
    let mut data = model.create_data();
    let mut g = c.benchmark_group(name);
    let run = |g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
               id: &str,
               f: &mut dyn FnMut(&Sample)| {
        let mut i = 0;
        g.bench_function(id, |b| {
            b.iter(|| {
                f(&s[i % s.len()]);
                i += 1;
            })
        });
    };
    run(&mut g, "forward_kinematics", &mut |x| {
        forward_kinematics(model, &mut data, &x.q, &x.v, &x.a).unwrap();
        black_box(&data);
    });
    run(&mut g, "compute_joint_jacobians", &mut |x| {
        compute_joint_jacobians(model, &mut data, &x.q).unwrap();
        black_box(&data);
    });
    run(&mut g, "rnea", &mut |x| {
        black_box(rnea(model, &mut data, &x.q, &x.v, &x.a).unwrap());
    });
    run(&mut g, "nonlinear_effects", &mut |x| {
        black_box(nonlinear_effects(model, &mut data, &x.q, &x.v).unwrap());
    });
    run(&mut g, "crba", &mut |x| {
        black_box(crba(model, &mut data, &x.q).unwrap());
    });
    run(&mut g, "aba", &mut |x| {
        black_box(aba(model, &mut data, &x.q, &x.v, &x.tau).unwrap());
    });
    run(&mut g, "compute_rnea_derivatives", &mut |x| {
        compute_rnea_derivatives(model, &mut data, &x.q, &x.v, &x.a).unwrap();
        black_box(&data);
    });
    run(&mut g, "compute_aba_derivatives", &mut |x| {
        compute_aba_derivatives(model, &mut data, &x.q, &x.v, &x.tau).unwrap();
        black_box(&data);
    });
    if !contacts.is_empty() {
        let mut cd = ContactData::new(model, contacts).expect("contact data");
        run(&mut g, "constraint_dynamics", &mut |x| {
            constraint_dynamics(model, &mut data, contacts, &mut cd, &x.q, &x.v, &x.tau).unwrap();
            black_box(&cd);
        });
        run(&mut g, "constraint_dynamics+derivatives", &mut |x| {
            constraint_dynamics(model, &mut data, contacts, &mut cd, &x.q, &x.v, &x.tau).unwrap();
            compute_constraint_dynamics_derivatives(model, &mut data, contacts, &mut cd).unwrap();
            black_box(&cd);
        });
    }
    g.finish();
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

fn benches(c: &mut Criterion) {
    let ur5 = load("ur5_robot.urdf", RootJoint::Fixed);
    bench_robot(c, "ur5", &ur5, &[]);
    let solo = load("solo12.urdf", RootJoint::FreeFlyer);
    let sc = contacts(
        &solo,
        ContactType::Contact3D,
        &["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
    );
    bench_robot(c, "solo12", &solo, &sc);
    let g1 = load("g1_29dof_rev_1_0.urdf", RootJoint::FreeFlyer);
    let gc = contacts(
        &g1,
        ContactType::Contact6D,
        &["left_ankle_roll_link", "right_ankle_roll_link"],
    );
    bench_robot(c, "g1", &g1, &gc);
}

criterion_group! {
    name = group;
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(200))
        .measurement_time(Duration::from_millis(600))
        .sample_size(20);
    targets = benches
}
criterion_main!(group);
