//! The UR10 ballistic task (ProxDDP paper §VII-B): ProxDDP's solution lands the mug on
//! the target, keeps the torques within (and on) their limits, holds the mug until the
//! release and then lets it fly on a ballistic parabola; the release map's Jacobians
//! against finite differences; the quasi-static torque against the composite body's
//! gravity compensation; the figure data.

use std::sync::{Arc, OnceLock};

use gharial::check::{CheckOptions, check_explicit_dynamics};
use gharial::dynamics::{Dynamics, Ode};
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver};
use gharial::spaces::Manifold;
use gharial_multibody::spatial::{Mat3, Se3, Vec3};
use gharial_multibody::{Model, RootJoint, forward_kinematics_placements};
use gharial_problems::ur10_ballistic::{MUG_JOINT, Ur10Ballistic, Ur10BallisticParams};
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, gravity_compensation};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const G: f64 = 9.81;

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

fn task() -> &'static Ur10Ballistic {
    static TASK: OnceLock<Ur10Ballistic> = OnceLock::new();
    TASK.get_or_init(|| Ur10Ballistic::new(Ur10BallisticParams::default()).expect("task"))
}

/// ProxDDP's solution from the example's cold start, solved once for all tests.
fn solution() -> &'static Solution {
    static SOL: OnceLock<Solution> = OnceLock::new();
    SOL.get_or_init(|| {
        let ex = &task().example;
        let mut solver = ProxDdp::new(ex.proxddp.clone());
        solver.setup(&ex.problem).expect("setup");
        solver
            .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
            .expect("solve")
            .clone()
    })
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[test]
fn proxddp_converges_to_1e_6() {
    let (ex, sol) = (&task().example, solution());
    let tol = ex.proxddp.tol;
    assert_eq!(tol, 1e-6);
    assert!(
        sol.status.converged(),
        "{:?} after {} iterations",
        sol.status,
        sol.iterations
    );
    assert!(
        sol.prim_err <= tol && sol.dual_err <= tol,
        "{} {}",
        sol.prim_err,
        sol.dual_err
    );
    eprintln!(
        "ur10-ballistic: {} iterations, {} AL iterations, prim {:.2e}, dual {:.2e}, cost {:.6}",
        sol.iterations, sol.al_iterations, sol.prim_err, sol.dual_err, sol.cost
    );
}

#[test]
fn the_mug_lands_on_the_target() {
    let (t, sol) = (task(), solution());
    let n = t.params.horizon;
    let p = t.mug_position(n, &sol.xs[n]).unwrap();
    let err: Vec<f64> = p.iter().zip(&t.params.target).map(|(a, b)| a - b).collect();
    assert!(norm(&err) <= t.example.proxddp.tol, "landing error {err:?}");
    // It was thrown: it started over a metre away from the target.
    let p0 = t.mug_position(0, &sol.xs[0]).unwrap();
    let dist: Vec<f64> = p0.iter().zip(&t.params.target).map(|(a, b)| a - b).collect();
    assert!(norm(&dist) > 2.0, "start {p0:?}");
}

#[test]
fn torques_stay_within_their_limits_and_saturate() {
    let (t, sol) = (task(), solution());
    let limits = &t.attached.model().effort_limit[..6];
    let tol = t.example.proxddp.tol;
    let mut saturated = 0;
    for (k, u) in sol.us.iter().enumerate() {
        for (j, (&uj, &lim)) in u.iter().zip(limits).enumerate() {
            assert!(uj.abs() <= lim + tol, "u[{k}][{j}] = {uj} beyond {lim}");
            if uj.abs() >= lim - 1e-2 {
                saturated += 1;
            }
        }
    }
    assert!(saturated > 0, "no torque reaches its limit");
    let nq = t.attached.nq();
    let vmax = &t.attached.model().velocity_limit[..6];
    let ratio = sol
        .xs
        .iter()
        .flat_map(|x| (0..6).map(move |j| x[nq + j].abs() / vmax[j]));
    eprintln!(
        "ur10-ballistic: {saturated} (stage, joint) pairs at their torque limit; max |v|/v_max = {:.2}",
        ratio.fold(0.0_f64, f64::max)
    );
}

#[test]
fn the_mug_is_held_until_the_release() {
    let (t, sol) = (task(), solution());
    let nc = t.release_node();
    let worst = (0..nc)
        .map(|k| t.grasp_error(&sol.xs[k]).unwrap())
        .fold(0.0_f64, f64::max);
    assert!(worst <= t.example.proxddp.tol, "grasp constraint violated by {worst}");
    // The released state is the held one: the mug where the grasp frame put it.
    let (before, after) = (&sol.xs[nc - 1], &sol.xs[nc]);
    let moved = t.mug_position(nc, after).unwrap();
    let held = t.mug_position(nc - 1, before).unwrap();
    let v: Vec<f64> = moved.iter().zip(&held).map(|(a, b)| (a - b) / t.params.dt).collect();
    // One step apart at the launch speed (a few m/s), not a jump.
    assert!(norm(&v) < 20.0 && norm(&v) > 1.0, "launch speed {v:?}");
}

