//! The data of the papers' figures for the experiments that have them, as CSV files
//! named after the figure (`gharial solve NAME --figures DIR`).

use gharial::Result;
use gharial::solvers::Solution;

/// The figure files of problem `name` at `solution` (file name, CSV text), or `None` if
/// the problem has no figure data.
///
/// # Errors
/// If the solution does not fit the problem.
pub fn figures(name: &str, solution: &Solution) -> Option<Result<Vec<(&'static str, String)>>> {
    match name {
        "ur10-ballistic" => Some(ur10(solution)),
        "solo-jump" => Some(solo_jump(solution)),
        _ => None,
    }
}

fn ur10(solution: &Solution) -> Result<Vec<(&'static str, String)>> {
    let task = crate::ur10_ballistic::Ur10Ballistic::new(Default::default())?;
    let f = task.figure_csv(solution)?;
    Ok(vec![
        ("ur10-ballistic-trajectory.csv", f.trajectory),
        ("ur10-ballistic-convergence.csv", f.convergence),
    ])
}

fn solo_jump(solution: &Solution) -> Result<Vec<(&'static str, String)>> {
    let setup = crate::solo_jump::JumpSetup::new(&Default::default())?;
    let f = setup.figures(solution)?;
    Ok(vec![
        ("solo-jump-trajectory.csv", f.trajectory),
        ("solo-jump-convergence.csv", f.convergence),
    ])
}
