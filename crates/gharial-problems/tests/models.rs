//! Derivatives and physics of the example models.
//!
//! - Hand-written ODE Jacobians against the same model written once generically and
//!   differentiated with dual numbers (1e-12) and against central finite differences
//!   (1e-6).
//! - Every dynamics, cost and constraint of every catalogue problem against finite
//!   differences at random points (gradients and Jacobians; Hessians are Gauss-Newton
//!   by design and not compared).
//! - Physics, independently of the equations of motion: along the ODE's velocity the
//!   total energy `T + V`, computed from the positions and velocities of the bodies,
//!   changes at the rate of the power of the inputs.

use gharial::autodiff::{AutoOdeFn, Dual64};
use gharial::check::{
    CheckOptions, DualCheckOptions, check_cost, check_explicit_dynamics, check_ode, check_ode_dual,
    check_stage_function,
};
use gharial::dynamics::{Dynamics, Ode};
use gharial::spaces::Manifold;
use gharial_problems::acrobot::AcrobotOde;
use gharial_problems::cartpole::CartpoleOde;
use gharial_problems::pendulum::PendulumOde;
use gharial_problems::quadrotor::QuadrotorOde;
use gharial_problems::se2_car::CarOde;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn random_point(space: &dyn Manifold, rng: &mut SmallRng, scale: f64) -> Vec<f64> {
    let mut x = vec![0.0; space.nx()];
    space.random(rng, &mut x);
    // Spread the vector parts over [-scale, scale].
    let mut v = vec![0.0; space.ndx()];
    for vi in v.iter_mut() {
        *vi = rng.random_range(-scale..=scale);
    }
    let mut y = vec![0.0; space.nx()];
    space.integrate(&x, &v, &mut y);
    y
}

fn random_vec(rng: &mut SmallRng, n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(-scale..=scale)).collect()
}

/// Checks a hand-written ODE against its generic version (dual numbers) and finite
/// differences at random points; returns the largest errors.
fn check_hand_written<O: Ode + AutoOdeFn>(ode: &O, seed: u64) -> (f64, f64) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let (mut e_dual, mut e_fd) = (0.0_f64, 0.0_f64);
    for _ in 0..20 {
        let x = random_point(ode.space().as_ref(), &mut rng, 2.0);
        let u = random_vec(&mut rng, Ode::nu(ode), 3.0);
        let rep = check_ode_dual(
            ode,
            &x,
            &u,
            |x: &[Dual64], u: &[Dual64], out: &mut [Dual64]| ode.eval(x, u, out),
            DualCheckOptions::default(),
        );
        rep.assert_ok();
        e_dual = e_dual.max(rep.max_error());
        let rep = check_ode(ode, &x, &u, CheckOptions::default());
        rep.assert_ok();
        e_fd = e_fd.max(rep.max_error());
    }
    (e_dual, e_fd)
}

#[test]
fn hand_written_ode_jacobians_match_dual_numbers_and_finite_differences() {
    let results = [
        ("pendulum", check_hand_written(&PendulumOde::new(), 1)),
        ("cartpole", check_hand_written(&CartpoleOde::new(), 2)),
        ("acrobot", check_hand_written(&AcrobotOde::new(), 3)),
        ("se2-car", check_hand_written(&CarOde::new(), 4)),
    ];
    for (name, (dual, fd)) in results {
        eprintln!("{name}: dual-number error {dual:.1e}, finite-difference error {fd:.1e}");
        assert!(dual < 1e-12 && fd < 1e-6);
    }
}