#[test]
fn the_flying_mug_follows_a_ballistic_parabola() {
    let (t, sol) = (task(), solution());
    let (nc, n, dt) = (t.release_node(), t.params.horizon, t.params.dt);
    let p: Vec<[f64; 3]> = (nc..=n).map(|k| t.mug_position(k, &sol.xs[k]).unwrap()).collect();
    let mut worst = 0.0_f64;
    for k in 1..p.len() - 1 {
        let a: Vec<f64> = (0..3)
            .map(|i| (p[k + 1][i] - 2.0 * p[k][i] + p[k - 1][i]) / (dt * dt))
            .collect();
        worst = worst.max(norm(&[a[0], a[1], a[2] + G]));
    }
    // The states satisfy the dynamics up to the primal tolerance; the second difference
    // divides the gaps by dt².
    let bound = 4.0 * sol.prim_err / (dt * dt) + 1e-6;
    eprintln!(
        "ur10-ballistic: finite-difference acceleration in flight within {worst:.3e} m/s² of g (bound {bound:.1e})"
    );
    assert!(worst <= bound, "acceleration off gravity by {worst}");
    // The exact parabola from the release state lands on the target too.
    let (x, nq) = (&sol.xs[nc], t.flight.nq());
    let tf = (n - nc) as f64 * dt;
    let v = &x[nq + 6..nq + 9];
    let exact: Vec<f64> = (0..3)
        .map(|i| p[0][i] + v[i] * tf - if i == 2 { 0.5 * G * tf * tf } else { 0.0 })
        .collect();
    let miss: Vec<f64> = exact.iter().zip(&t.params.target).map(|(a, b)| a - b).collect();
    // Semi-implicit Euler's O(dt) error of a parabola: g dt T / 2 in height.
    assert!(norm(&miss) < 0.6 * G * dt * tf + 1e-3, "exact landing {exact:?}");
    // The ODE itself: the mug's centre accelerates at exactly g in flight, whatever the
    // arm does.
    let ode = MultibodyFreeFwdDynamics::new(
        t.flight.clone(),
        Actuation::dofs(t.flight.model(), &(0..6).collect::<Vec<_>>()).unwrap(),
    )
    .unwrap();
    let mut data = ode.create_data();
    for k in nc..n {
        ode.evaluate(&sol.xs[k], &sol.us[k], &mut data);
        let a = &data.xdot()[t.flight.nv() + 6..t.flight.nv() + 9];
        assert!(norm(&[a[0], a[1], a[2] + G]) < 1e-9, "node {k}: {a:?}");
    }
}

#[test]
fn the_release_stage_jacobians_match_finite_differences() {
    let t = task();
    let stage = &t.example.problem.stages()[t.release_node() - 1];
    let Dynamics::Explicit(release) = &stage.dynamics else {
        panic!("the release stage has explicit dynamics")
    };
    let mut rng = SmallRng::seed_from_u64(5);
    let space = t.attached.clone();
    for _ in 0..3 {
        // Near the grasp, arm and mug moving.
        let dx: Vec<f64> = (0..space.ndx()).map(|_| 0.3 * rng.random_range(-1.0..1.0)).collect();
        let mut x = vec![0.0; space.nx()];
        space.integrate(&t.x0, &dx, &mut x);
        let u: Vec<f64> = t.tau0.iter().map(|u| u + 5.0 * rng.random_range(-1.0..1.0)).collect();
        check_explicit_dynamics(release.as_ref(), &x, &u, CheckOptions { eps: 1e-6, tol: 1e-5 }).assert_ok();
    }
}

#[test]
fn the_release_stage_allocates_nothing() {
    let t = task();
    let Dynamics::Explicit(release) = &t.example.problem.stages()[t.release_node() - 1].dynamics else {
        panic!("the release stage has explicit dynamics")
    };
    let mut data = release.create_data();
    // A first call (which may set up thread-local state of the linear algebra), then a
    // call at another point.
    release.forward(&t.x0, &t.tau0, &mut data);
    release.jacobians(&t.x0, &t.tau0, &mut data);
    let u: Vec<f64> = t.tau0.iter().map(|u| u + 1.0).collect();
    let x = &t.x0;
    let n = counting_alloc::local_allocations_during(|| {
        release.forward(x, &u, &mut data);
        release.jacobians(x, &u, &mut data);
    });
    assert!(gharial::linalg::slice(&data.xnext).iter().all(|v| v.is_finite()));
    assert_eq!(n, 0, "release forward + jacobians allocated {n} times");
}

