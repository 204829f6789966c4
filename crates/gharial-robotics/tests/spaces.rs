//! The multibody spaces against Pinocchio's `integrate` / `difference` and their
//! Jacobians (the fixtures), and against the core's derivative checkers.

mod common;

use common::{matf, max_diff, max_diff_mat, vecf};

use faer::Mat;
use gharial::check::{CheckOptions, DualCheckOptions, check_manifold, check_manifold_dual};
use gharial::spaces::{Arg, Manifold};
use gharial_robotics::{MultibodyConfiguration, MultibodyPhaseSpace};
use rand::SeedableRng;
use rand::rngs::SmallRng;

/// A quaternion and its negative are the same rotation: compare representations up to
/// that sign, joint by joint.
fn config_diff(space: &MultibodyConfiguration, a: &[f64], b: &[f64]) -> f64 {
    let mut d = vec![0.0; space.ndx()];
    space.difference(a, b, &mut d);
    d.iter().fold(0.0_f64, |m, x| m.max(x.abs()))
}

#[test]
fn integrate_and_difference_equal_pinocchio() {
    const TOL: f64 = 1e-12;
    let mut checked = 0;
    for fixture in common::FIXTURES {
        let (model, json) = common::fixture(fixture);
        let space = MultibodyConfiguration::new(model.clone());
        assert_eq!((space.nx(), space.ndx()), (model.nq(), model.nv()), "{fixture}");
        let n = space.ndx();
        let mut j = Mat::zeros(n, n);
        for s in json["samples"].as_array().expect("samples") {
            let it = &s["integrate"];
            let (q, v) = (vecf(&it["q"]), vecf(&it["v"]));
            let mut out = vec![0.0; space.nx()];
            space.integrate(&q, &v, &mut out);
            let err = config_diff(&space, &out, &vecf(&it["result"]));
            assert!(err < TOL, "{fixture}: integrate off by {err:e}");
            space.jintegrate(&q, &v, Arg::First, j.as_mut());
            assert!(
                max_diff_mat(j.as_ref(), matf(&it["d_dq"]).as_ref()) < TOL,
                "{fixture}: d integrate / dq"
            );
            space.jintegrate(&q, &v, Arg::Second, j.as_mut());
            assert!(
                max_diff_mat(j.as_ref(), matf(&it["d_dv"]).as_ref()) < TOL,
                "{fixture}: d integrate / dv"
            );

            let df = &s["difference"];
            let (q0, q1) = (vecf(&df["q0"]), vecf(&df["q1"]));
            let mut d = vec![0.0; n];
            space.difference(&q0, &q1, &mut d);
            assert!(max_diff(&d, &vecf(&df["result"])) < TOL, "{fixture}: difference");
            space.jdifference(&q0, &q1, Arg::First, j.as_mut());
            assert!(
                max_diff_mat(j.as_ref(), matf(&df["d_dq0"]).as_ref()) < TOL,
                "{fixture}: d difference / dq0"
            );
            space.jdifference(&q0, &q1, Arg::Second, j.as_mut());
            assert!(
                max_diff_mat(j.as_ref(), matf(&df["d_dq1"]).as_ref()) < TOL,
                "{fixture}: d difference / dq1"
            );
            checked += 1;
        }
    }
    assert!(checked >= 60, "only {checked} samples checked");
}

#[test]
fn jacobians_match_finite_differences_and_dual_numbers() {
    let mut rng = SmallRng::seed_from_u64(7);
    for fixture in common::FIXTURES {
        let (model, _) = common::fixture(fixture);
        let spaces: [Box<dyn Manifold>; 2] = [
            Box::new(MultibodyConfiguration::new(model.clone())),
            Box::new(MultibodyPhaseSpace::new(model.clone())),
        ];
        for space in &spaces {
            for _ in 0..3 {
                let (mut x, mut x1) = (vec![0.0; space.nx()], vec![0.0; space.nx()]);
                space.random(&mut rng, &mut x);
                space.random(&mut rng, &mut x1);
                assert!(space.is_valid(&x), "{fixture}: random point is not valid");
                let v: Vec<f64> = (0..space.ndx()).map(|i| 0.3 * ((i as f64) * 0.7).sin()).collect();
                let fd = check_manifold(space.as_ref(), &x, &v, &x1, CheckOptions { eps: 1e-6, tol: 1e-5 });
                assert!(fd.passed(), "{fixture}: {:?}", fd.errors);
                let dual = check_manifold_dual(space.as_ref(), &x, &v, &x1, DualCheckOptions::default());
                assert!(dual.passed(), "{fixture}: {:?}", dual.errors);
            }
        }
    }
}

#[test]
fn random_configurations_respect_the_joint_limits() {
    let (model, _) = common::fixture("ur5");
    let space = MultibodyConfiguration::new(model.clone());
    let mut rng = SmallRng::seed_from_u64(3);
    let mut q = vec![0.0; space.nx()];
    for _ in 0..200 {
        space.random(&mut rng, &mut q);
        for (i, &qi) in q.iter().enumerate() {
            assert!(qi >= model.lower_position_limit[i] && qi <= model.upper_position_limit[i]);
        }
    }
    // The limits of the UR5 are ±2π: draws outside [-1, 1] occur.
    space.random(&mut rng, &mut q);
    assert!((0..50).any(|_| {
        space.random(&mut rng, &mut q);
        q.iter().any(|v| v.abs() > 1.0)
    }));
}

#[test]
fn phase_space_is_the_tangent_bundle() {
    let (model, _) = common::fixture("solo12");
    let space = MultibodyPhaseSpace::new(model.clone());
    let (nq, nv) = (model.nq(), model.nv());
    assert_eq!((space.nx(), space.ndx()), (nq + nv, 2 * nv));
    let mut rng = SmallRng::seed_from_u64(11);
    let mut x = vec![0.0; nq + nv];
    space.random(&mut rng, &mut x);
    let dx: Vec<f64> = (0..2 * nv).map(|i| 0.01 * i as f64).collect();
    let mut y = vec![0.0; nq + nv];
    space.integrate(&x, &dx, &mut y);
    let mut q = vec![0.0; nq];
    space.configuration().integrate(&x[..nq], &dx[..nv], &mut q);
    assert_eq!(&y[..nq], &q[..]);
    for i in 0..nv {
        assert_eq!(y[nq + i], x[nq + i] + dx[nv + i]);
    }
}
