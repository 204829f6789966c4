//! `gharial view`: the 3D viewer page of a solution file (one self-contained HTML file),
//! optionally served on localhost.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpListener;
use std::path::Path;

use gharial_multibody::Model;
use gharial_problems::scenes::{ContactForces, RobotScene, contact_forces, robot_scene};
use gharial_viz::viewer::{Arrow, MeshSearch, Pose, Scene, Shape, page};
use gharial_viz::{SolutionFile, frame_paths};

/// The arguments of `gharial view`.
#[derive(clap::Args, Debug, Clone)]
pub struct ViewArgs {
    /// A solution file written by `gharial solve --output`.
    pub solution: String,
    /// The page to write (default: `<problem>-view.html`).
    #[arg(long)]
    pub out: Option<String>,
    /// Serve the page on localhost (until interrupted) instead of only writing it.
    #[arg(long)]
    pub serve: bool,
    /// Port of `--serve` (0: any free port).
    #[arg(long, default_value_t = 8000)]
    pub port: u16,
}

/// A problem's robot: its scene, its model and its configurations along a solution.
pub type Robot = (RobotScene, Model, Vec<Vec<f64>>);

/// The robot of a solution's problem (`None` for problems without a robot).
pub fn robot_of(doc: &SolutionFile) -> Result<Option<Robot>, String> {
    let Some(spec) = robot_scene(&doc.problem) else {
        return Ok(None);
    };
    let model = Model::from_urdf_str(spec.urdf, spec.root).map_err(|e| e.to_string())?;
    let nq = model.nq();
    if let Some((t, x)) = doc.xs.iter().enumerate().find(|(_, x)| x.len() < nq) {
        return Err(format!(
            "state {t} has {} entries, the robot's configuration {nq}",
            x.len()
        ));
    }
    let qs = doc.xs.iter().map(|x| x[..nq].to_vec()).collect();
    Ok(Some((spec, model, qs)))
}

/// The scene of a solution: its robot, or the sketch of a problem without one; and the
/// meshes it could not load.
fn scene_of(doc: &SolutionFile) -> Result<(Scene, Vec<String>), String> {
    let mut scene = Scene::new(format!("{} ({})", doc.problem, doc.solver), doc.dt.unwrap_or(0.05));
    let Some((spec, model, qs)) = robot_of(doc)? else {
        if crate::sketch::sketch(&doc.problem, &doc.xs, &mut scene) {
            return Ok((scene, Vec::new()));
        }
        return Err(format!(
            "`{}` has nothing to show: the viewer shows the robot problems (ur5, double-pendulum, quadrotor, \
             solo and their variants) and sketches pendulum, cartpole, acrobot and se2-car",
            doc.problem
        ));
    };
    let report = scene
        .add_robot(&model, &qs, &MeshSearch::from_env())
        .map_err(|e| e.to_string())?;
    for p in &spec.targets {
        scene.add_target(*p, 0.04);
    }
    if let Some(contacts) = contact_forces(&doc.problem, &doc.xs, &doc.us) {
        add_force_arrows(&mut scene, &model, &qs, &contacts.map_err(|e| e.to_string())?)?;
    }
    for c in spec.cylinders {
        let shape = Shape::Cylinder {
            radius: c.radius,
            length: c.z.1 - c.z.0,
        };
        scene.add_obstacle(shape, Pose::at([c.centre[0], c.centre[1], 0.5 * (c.z.0 + c.z.1)]));
    }
    Ok((scene, report.missing))
}

/// Arrows of the contact forces from the feet, the largest 0.3 m long (none at the last
/// node, which has no control).
fn add_force_arrows(scene: &mut Scene, model: &Model, qs: &[Vec<f64>], contacts: &ContactForces) -> Result<(), String> {
    let feet = frame_paths(model, qs, &contacts.feet).map_err(|e| e.to_string())?;
    let largest = contacts
        .forces
        .iter()
        .flatten()
        .map(|f| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
        .fold(0.0, f64::max);
    let scale = if largest > 0.0 { 0.3 / largest } else { 0.0 };
    scene.arrows = (0..qs.len())
        .map(|t| match contacts.forces.get(t) {
            Some(stage) => stage
                .iter()
                .zip(&feet)
                .filter(|(f, _)| f[2] > 1e-9)
                .map(|(f, foot)| Arrow {
                    from: foot.points[t],
                    vector: f.map(|v| v * scale),
                })
                .collect(),
            None => Vec::new(),
        })
        .collect();
    Ok(())
}

/// Runs `gharial view`; returns the exit code (0 written, 2 bad input or an unwritable
/// page, 1 a server that failed).
pub fn run(args: &ViewArgs) -> i32 {
    let fail = |e: String| {
        eprintln!("gharial view: {e}");
        2
    };
    let doc = match SolutionFile::read(Path::new(&args.solution)) {
        Ok(d) => d,
        Err(e) => return fail(e.to_string()),
    };
    let (scene, missing) = match scene_of(&doc) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    let html = match page(&scene) {
        Ok(h) => h,
        Err(e) => return fail(e.to_string()),
    };
    let out = args.out.clone().unwrap_or_else(|| format!("{}-view.html", doc.problem));
    if let Err(e) = std::fs::write(&out, &html) {
        return fail(format!("cannot write {out}: {e}"));
    }
    if !missing.is_empty() {
        out!(
            "meshes    {} not loaded, capsules between the joints instead (set GHARIAL_MESH_PATH); first: {}",
            missing.len(),
            missing[0]
        );
    }
    out!("viewer    written to {out}");
    if args.serve { serve(&html, args.port) } else { 0 }
}

/// Serves `html` at every path of `http://127.0.0.1:port/` until the process ends.
fn serve(html: &str, port: u16) -> i32 {
    let listener = match TcpListener::bind(("127.0.0.1", port)) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("gharial view: cannot listen on port {port}: {e}");
            return 1;
        }
    };
    let port = listener.local_addr().map(|a| a.port()).unwrap_or(port);
    out!("serving   http://127.0.0.1:{port}/ (interrupt to stop)");
    for stream in listener.incoming() {
        let Ok(mut stream) = stream else { continue };
        // Read the request head, then answer with the page.
        let mut reader = BufReader::new(&stream);
        let mut line = String::new();
        while reader.read_line(&mut line).is_ok_and(|n| n > 2) {
            line.clear();
        }
        let head = format!(
            "HTTP/1.1 200 OK\r\nContent-Type: text/html; charset=utf-8\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            html.len()
        );
        let _ = stream
            .write_all(head.as_bytes())
            .and_then(|()| stream.write_all(html.as_bytes()));
    }
    0
}
