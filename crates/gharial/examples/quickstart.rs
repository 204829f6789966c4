//! A point mass in the plane driven to the origin under force limits, solved with
//! ProxDDP: the library example of the README.
//!
//! ```sh
//! cargo run --release -p gharial --example quickstart
//! ```

use std::sync::Arc;

use gharial::Result;
use gharial::constraints::BoxConstraint;
use gharial::costs::{CostStack, QuadraticControlCost, QuadraticStateCost};
use gharial::dynamics::{Dynamics, LinearDiscreteDynamics};
use gharial::functions::ControlError;
use gharial::problem::{Problem, StageConstraint, StageModel};
use gharial::solvers::InitialGuess;
use gharial::solvers::Solver;
use gharial::solvers::proxddp::{ProxDdp, ProxDdpOptions};
use gharial::spaces::{Manifold, VectorSpace};

fn main() -> Result<()> {
    // State x = (position, velocity) in R² x R², control u = force in R², dt = 50 ms.
    let (dt, horizon) = (0.05, 60);
    let space: Arc<dyn Manifold> = Arc::new(VectorSpace::new(4));
    let mut a = faer::Mat::<f64>::identity(4, 4);
    let mut b = faer::Mat::<f64>::zeros(4, 2);
    for i in 0..2 {
        a[(i, i + 2)] = dt;
        b[(i, i)] = 0.5 * dt * dt;
        b[(i + 2, i)] = dt;
    }
    let dynamics = Dynamics::Explicit(Arc::new(LinearDiscreteDynamics::new(
        a.as_ref(),
        b.as_ref(),
        &[0.0; 4],
    )?));

    // Running cost: 1/2 |x - 0|²_Wx + 1/2 |u|²_Wu; terminal cost: 1/2 |x_N|²_Wf.
    let x_ref = [0.0; 4];
    let cost = CostStack::new(space.as_ref(), 2)
        .with(
            "state",
            Arc::new(QuadraticStateCost::diagonal(
                space.clone(),
                &x_ref,
                &[1.0, 1.0, 0.1, 0.1],
                2,
            )?),
            dt,
        )?
        .with(
            "control",
            Arc::new(QuadraticControlCost::diagonal(space.as_ref(), &[0.0; 2], &[0.1; 2])?),
            dt,
        )?;
    let terminal = Arc::new(QuadraticStateCost::diagonal(space.clone(), &x_ref, &[100.0; 4], 0)?);

    // Path constraint: |u_i| <= 2 N.
    let force = Arc::new(ControlError::new(space.as_ref(), &[0.0; 2])?);
    let limits = Arc::new(BoxConstraint::new(&[-2.0; 2], &[2.0; 2])?);
    let stage =
        StageModel::new(Arc::new(cost), dynamics)?.with_constraint(StageConstraint::new("force", force, limits))?;
    let problem = Problem::new(&[1.0, -0.5, 0.0, 0.0], vec![stage; horizon], terminal)?;

    // Solve from a dynamically infeasible guess: every state at x0, zero forces.
    let xs0 = vec![vec![1.0, -0.5, 0.0, 0.0]; horizon + 1];
    let us0 = vec![vec![0.0; 2]; horizon];
    let mut solver = ProxDdp::new(ProxDdpOptions::default().with(|o| {
        o.log = gharial::solvers::log::LogSink::Stderr;
    }));
    solver.setup(&problem)?;
    let sol = solver.solve(&problem, InitialGuess::primal(&xs0, &us0))?;
    println!(
        "{} after {} iterations: cost {:.6}, final position ({:.4}, {:.4}), largest force {:.3}",
        sol.status,
        sol.iterations,
        sol.cost,
        sol.xs[horizon][0],
        sol.xs[horizon][1],
        sol.us.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs()))
    );
    Ok(())
}
