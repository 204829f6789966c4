//! The UR5 circle-tracking task (`gharial_problems::ur5_circle`):
//! - the reference is the documented circle (centre, radius, plane, speed, start at the
//!   initial tool position), checked from sampled points;
//! - every stage owns its tracking target: moving one changes that stage's cost by the
//!   exact tracking difference and no other stage's; `set_horizon` places every target;
//! - each variant's first OCP converges with ProxDDP (KKT residuals recomputed), its
//!   constraint holds at the solution, is active, and is violated by the unconstrained
//!   solution;
//! - the constraint functions (a box on `q_1`, the half-space through the frame
//!   translation) against finite differences and independent values;
//! - a nominal closed loop (MPC at 100 Hz on a plant integrated at 1 ms) tracks the
//!   circle to the documented errors.
//!
//! The tool position is computed independently of the task, from the URDF, through
//! `gharial-multibody`'s forward kinematics.

use std::f64::consts::PI;
use std::sync::Arc;

use gharial::check::{CheckOptions, check_stage_function};
use gharial::costs::Cost;
use gharial::dynamics::{ExplicitDynamics, ExplicitDynamicsData, SemiImplicitEuler};
use gharial::mpc::{ClosedLoop, Mpc, MpcOptions, simulate};
use gharial::problem::{Problem, kkt_residuals};
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver, Status};
use gharial_multibody::{Data, Model, RootJoint, forward_kinematics_placements, update_frame_placements};
use gharial_problems::ur5_circle::{
    CircleTask, CircleVariant, DT, HORIZON, JOINT_BOUND, OMEGA, Q0, RADIUS, build, proxddp_options,
};
use gharial_robotics::{Actuation, MultibodyFreeFwdDynamics, MultibodyPhaseSpace, gravity_compensation};

const URDF: &str = gharial_problems::robots::UR5_URDF;

/// The UR5 and its `tool0` frame, evaluated directly with the multibody crate.
struct Kinematics {
    model: Arc<Model>,
    data: Data,
    tool: usize,
}

impl Kinematics {
    fn new() -> Self {
        let model = Arc::new(Model::from_urdf_str(URDF, RootJoint::Fixed).unwrap());
        let tool = model.frame_id("tool0").unwrap();
        Self {
            data: Data::new(&model),
            model,
            tool,
        }
    }

