//! ALTRO's Table I problems (`altro_table`) solved by ProxDDP to the paper's constraint
//! tolerance 1e-8: the goal reached, the bounds and discs respected at every node, the
//! KKT residuals recomputed independently of the solver.

use gharial::problem::kkt_residuals;
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver, Status};

fn solve(name: &str) -> (gharial_problems::Example, Solution) {
    solve_to(name, 1e-7)
}

/// `name` solved by ProxDDP at its settings, its KKT residuals below `kkt_tol`.
fn solve_to(name: &str, kkt_tol: f64) -> (gharial_problems::Example, Solution) {
    let ex = gharial_problems::build(name).unwrap();
    let mut solver = ProxDdp::new(ex.proxddp.clone());
    solver.setup(&ex.problem).unwrap();
    let sol = solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone();
    assert_eq!(sol.status, Status::Converged, "{name}");
    let kkt = kkt_residuals(&ex.problem, &sol.xs, &sol.us, &sol.lambdas, &sol.nus).unwrap();
    assert!(kkt.max() < kkt_tol, "{name}: {kkt:?}");
    eprintln!("{name}: {} iterations, cost {}", sol.iterations, sol.cost);
    (ex, sol)
}

/// Largest violation of `goal` by the last state.
fn goal_error(sol: &Solution, goal: &[f64]) -> f64 {
    sol.xs
        .last()
        .unwrap()
        .iter()
        .zip(goal)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

#[test]
fn block_move_reaches_its_goal_within_the_control_limits() {
    let (_, sol) = solve("block-move");
    assert!(goal_error(&sol, &[1.0, 0.0]) < 1e-8);
    let umax = sol.us.iter().map(|u| u[0].abs()).fold(0.0, f64::max);
    assert!(umax <= 1.5 + 1e-8, "{umax}");
    // The bound is active: the unconstrained move would push harder.
    assert!(umax > 1.5 - 1e-6, "{umax}");
}

#[test]
fn parallel_park_stays_in_its_box() {
    let (_, sol) = solve("car-parallel-park");
    assert!(goal_error(&sol, &[0.0, 1.0, 0.0]) < 1e-8);
    for x in &sol.xs {
        assert!(
            x[0].abs() <= 0.25 + 1e-8 && (-0.001 - 1e-8..=1.001 + 1e-8).contains(&x[1]),
            "{x:?}"
        );
    }
    for u in &sol.us {
        assert!(u.iter().all(|v| v.abs() <= 2.0 + 1e-8), "{u:?}");
    }
}

#[test]
fn car_avoids_the_three_discs() {
    let (_, sol) = solve("car-3-obstacles");
    assert!(goal_error(&sol, &[1.0, 1.0, 0.0]) < 1e-8);
    let mut closest = f64::INFINITY;
    for x in &sol.xs {
        for c in [0.25, 0.5, 0.75] {
            closest = closest.min(((x[0] - c).powi(2) + (x[1] - c).powi(2)).sqrt() - 0.1);
        }
    }
    // Outside every disc (the optimal S-curve, which starts and ends heading along x,
    // passes them at a distance).
    assert!(closest > -1e-8, "{closest:e}");
    eprintln!("car-3-obstacles: closest approach {closest:.4} outside a disc");
}

/// The UR5 moves between its two configurations with its tool outside both spheres at
/// every node (positions by forward kinematics here, not through the solver's residual)
/// and every torque within the URDF's effort limits.
#[test]
fn arm_avoids_the_spheres_within_its_torque_limits() {
    use gharial_multibody::{Data, Model, RootJoint, forward_kinematics_placements, update_frame_placements};
    let t = std::time::Instant::now();
    let free = gharial_problems::altro_table::arm_free().unwrap();
    let mut solver = ProxDdp::new(free.proxddp.clone().with(|o| o.tol = 1e-8));
    solver.setup(&free.problem).unwrap();
    let free_sol = solver
        .solve(&free.problem, InitialGuess::primal(&free.xs0, &free.us0))
        .unwrap()
        .clone();
    assert_eq!(free_sol.status, Status::Converged);
    let (ex, sol) = solve_to("arm-obstacles", 1e-6);
    eprintln!(
        "arm-obstacles: solved in {:.2} s (debug build)",
        t.elapsed().as_secs_f64()
    );
    let xb = [1.5, -1.4, 1.6, -0.5, -0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert!(goal_error(&sol, &xb) < 1e-6);
    let model = Model::from_urdf_str(gharial_problems::robots::UR5_URDF, RootJoint::Fixed).unwrap();
    let mut data = Data::new(&model);
    let tool = model.frame_id("tool0").unwrap();
    let mut tool_at = |q: &[f64]| {
        forward_kinematics_placements(&model, &mut data, q).unwrap();
        update_frame_placements(&model, &mut data).unwrap();
        data.frame_placement(tool).translation
    };
    let centres = gharial_problems::altro_table::ARM_CENTRES;
    let r = gharial_problems::altro_table::ARM_RADIUS;
    let mut closest = f64::INFINITY;
    for x in &sol.xs {
        let p = tool_at(&x[..6]);
        for c in &centres {
            let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
            closest = closest.min(d - r);
        }
    }
    // Outside both spheres, touching them (they bend the motion).
    assert!(closest > -1e-6 && closest < 1e-4, "{closest:e}");
    // The spheres are in the way: the motion without them passes 2 cm below each centre.
    let n = free_sol.xs.len() - 1;
    for (k, c) in centres.iter().enumerate() {
        let p = tool_at(&free_sol.xs[(k + 1) * n / 3][..6]);
        let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
        assert!((d - 0.02).abs() < 1e-6, "{d}");
    }
    let mut worst_u = f64::NEG_INFINITY;
    for u in &sol.us {
        for (v, limit) in u.iter().zip(&model.effort_limit) {
            worst_u = worst_u.max(v.abs() - limit);
        }
    }
    assert!(worst_u <= 1e-6, "{worst_u:e}");
    eprintln!(
        "arm-obstacles: {} iterations, closest approach {closest:.1e} m outside a sphere, \
         largest torque {worst_u:.2} N m from its limit; initial guess {} nodes",
        sol.iterations,
        ex.xs0.len()
    );
}