#[test]
fn every_catalogue_model_passes_the_finite_difference_checker() {
    let mut rng = SmallRng::seed_from_u64(11);
    let opts = CheckOptions::default();
    for info in gharial_problems::catalogue() {
        let ex = gharial_problems::build(info.name).unwrap();
        let p = &ex.problem;
        let n = p.horizon();
        let mut worst = 0.0_f64;
        // The first, a middle and the last stage (stages differ in the quadrotor problems).
        for t in [0, n / 2, n - 1] {
            let stage = &p.stages()[t];
            let space = stage.space().clone();
            for _ in 0..3 {
                let x = random_point(space.as_ref(), &mut rng, 1.0);
                let u = random_vec(&mut rng, stage.nu(), 1.0);
                if let Dynamics::Explicit(d) = &stage.dynamics {
                    let rep = check_explicit_dynamics(d.as_ref(), &x, &u, opts);
                    assert!(rep.passed(), "{} stage {t} dynamics: {:?}", info.name, rep.errors);
                    worst = worst.max(rep.max_error());
                }
                let rep = check_cost(stage.cost.as_ref(), space.as_ref(), &x, &u, opts);
                // Central differences resolve a gradient only down to about ε |ℓ| / h: at
                // random states with the feet under the ground, the fly-high cost of
                // solo-jump reaches 1e85 and its control term falls below one ulp.
                let mut cost_data = stage.cost.create_data();
                stage.cost.evaluate(&x, &u, &mut cost_data);
                let resolution = f64::EPSILON * cost_data.value.abs() / opts.eps;
                for (block, e) in &rep.errors {
                    if block == "lx" || block == "lu" {
                        assert!(*e < 1e-6 + resolution, "{} stage {t} cost {block}: {e:e}", info.name);
                        worst = worst.max(*e);
                    }
                }
                for c in stage.constraints() {
                    let rep = check_stage_function(c.func.as_ref(), space.as_ref(), &x, &u, None, opts);
                    assert!(
                        rep.passed(),
                        "{} stage {t} constraint {}: {:?}",
                        info.name,
                        c.name,
                        rep.errors
                    );
                    worst = worst.max(rep.max_error());
                }
            }
        }
        let space = p.space(n).clone();
        let x = random_point(space.as_ref(), &mut rng, 1.0);
        let rep = check_cost(p.terminal_cost().as_ref(), space.as_ref(), &x, &[], opts);
        for (block, e) in &rep.errors {
            if block == "lx" {
                assert!(*e < 1e-6, "{} terminal cost: {e:e}", info.name);
            }
        }
        for c in p.terminal_constraints() {
            let rep = check_stage_function(c.func.as_ref(), space.as_ref(), &x, &[], None, opts);
            assert!(
                rep.passed(),
                "{} terminal constraint {}: {:?}",
                info.name,
                c.name,
                rep.errors
            );
            worst = worst.max(rep.max_error());
        }
        eprintln!("{}: largest finite-difference error {worst:.1e}", info.name);
    }
}

/// `dE/dt` along the ODE's velocity, by central differences of `E(x ⊕ h ẋ)`.
fn energy_rate(ode: &dyn Ode, x: &[f64], u: &[f64], energy: impl Fn(&[f64]) -> f64) -> f64 {
    let space = ode.space().clone();
    let mut data = ode.create_data();
    ode.evaluate(x, u, &mut data);
    let h = 1e-6;
    let mut xp = vec![0.0; space.nx()];
    let mut xm = vec![0.0; space.nx()];
    let vp: Vec<f64> = data.xdot().iter().map(|v| h * v).collect();
    let vm: Vec<f64> = data.xdot().iter().map(|v| -h * v).collect();
    space.integrate(x, &vp, &mut xp);
    space.integrate(x, &vm, &mut xm);
    (energy(&xp) - energy(&xm)) / (2.0 * h)
}

fn assert_power_balance(
    name: &str,
    ode: &dyn Ode,
    energy: impl Fn(&[f64]) -> f64,
    power: impl Fn(&[f64], &[f64]) -> f64,
) {
    let mut rng = SmallRng::seed_from_u64(5);
    let mut worst = 0.0_f64;
    for _ in 0..20 {
        let x = random_point(ode.space().as_ref(), &mut rng, 2.0);
        let u = random_vec(&mut rng, ode.nu(), 3.0);
        let rate = energy_rate(ode, &x, &u, &energy);
        let p = power(&x, &u);
        let err = (rate - p).abs() / p.abs().max(1.0);
        worst = worst.max(err);
    }
    eprintln!("{name}: energy balance error {worst:.1e}");
    assert!(worst < 1e-7, "{name}: {worst:e}");
}

#[test]
fn pendulum_energy_changes_at_the_rate_of_the_motor_power() {
    let (m, l, r, g) = (1.0, 1.0, 0.1, 9.81);
    let inertia = m * l * l + 0.4 * m * r * r;
    assert_power_balance(
        "pendulum",
        &PendulumOde::new(),
        |x| 0.5 * inertia * x[2] * x[2] + m * g * l * x[0],
        |x, u| u[0] * x[2],
    );
}

