//! Pictures from Python: plots of results (`Results.plot`, `gharial.plot_convergence`)
//! and the 3D viewer page of a robot's trajectory (`gharial.view`).

use std::path::{Path, PathBuf};

use gharial::solvers::Solution;
use gharial::solvers::ddp::control_bounds;
use gharial_viz::viewer::{MeshSearch, Scene, page};
use gharial_viz::{Run, Trajectory, convergence, trajectory};
use pyo3::prelude::*;

use crate::convert::{value_error, vectors};
use crate::problem::PyProblem;
use crate::robots::PyRobotModel;
use crate::solvers::PyResults;

/// A drawing error as a Python `ValueError`.
fn viz_err(e: gharial_viz::Error) -> PyErr {
    value_error(e.to_string())
}

/// `<directory>/<name>-convergence.<format>` and `<name>-trajectory.<format>` of a
/// solution; the files written.
pub fn plot_solution(
    s: &Solution,
    directory: &str,
    name: &str,
    dt: Option<f64>,
    problem: Option<&Bound<'_, PyProblem>>,
    format: &str,
) -> PyResult<Vec<String>> {
    if !matches!(format, "png" | "svg") {
        return Err(value_error(format!(
            "format must be \"png\" or \"svg\", got {format:?}"
        )));
    }
    std::fs::create_dir_all(directory).map_err(|e| value_error(format!("cannot make {directory}: {e}")))?;
    let file = |what: &str| -> PathBuf { Path::new(directory).join(format!("{name}-{what}.{format}")) };
    let (c, t) = (file("convergence"), file("trajectory"));
    convergence(&[Run::from_solution(name, s)], name, &c).map_err(viz_err)?;
    // The control bounds when the problem's path constraints are bounds on the controls.
    let (u_lower, u_upper) = match problem {
        Some(p) => {
            let p = p.borrow_mut().problem(p.py())?;
            control_bounds(&p, &s.xs, &s.us).unwrap_or_default()
        }
        None => Default::default(),
    };
    let traj = Trajectory {
        title: name.to_string(),
        dt,
        xs: s.xs.clone(),
        us: s.us.clone(),
        u_lower,
        u_upper,
    };
    trajectory(&traj, &t).map_err(viz_err)?;
    Ok(vec![c.display().to_string(), t.display().to_string()])
}

/// Draws the residuals of several solves on one plot: `runs` is a list of `(label,
/// Results)` pairs (`list(d.items())` of a dict).
#[pyfunction]
#[pyo3(signature = (runs, path, title = "convergence"))]
fn plot_convergence(runs: Vec<(String, PyRef<'_, PyResults>)>, path: &str, title: &str) -> PyResult<()> {
    let runs: Vec<Run> = runs.iter().map(|(label, r)| Run::from_solution(label, &r.s)).collect();
    convergence(&runs, title, Path::new(path)).map_err(viz_err)?;
    Ok(())
}

/// Writes the 3D viewer page (one self-contained HTML file) of `robot` along the states
/// `xs` (a `Results`, or a list of states whose first `nq` entries are the
/// configuration), `dt` seconds apart, with `targets` marked; returns the path. Meshes
/// resolve through `GHARIAL_MESH_PATH`, `ROS_PACKAGE_PATH` and example-robot-data.
#[pyfunction]
#[pyo3(signature = (xs, robot, path, dt, targets = Vec::new(), title = "gharial"))]
fn view(
    xs: &Bound<'_, PyAny>,
    robot: &PyRobotModel,
    path: &str,
    dt: f64,
    targets: Vec<[f64; 3]>,
    title: &str,
) -> PyResult<String> {
    let model = robot.model();
    let nq = model.nq();
    let xs = match xs.cast::<PyResults>() {
        Ok(r) => r.borrow().s.xs.clone(),
        Err(_) => vectors(xs, "xs")?,
    };
    if let Some((t, x)) = xs.iter().enumerate().find(|(_, x)| x.len() < nq) {
        return Err(value_error(format!(
            "xs[{t}] has {} entries, the robot's configuration {nq}",
            x.len()
        )));
    }
    let qs: Vec<Vec<f64>> = xs.iter().map(|x| x[..nq].to_vec()).collect();
    let mut scene = Scene::new(title, dt);
    scene.add_robot(model, &qs, &MeshSearch::from_env()).map_err(viz_err)?;
    for p in targets {
        scene.add_target(p, 0.04);
    }
    let html = page(&scene).map_err(viz_err)?;
    std::fs::write(path, html).map_err(|e| value_error(format!("cannot write {path}: {e}")))?;
    Ok(path.to_string())
}

/// Registers the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(plot_convergence, m)?)?;
    m.add_function(wrap_pyfunction!(view, m)?)?;
    Ok(())
}
