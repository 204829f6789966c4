//! Rigid-body dynamics micro-benchmarks on ur5, solo12 and g1, in ns per call.
//!
//! Each iteration calls the function on the next of K = 100 random (q, v, a, tau) samples
//! (`common`), like the Pinocchio harness of `shared/peers` ("Micro-benchmarks").

mod common;

use common::{Sample, robots, samples};
use criterion::{Criterion, criterion_group, criterion_main};
use gharial_multibody::*;
use std::hint::black_box;
use std::time::Duration;

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

fn benches(c: &mut Criterion) {
    for (name, model, contacts) in robots() {
        bench_robot(c, name, &model, &contacts);
    }
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
