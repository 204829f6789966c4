//! One horizon of N = 100 stages of multibody dynamics: the ODE alone (`evaluate`,
//! `evaluate` + `jacobians`) and integrated by semi-implicit Euler (as Crocoddyl's
//! `IntegratedActionModelEuler`; `forward`, `forward` + `jacobians`). Every call is at a
//! new random state (iterations alternate between two sets of N states), so that the
//! constrained dynamics never reuse the solution kept for their last point.
//!
//! ```sh
//! cargo bench -p gharial-robotics --features bench --bench dynamics
//! ```

use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, criterion_group, criterion_main};
use gharial::dynamics::{ExplicitDynamics, ExplicitDynamicsData, Ode, OdeData, SemiImplicitEuler};
use gharial::spaces::Manifold;
use gharial_multibody::{Model, ReferenceFrame, RootJoint};
use gharial_robotics::{
    Actuation, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics, MultibodyPhaseSpace,
};
use rand::SeedableRng;
use rand::rngs::SmallRng;

const N: usize = 100;

fn robot(file: &str, root: RootJoint) -> Arc<Model> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../gharial-multibody/tests/data/robots")
        .join(file);
    Arc::new(Model::from_urdf_file(&path, root).expect("robot"))
}

/// Two sets of N random states.
fn states(space: &MultibodyPhaseSpace) -> [Vec<Vec<f64>>; 2] {
    let mut rng = SmallRng::seed_from_u64(1);
    let mut draw = || {
        (0..N)
            .map(|_| {
                let mut x = vec![0.0; space.nx()];
                space.random(&mut rng, &mut x);
                x
            })
            .collect()
    };
    [draw(), draw()]
}

/// Times `f(x, data)` over the N stages, alternating the state sets between iterations.
fn horizon<D>(
    g: &mut BenchmarkGroup<'_, WallTime>,
    id: &str,
    xs: &[Vec<Vec<f64>>; 2],
    data: &mut [D],
    f: impl Fn(&[f64], &mut D),
) {
    let mut k = 0;
    g.bench_function(id, |b| {
        b.iter(|| {
            k ^= 1;
            for (x, d) in xs[k].iter().zip(data.iter_mut()) {
                f(x, d);
            }
            black_box(&data);
        })
    });
}

fn bench_horizon(c: &mut Criterion, name: &str, ode: Arc<dyn Ode>, space: &Arc<MultibodyPhaseSpace>) {
    let config: Arc<dyn Manifold> = space.configuration().clone();
    let step = SemiImplicitEuler::new(ode.clone(), config, 0.01).expect("integrator");
    let xs = states(space);
    let u = vec![0.1; ode.nu()];
    let mut g = c.benchmark_group(name);
    let mut ode_data: Vec<OdeData> = (0..N).map(|_| ode.create_data()).collect();
    horizon(&mut g, "ode evaluate x100", &xs, &mut ode_data, |x, d| {
        ode.evaluate(x, &u, d)
    });
    horizon(&mut g, "ode evaluate + jacobians x100", &xs, &mut ode_data, |x, d| {
        ode.evaluate(x, &u, d);
        ode.jacobians(x, &u, d);
    });
    let mut data: Vec<ExplicitDynamicsData> = (0..N).map(|_| step.create_data()).collect();
    horizon(&mut g, "semi-implicit Euler forward x100", &xs, &mut data, |x, d| {
        step.forward(x, &u, d)
    });
    horizon(
        &mut g,
        "semi-implicit Euler forward + jacobians x100",
        &xs,
        &mut data,
        |x, d| {
            step.forward(x, &u, d);
            step.jacobians(x, &u, d);
        },
    );
    g.finish();
}

fn benches(c: &mut Criterion) {
    let ur5 = robot("ur5_robot.urdf", RootJoint::Fixed);
    let space = Arc::new(MultibodyPhaseSpace::new(ur5.clone()));
    let ode = MultibodyFreeFwdDynamics::new(space.clone(), Actuation::full(&ur5)).expect("ode");
    bench_horizon(c, "ur5 free", Arc::new(ode), &space);

    let solo = robot("solo12.urdf", RootJoint::FreeFlyer);
    let space = Arc::new(MultibodyPhaseSpace::new(solo.clone()));
    let b = Arc::new(Actuation::floating_base(&solo).expect("actuation"));
    let ode = MultibodyFreeFwdDynamics::new(space.clone(), b.clone()).expect("ode");
    bench_horizon(c, "solo12 free", Arc::new(ode), &space);
    let feet = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];
    let spec = ContactSpec::point(ReferenceFrame::LocalWorldAligned);
    let ode = MultibodyConstraintFwdDynamics::at_frames(space.clone(), b, &feet, spec).expect("ode");
    bench_horizon(c, "solo12 4 feet", Arc::new(ode), &space);
}

criterion_group! {
    name = group;
    config = Criterion::default().warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    targets = benches
}
criterion_main!(group);