#[test]
fn the_quasi_static_torque_carries_the_mug() {
    let t = task();
    // Independent: the UR10 with the mug's inertia welded to the wrist at the grasp.
    let mut welded = Model::from_urdf_str(gharial_problems::robots::UR10_URDF, RootJoint::Fixed).unwrap();
    let tool = welded.frames()[welded.frame_id("tool0").unwrap()].clone();
    let grasp = tool
        .placement
        .compose(&Se3::new(Mat3::identity(), Vec3::new(0.0, 0.0, t.params.grasp_offset)));
    let mug = t.attached.model();
    let id = mug.joint_id(MUG_JOINT).unwrap();
    welded
        .append_body_to_joint(tool.parent_joint, &mug.inertias()[id], &grasp)
        .unwrap();
    assert!((welded.total_mass() - mug.total_mass()).abs() < 1e-12);
    let g = gravity_compensation(&welded, &Actuation::full(&welded), &t.params.q0).unwrap();
    let diff = g.iter().zip(&t.tau0).fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff < 1e-9, "{g:?} vs {:?}", t.tau0);
    // It holds the arm and mug at rest: the guess's attached nodes are a rollout.
    let xs = gharial_problems::rollout(&t.example.problem, &t.example.us0).unwrap();
    for x in &xs[..t.release_node()] {
        let gap = x.iter().zip(&t.x0).fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(gap < 1e-10, "drift {gap}");
    }
    // The mug starts at the grasp frame.
    let mut data = mug.create_data();
    forward_kinematics_placements(mug, &mut data, &t.x0[..t.attached.nq()]).unwrap();
    let expected = data.joint_placement(tool.parent_joint).compose(&grasp).translation;
    let p = t.mug_position(0, &t.x0).unwrap();
    assert!((Vec3::new(p[0], p[1], p[2]) - expected).norm() < 1e-12);
}

#[test]
fn figure_data_lists_the_solution_and_its_convergence() {
    let (t, sol) = (task(), solution());
    let figs = t.figure_csv(sol).unwrap();
    let rows: Vec<Vec<&str>> = figs.trajectory.lines().map(|l| l.split(',').collect()).collect();
    let header = &rows[0];
    assert_eq!(rows.len(), t.params.horizon + 2);
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("{name}"))
    };
    let num = |s: &str| s.parse::<f64>().unwrap();
    let (tau, tau_max, v, v_max) = (
        col("tau_elbow_joint"),
        col("tau_max_elbow_joint"),
        col("v_wrist_1_joint"),
        col("v_max_wrist_1_joint"),
    );
    let nq = t.attached.nq();
    for (k, row) in rows[1..].iter().enumerate() {
        assert_eq!(row.len(), header.len());
        assert!((num(row[0]) - k as f64 * t.params.dt).abs() < 1e-12);
        match sol.us.get(k) {
            Some(u) => assert_eq!(num(row[tau]), u[2]),
            None => assert!(row[tau].is_empty()),
        }
        assert_eq!(num(row[tau_max]), 150.0);
        assert_eq!(num(row[v]), sol.xs[k][nq + 3]);
        assert_eq!(num(row[v_max]), 3.2);
        let p = t.mug_position(k, &sol.xs[k]).unwrap();
        assert_eq!(num(row[col("mug_z")]), p[2]);
        assert_eq!(row[col("attached")], if k < t.release_node() { "1" } else { "0" });
    }
    let conv: Vec<Vec<&str>> = figs.convergence.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(conv[0], ["iter", "prim_err", "dual_err", "mu", "al_iter"]);
    assert_eq!(conv.len(), sol.history.len() + 1);
    for (r, h) in conv[1..].iter().zip(&sol.history) {
        assert_eq!((num(r[1]), num(r[2])), (h.prim_err, h.dual_err));
    }
    let wrong = Solution {
        us: vec![],
        ..sol.clone()
    };
    assert!(t.figure_csv(&wrong).is_err());
}

#[test]
fn bad_parameters_are_errors() {
    let p = Ur10BallisticParams {
        contact_stages: 0,
        ..Default::default()
    };
    assert!(
        Ur10Ballistic::new(p)
            .unwrap_err()
            .to_string()
            .contains("contact_stages")
    );
    let p = Ur10BallisticParams {
        gains: (-1.0, 0.0),
        ..Default::default()
    };
    assert!(Ur10Ballistic::new(p).is_err());
    assert!(gharial_problems::build("ur10-ballistic").is_ok());
    let _: Arc<dyn Manifold> = task().flight.clone();
}