    /// The world position of `tool0` at the state `x = (q, v)`.
    fn tool(&mut self, x: &[f64]) -> [f64; 3] {
        forward_kinematics_placements(&self.model, &mut self.data, &x[..6]).unwrap();
        update_frame_placements(&self.model, &mut self.data).unwrap();
        let p = self.data.frame_placement(self.tool).translation;
        [p[0], p[1], p[2]]
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
}

fn x0() -> Vec<f64> {
    Q0.iter().copied().chain([0.0; 6]).collect()
}

/// The cost `ℓ_t(x, u)` of running stage `t` (`t = N`: the terminal cost at `x`).
fn stage_cost(problem: &Problem, t: usize, x: &[f64], u: &[f64]) -> f64 {
    let cost: &Arc<dyn Cost> = if t < problem.horizon() {
        &problem.stages()[t].cost
    } else {
        problem.terminal_cost()
    };
    let mut data = cost.create_data();
    cost.evaluate(x, if t < problem.horizon() { u } else { &[] }, &mut data);
    data.value
}

fn solve(problem: &Problem, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Solution {
    let mut solver = ProxDdp::new(proxddp_options());
    solver.setup(problem).unwrap();
    solver.solve(problem, InitialGuess::primal(xs, us)).unwrap().clone()
}

#[test]
fn the_reference_is_the_documented_circle() {
    let task = CircleTask::new(CircleVariant::Free).unwrap();
    let p0 = Kinematics::new().tool(&x0());
    // It starts at the initial tool position, at the lowest point of the circle.
    assert!(
        dist(task.reference(0.0), p0) < 1e-14,
        "{:?} vs {p0:?}",
        task.reference(0.0)
    );
    let samples: Vec<[f64; 3]> = (0..97).map(|k| task.reference(0.0377 * k as f64)).collect();
    // Centre from antipodal points (half a period apart), then every sample at distance r
    // from it in the plane x = c_x.
    let half = PI / OMEGA;
    for k in 0..20 {
        let t = 0.11 * k as f64;
        let (a, b) = (task.reference(t), task.reference(t + half));
        let c = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0, (a[2] + b[2]) / 2.0];
        assert!(dist(c, [p0[0], p0[1], p0[2] + RADIUS]) < 1e-14, "centre {c:?}");
        assert!(dist(c, task.circle().centre) < 1e-15, "{c:?}");
    }
    let c = task.circle().centre;
    for p in &samples {
        assert!((dist(*p, c) - 0.3).abs() < 1e-14, "{p:?}");
        assert_eq!(p[0], p0[0]);
        assert!(p[2] >= p0[2] - 1e-15 && p[2] <= p0[2] + 0.6 + 1e-15, "{p:?}");
    }
    // Speed r ω, towards +y at t = 0; period 2π/ω.
    let h = 1e-6;
    for t in [0.0, 0.4, 1.3] {
        let (a, b) = (task.reference(t - h), task.reference(t + h));
        let speed = dist(a, b) / (2.0 * h);
        assert!((speed - 0.6).abs() < 1e-8, "speed {speed} at {t}");
        assert!(dist(task.reference(t), task.reference(t + 2.0 * PI / OMEGA)) < 1e-14);
    }
    let v0 = (task.reference(h)[1] - task.reference(-h)[1]) / (2.0 * h);
    assert!((v0 - 0.6).abs() < 1e-8, "{v0}");
}

#[test]
fn the_task_starts_at_rest_with_gravity_compensation() {
    let task = CircleTask::new(CircleVariant::Free).unwrap();
    assert_eq!(task.x0, x0());
    assert_eq!(task.problem.x0().unwrap(), task.x0.as_slice());
    assert_eq!(task.problem.horizon(), HORIZON);
    let model = Model::from_urdf_str(URDF, RootJoint::Fixed).unwrap();
    let g = gravity_compensation(&model, &Actuation::full(&model), &Q0).unwrap();
    assert_eq!(task.us0, vec![g; HORIZON]);
    // The guess holds the robot still: its rollout stays at x0.
    let ex = build(CircleVariant::Free).unwrap();
    assert_eq!(ex.dt, Some(DT));
    let drift = ex
        .xs0
        .iter()
        .flat_map(|x| x.iter().zip(&task.x0).map(|(a, b)| (a - b).abs()))
        .fold(0.0, f64::max);
    assert!(drift < 1e-12, "{drift:e}");
}

#[test]
fn every_stage_owns_its_target() {
    let task = CircleTask::new(CircleVariant::Free).unwrap();
    let p = &task.problem;
    let n = p.horizon();
    for i in 0..n {
        for j in 0..i {
            assert!(!Arc::ptr_eq(&p.stages()[i].cost, &p.stages()[j].cost), "{i} {j}");
            let (a, b) = (task.stage_residual(i).unwrap(), task.stage_residual(j).unwrap());
            assert!(!Arc::ptr_eq(a, b));
        }
    }
    // A state away from the circle, so that every tracking term is nonzero.
    let mut x = x0();
    x[0] = 0.3;
    x[2] = 1.5;
    x[7] = 0.2;
    let u = vec![1.0; 6];
    let p_x = Kinematics::new().tool(&x);
    let before: Vec<f64> = (0..=n).map(|t| stage_cost(p, t, &x, &u)).collect();
    // ½ w ‖p − p*‖², w = 20, times dt on running stages.
    let tracking = |target: [f64; 3], scale: f64| scale * 0.5 * 20.0 * dist(p_x, target).powi(2);

    let (k, time) = (3, 1.234);
    task.set_stage_target(k, time).unwrap();
    assert_eq!(task.stage_residual(k).unwrap().target(), task.reference(time).to_vec());
    for t in 0..=n {
        let after = stage_cost(p, t, &x, &u);
        if t == k {
            let expected = before[t] + tracking(task.reference(time), DT) - tracking(task.reference(k as f64 * DT), DT);
            assert!((after - expected).abs() < 1e-13, "stage {t}: {after} vs {expected}");
            assert!((after - before[t]).abs() > 1e-3, "stage {t} unchanged");
        } else {
            assert_eq!(after, before[t], "stage {t} changed");
        }
    }
    task.set_terminal_target(2.0).unwrap();
    let expected = before[n] + tracking(task.reference(2.0), 1.0) - tracking(task.reference(n as f64 * DT), 1.0);
    assert!((stage_cost(p, n, &x, &u) - expected).abs() < 1e-12);
    assert_eq!(stage_cost(p, n - 1, &x, &u), before[n - 1]);

    // set_horizon places stage object i at t0 + i dt and the terminal at t0 + N dt.
    let t0 = 0.77;
    task.set_horizon(t0).unwrap();
    for i in 0..n {
        let target = task.stage_residual(i).unwrap().target();
        assert_eq!(target, task.reference(t0 + i as f64 * DT).to_vec(), "stage {i}");
    }
    assert_eq!(
        task.terminal_residual().target(),
        task.reference(t0 + n as f64 * DT).to_vec()
    );
    task.set_horizon(0.0).unwrap();
    for t in 0..=n {
        let cost = stage_cost(p, t, &x, &u);
        assert!((cost - before[t]).abs() <= 1e-15 * before[t].abs(), "stage {t}");
    }

    // Bad input: errors naming the index or the time; the targets unchanged.
    let err = task.set_stage_target(n, 0.0).unwrap_err().to_string();
    assert!(err.contains("stage object 10") && err.contains("horizon 10"), "{err}");
    let err = task.set_stage_target(2, f64::NAN).unwrap_err().to_string();
    assert!(err.contains("set_stage_target") && err.contains("NaN"), "{err}");
    assert!(task.set_terminal_target(f64::INFINITY).is_err());
    assert!(task.set_horizon(f64::NAN).is_err());
    assert!(task.stage_residual(n).is_none());
    for i in 0..n {
        let target = task.stage_residual(i).unwrap().target();
        assert_eq!(target, task.reference(i as f64 * DT).to_vec(), "stage {i}");
    }
}

/// Largest `|q_1|` and largest tool `y` over the knots of `sol`.
fn extremes(sol: &Solution) -> (f64, f64) {
    let mut kin = Kinematics::new();
    let q1 = sol.xs.iter().map(|x| x[0].abs()).fold(0.0, f64::max);
    let y = sol.xs.iter().map(|x| kin.tool(x)[1]).fold(f64::NEG_INFINITY, f64::max);
    (q1, y)
}

#[test]
fn each_variant_converges_and_its_constraint_binds() {
    let y_max = CircleTask::new(CircleVariant::HalfSpace).unwrap().y_max();
    let mut free = None;
    for (variant, name) in [
        (CircleVariant::Free, "ur5-circle"),
        (CircleVariant::JointBound, "ur5-circle-joint-bound"),
        (CircleVariant::HalfSpace, "ur5-circle-half-space"),
    ] {
        let ex = gharial_problems::build(name).unwrap();
        let sol = solve(&ex.problem, &ex.xs0, &ex.us0);
        assert_eq!(sol.status, Status::Converged, "{name}: {} iterations", sol.iterations);
        let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
        assert!(kkt.max() < 1e-6, "{name}: {kkt:?}");
        eprintln!(
            "{name}: {} iterations ({} AL), cost {:.10}",
            sol.iterations, sol.al_iterations, sol.cost
        );
        let (q1, y) = extremes(&sol);
        match variant {
            CircleVariant::Free => free = Some((q1, y)),
            CircleVariant::JointBound => {
                assert!(q1 <= JOINT_BOUND + 1e-6, "{name}: |q1| {q1}");
                assert!(q1 >= JOINT_BOUND - 1e-6, "{name}: the bound is not active: {q1}");
                let nu_max = sol.nus.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
                assert!(nu_max > 1e-3, "{name}: multipliers {:?}", sol.nus);
            }
            CircleVariant::HalfSpace => {
                assert!(y <= y_max + 1e-6, "{name}: y {y} > {y_max}");
                assert!(y >= y_max - 1e-6, "{name}: the half-space is not active: {y}");
                let nu_max = sol.nus.iter().flatten().fold(0.0, |a: f64, &v| a.max(v));
                assert!(nu_max > 1e-3, "{name}: multipliers {:?}", sol.nus);
            }
        }
    }
    // The unconstrained solution violates both constraints by far.
    let (q1, y) = free.unwrap();
    assert!(q1 > 0.3, "free |q1| {q1}");
    assert!(y > y_max + 0.05, "free y {y} vs {y_max}");
}

#[test]
fn constraint_functions_match_finite_differences_and_independent_values() {
    let mut kin = Kinematics::new();
    let model = Arc::new(Model::from_urdf_str(URDF, RootJoint::Fixed).unwrap());
    let space = MultibodyPhaseSpace::new(model);
    let states: Vec<Vec<f64>> = (0..5)
        .map(|k| {
            let s = k as f64;
            (0..12)
                .map(|i| Q0.get(i).copied().unwrap_or(0.0) + 0.3 * (1.7 * s + 0.9 * i as f64).sin())
                .collect()
        })
        .collect();
    for (variant, bound) in [
        (CircleVariant::JointBound, JOINT_BOUND),
        (CircleVariant::HalfSpace, f64::NAN),
    ] {
        let task = CircleTask::new(variant).unwrap();
        let p = &task.problem;
        let stage = &p.stages()[4];
        let terminal = &p.terminal_constraints()[0];
        assert_eq!((stage.constraints().len(), p.terminal_constraints().len()), (1, 1));
        for c in [&stage.constraints()[0], terminal] {
            let f = c.func.as_ref();
            let u = vec![0.5; f.nu()];
            for x in &states {
                let rep = check_stage_function(f, &space, x, &u, None, CheckOptions::default());
                assert!(rep.passed(), "{variant:?} {}: {:?}", c.name, rep.errors);
                let mut data = f.create_data();
                f.evaluate(x, &u, &mut data);
                let expected = match variant {
                    CircleVariant::JointBound => x[0],
                    _ => kin.tool(x)[1] - task.y_max(),
                };
                assert!((data.value()[0] - expected).abs() < 1e-14, "{variant:?}");
            }
        }
        if variant == CircleVariant::JointBound {
            let (mut lower, mut upper) = ([0.0], [0.0]);
            assert!(stage.constraints()[0].set.box_bounds(&mut lower, &mut upper));
            assert_eq!((lower[0], upper[0]), (-bound, bound));
        }
    }
    // The half-space bound c_y + r/2.
    let task = CircleTask::new(CircleVariant::HalfSpace).unwrap();
    assert_eq!(task.y_max(), task.circle().centre[1] + RADIUS / 2.0);
    assert_eq!(task.variant(), CircleVariant::HalfSpace);
}

/// The plant: the UR5's ABA integrated by semi-implicit Euler at 1 ms.
struct Plant {
    step: SemiImplicitEuler,
    data: ExplicitDynamicsData,
}

impl Plant {
    const H: f64 = 1e-3;

