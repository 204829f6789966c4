//! Residuals over one horizon of N = 100 stages on distinct random states: `evaluate`
//! at every stage, and `evaluate` + `jacobians` at every stage. Successive runs
//! alternate between two sets of states, so that nothing is reused from the previous
//! run (the contact dynamics keeps the solution of its last point).
//!
//! ```sh
//! cargo bench -p gharial-robotics --features bench --bench residuals
//! ```

use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use gharial::functions::{StageFunction, StageFunctionData, Unary};
use gharial::spaces::Manifold;
use gharial_multibody::spatial::Se3;
use gharial_multibody::{Model, ReferenceFrame, RootJoint};
use gharial_robotics::residuals::{
    CenterOfMassTranslationResidual, FramePlacementResidual, FrameTranslationResidual, FrameVelocityResidual,
    FrictionCone, FrictionConeResidual,
};
use gharial_robotics::{Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyPhaseSpace};
use rand::SeedableRng;
use rand::rngs::SmallRng;

const N: usize = 100;

fn robot(file: &str, root: RootJoint) -> Arc<Model> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../gharial-multibody/tests/data/robots")
        .join(file);
    Arc::new(Model::from_urdf_file(&path, root).expect("robot"))
}

fn bench_horizon(c: &mut Criterion, name: &str, f: &dyn StageFunction, space: &MultibodyPhaseSpace) {
    let mut rng = SmallRng::seed_from_u64(1);
    let xs: Vec<Vec<f64>> = (0..2 * N)
        .map(|_| {
            let mut x = vec![0.0; space.nx()];
            space.random(&mut rng, &mut x);
            x
        })
        .collect();
    let u = vec![0.1; f.nu()];
    let mut data: Vec<StageFunctionData> = (0..N).map(|_| f.create_data()).collect();
    let mut run = 0;
    let mut g = c.benchmark_group(name);
    g.bench_function("evaluate x100", |b| {
        b.iter(|| {
            run += 1;
            for (x, d) in xs[(run % 2) * N..].iter().zip(&mut data) {
                f.evaluate(x, &u, d);
            }
            black_box(&data);
        })
    });
    g.bench_function("evaluate + jacobians x100", |b| {
        b.iter(|| {
            run += 1;
            for (x, d) in xs[(run % 2) * N..].iter().zip(&mut data) {
                f.evaluate(x, &u, d);
                f.jacobians(x, &u, d);
            }
            black_box(&data);
        })
    });
    g.finish();
}

fn benches(c: &mut Criterion) {
    let ur5 = robot("ur5_robot.urdf", RootJoint::Fixed);
    let space = MultibodyPhaseSpace::new(ur5.clone());
    let nu = ur5.nv();
    let f = FrameTranslationResidual::new(&space, "tool0", &[0.4, 0.2, 0.3]).expect("residual");
    bench_horizon(c, "ur5 frame translation", &Unary::new(Arc::new(f), nu), &space);
    let f = FramePlacementResidual::new(&space, "tool0", &Se3::identity()).expect("residual");
    bench_horizon(c, "ur5 frame placement", &Unary::new(Arc::new(f), nu), &space);
    let f =
        FrameVelocityResidual::new(&space, "tool0", ReferenceFrame::LocalWorldAligned, &[0.0; 6]).expect("residual");
    bench_horizon(c, "ur5 frame velocity LWA", &Unary::new(Arc::new(f), nu), &space);
    let f = CenterOfMassTranslationResidual::new(&space, &[0.0; 3]).expect("residual");
    bench_horizon(c, "ur5 com", &Unary::new(Arc::new(f), nu), &space);

    let solo = robot("solo12.urdf", RootJoint::FreeFlyer);
    let space = Arc::new(MultibodyPhaseSpace::new(solo.clone()));
    let b = Actuation::floating_base(&solo).expect("actuation");
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned);
    let dynamics = MultibodyConstraintFwdDynamics::at_frames(space.clone(), b, &feet, spec).expect("dynamics");
    let cone = FrictionCone::vertical(0.7).expect("cone");
    let f = FrictionConeResidual::new(Arc::new(dynamics), 0, cone).expect("residual");
    bench_horizon(c, "solo12 friction cone", &f, &space);
}

criterion_group! {
    name = group;
    config = Criterion::default().warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    targets = benches
}
criterion_main!(group);
