//! Friction-cone margins of a solution, the forces recomputed by the contact dynamics.

use gharial::solvers::Solution;
use gharial_robotics::MultibodyConstraintFwdDynamics;

/// `‖f_t‖ − μ f_n` (N) of each of four point contacts at each stage of `sol`, the forces
/// recomputed by `dynamics` at the solution's states and controls.
pub fn cone_margins(dynamics: &MultibodyConstraintFwdDynamics, mu: f64, sol: &Solution) -> Vec<[f64; 4]> {
    let mut d = dynamics.create_contact_data();
    sol.us
        .iter()
        .zip(&sol.xs)
        .map(|(u, x)| {
            let f = dynamics.contact_forces(x, u, &mut d).unwrap();
            std::array::from_fn(|j| f[3 * j].hypot(f[3 * j + 1]) - mu * f[3 * j + 2])
        })
        .collect()
}