    fn new() -> Self {
        let model = Arc::new(Model::from_urdf_str(URDF, RootJoint::Fixed).unwrap());
        let space = Arc::new(MultibodyPhaseSpace::new(model.clone()));
        let ode = Arc::new(MultibodyFreeFwdDynamics::new(space.clone(), Actuation::full(&model)).unwrap());
        let step = SemiImplicitEuler::new(ode, space.configuration().clone(), Self::H).unwrap();
        Self {
            data: step.create_data(),
            step,
        }
    }

    fn advance(&mut self, x: &mut [f64], u: &[f64]) {
        self.step.forward(x, u, &mut self.data);
        x.copy_from_slice(self.data.xnext());
    }
}

/// What one turn of the closed loop gives: mean tracking error, largest `|q_1|` and
/// largest `y − y_max` of the plant.
struct Tracking {
    mean_error: f64,
    q1_max: f64,
    y_excess: f64,
}

/// One turn of the circle (π s) from `x0`: every 10 ms the task's targets are placed for
/// the horizon starting now, the OCP is solved from the plant's state (at most 20
/// ProxDDP iterations, warm-started from the previous solution), and its first control
/// is held on the plant for 10 ms.
fn closed_loop(variant: CircleVariant) -> Tracking {
    let mut task = CircleTask::new(variant).unwrap();
    let mut solver = ProxDdp::new(proxddp_options().with(|o| o.max_iters = 20));
    solver.setup(&task.problem).unwrap();
    let mut xs = gharial_problems::rollout(&task.problem, &task.us0).unwrap();
    let mut us = task.us0.clone();
    let (mut plant, mut kin) = (Plant::new(), Kinematics::new());
    let mut x = task.x0.clone();
    let (period, cycles) = (0.01, 314);
    let sub = (period / Plant::H).round() as usize;
    let (mut sum, mut n) = (0.0, 0);
    let mut out = Tracking {
        mean_error: 0.0,
        q1_max: 0.0,
        y_excess: f64::NEG_INFINITY,
    };
    for k in 0..cycles {
        let t = k as f64 * period;
        task.set_horizon(t).unwrap();
        task.problem.set_x0(&x).unwrap();
        xs[0].copy_from_slice(&x);
        let sol = solver.solve(&task.problem, InitialGuess::primal(&xs, &us)).unwrap();
        assert!(sol.xs.iter().flatten().all(|v| v.is_finite()), "cycle {k}");
        xs.clone_from(&sol.xs);
        us.clone_from(&sol.us);
        for s in 1..=sub {
            plant.advance(&mut x, &us[0]);
            let p = kin.tool(&x);
            sum += dist(p, task.reference(t + s as f64 * Plant::H));
            n += 1;
            out.q1_max = out.q1_max.max(x[0].abs());
            out.y_excess = out.y_excess.max(p[1] - task.y_max());
        }
    }
    out.mean_error = sum / n as f64;
    out
}

#[test]
fn closed_loop_tracking() {
    let free = closed_loop(CircleVariant::Free);
    let joint = closed_loop(CircleVariant::JointBound);
    let half = closed_loop(CircleVariant::HalfSpace);
    for (name, r) in [("free", &free), ("joint bound", &joint), ("half space", &half)] {
        eprintln!(
            "{name}: mean error {:.4} m, max |q1| {:.4} rad, max y - y_max {:.4} m",
            r.mean_error, r.q1_max, r.y_excess
        );
    }
    // Unconstrained: close tracking, with a large base rotation and y beyond y_max.
    assert!(free.mean_error < 0.02, "{}", free.mean_error);
    assert!(free.q1_max > 0.4 && free.y_excess > 0.1);
    // Joint bound: held to within a few millimetres of the bound (the OCP predicts with
    // 50 ms steps and bounds the knots), at the price of the y-motion.
    assert!(joint.q1_max < JOINT_BOUND + 0.01, "{}", joint.q1_max);
    assert!(joint.mean_error > 4.0 * free.mean_error, "{}", joint.mean_error);
    // Half-space: near the bound, and no better than the perfect clipped tracker
    // (r (√3 − π/3) / 2π = 3.27 cm) allows.
    assert!(half.y_excess < 0.01, "{}", half.y_excess);
    let clipped = RADIUS * (3f64.sqrt() - PI / 3.0) / (2.0 * PI);
    assert!(half.mean_error > clipped - 0.002, "{} vs {clipped}", half.mean_error);
    assert!(half.mean_error < clipped + 0.02, "{} vs {clipped}", half.mean_error);
}

/// The task in `gharial::mpc`: one cycle per node (50 ms), the stages rotating, the
/// feedback policy on the plant at 1 ms between cycles. After each shift the stage object
/// that entered at the back (numbered by its original index, as `set_stage_target`
/// addresses it) gets the target of its time, and the terminal stage the next one.
#[test]
fn closed_loop_with_the_mpc_module() {
    let task = CircleTask::new(CircleVariant::Free).unwrap();
    let n = HORIZON;
    let xs0 = gharial_problems::rollout(&task.problem, &task.us0).unwrap();
    // Clones of a problem share the stage costs, hence the task's handles.
    let mut mpc = Mpc::new(
        task.problem.clone(),
        ProxDdp::new(proxddp_options()),
        Vec::new(),
        InitialGuess::primal(&xs0, &task.us0),
        MpcOptions::default().with(|o| o.max_iters = 10),
    )
    .unwrap();
    let sub = (DT / Plant::H).round() as usize;
    let settings = ClosedLoop::new(63 * sub, sub);
    let mut plant = gharial::mpc::DiscretePlant::new(Arc::new(Plant::new().step));
    let rec = simulate(&mut mpc, &mut plant, &task.x0, &settings, |cycle, id, _| {
        let t0 = cycle as f64 * DT;
        task.set_stage_target(id, t0 + (n - 1) as f64 * DT)?;
        task.set_terminal_target(t0 + n as f64 * DT)
    })
    .unwrap();
    // The rotated horizon holds at knot j the target of t0 + j dt.
    let t0 = (rec.cycles.len() - 1) as f64 * DT;
    for (j, &id) in mpc.stage_ids().iter().enumerate() {
        let target = task.stage_residual(id).unwrap().target();
        let expected = task.reference(t0 + j as f64 * DT);
        assert!(dist([target[0], target[1], target[2]], expected) < 1e-14, "knot {j}");
    }
    let terminal = task.terminal_residual().target();
    let expected = task.reference(t0 + n as f64 * DT);
    assert!(dist([terminal[0], terminal[1], terminal[2]], expected) < 1e-14);
    assert_ne!(mpc.stage_ids()[0], 0, "the stages rotated");
    let mut kin = Kinematics::new();
    let errors: Vec<f64> = rec
        .xs
        .iter()
        .enumerate()
        .map(|(k, x)| dist(kin.tool(x), task.reference(k as f64 * Plant::H)))
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let iters: usize = rec.cycles.iter().map(|c| c.iterations).sum();
    eprintln!(
        "mpc module: {} cycles, {iters} iterations, mean error {mean:.4} m, max {:.4} m",
        rec.cycles.len(),
        errors.iter().fold(0.0_f64, |a, &e| a.max(e))
    );
    assert!(mean < 0.03, "{mean}");
}