#[test]
fn cartpole_energy_changes_at_the_rate_of_the_cart_force_power() {
    let (mc, m, l, r, g) = (1.0, 0.1, 1.0, 0.1, 9.81);
    assert_power_balance(
        "cartpole",
        &CartpoleOde::new(),
        |x| {
            let (yd, th, thd) = (x[2], x[1], x[3]);
            // Pole mass at (y - l sin θ, l cos θ).
            let (vy, vz) = (yd - l * th.cos() * thd, -l * th.sin() * thd);
            0.5 * mc * yd * yd
                + 0.5 * m * (vy * vy + vz * vz)
                + 0.5 * 0.4 * m * r * r * thd * thd
                + m * g * l * th.cos()
        },
        |x, u| u[0] * x[2],
    );
}

#[test]
fn acrobot_energy_changes_at_the_rate_of_the_elbow_power() {
    let (m1, m2, i1, i2, g) = (0.26703, 0.33238, 4.0827e-4, 1.1753e-3, 9.81);
    let (c1, c2, j) = ([2.1727e-6, 0.036012], [1.9371e-10, 0.10088], [0.0, 0.1]);
    assert_power_balance(
        "acrobot",
        &AcrobotOde::new(),
        |x| {
            let (t1, t2) = (x[1].atan2(x[0]), x[3].atan2(x[2]));
            let (w1, w2) = (x[4], x[5]);
            // Points of the planar chain and their velocities, from the angles alone.
            let at = |phi: f64, p: [f64; 2]| [p[0] * phi.cos() - p[1] * phi.sin(), p[0] * phi.sin() + p[1] * phi.cos()];
            let vel = |phi: f64, p: [f64; 2], w: f64| {
                [
                    -w * (p[0] * phi.sin() + p[1] * phi.cos()),
                    w * (p[0] * phi.cos() - p[1] * phi.sin()),
                ]
            };
            let p1 = at(t1, c1);
            let v1 = vel(t1, c1, w1);
            let pj = at(t1, j);
            let vj = vel(t1, j, w1);
            let p2 = at(t1 + t2, c2);
            let v2 = vel(t1 + t2, c2, w1 + w2);
            let v2 = [vj[0] + v2[0], vj[1] + v2[1]];
            let z2 = pj[1] + p2[1];
            0.5 * m1 * (v1[0] * v1[0] + v1[1] * v1[1])
                + 0.5 * i1 * w1 * w1
                + 0.5 * m2 * (v2[0] * v2[0] + v2[1] * v2[1])
                + 0.5 * i2 * (w1 + w2) * (w1 + w2)
                + g * (m1 * p1[1] + m2 * z2)
        },
        |x, u| u[0] * x[5],
    );
}

#[test]
fn quadrotor_energy_changes_at_the_rate_of_the_rotor_power() {
    let q = QuadrotorOde::hector().unwrap();
    let ode = gharial::autodiff::AutoDiff::ode(gharial_problems::quadrotor::space(), q).unwrap();
    assert_power_balance(
        "quadrotor",
        &ode,
        |x| {
            let (v, w) = (&x[7..10], &x[10..13]);
            let kin = 0.5 * q.mass * v.iter().map(|a| a * a).sum::<f64>()
                + 0.5 * (0..3).map(|i| q.inertia[i] * w[i] * w[i]).sum::<f64>();
            kin + q.mass * q.gravity * x[2]
        },
        |x, u| {
            // Body wrench of the rotors against the body twist.
            let thrust: f64 = u.iter().sum();
            let tau = [
                q.arm * (u[1] - u[3]),
                q.arm * (u[2] - u[0]),
                q.yaw_ratio * (-u[0] + u[1] - u[2] + u[3]),
            ];
            thrust * x[9] + tau[0] * x[10] + tau[1] * x[11] + tau[2] * x[12]
        },
    );
}

#[test]
fn the_quadrotor_takes_mass_and_inertia_from_the_hector_urdf() {
    // The numbers of quadrotor_base.urdf's base_link <inertial>.
    let q = QuadrotorOde::hector().unwrap();
    assert_eq!(q.mass, 1.477);
    assert_eq!(q.inertia, [0.01152, 0.01152, 0.0218]);
    assert!((q.hover_thrust() - 1.477 * 9.81 / 4.0).abs() < 1e-15);
}
