//! `gharial plot` and `gharial solve --plot`: the convergence and trajectory plots of a
//! solution document (the JSON that `gharial solve --output` writes).

use std::path::{Path, PathBuf};

use clap::ValueEnum;
use gharial_problems::scenes::contact_forces;
use gharial_viz::{
    Cylinder, FootForces, SolutionFile, convergence, forces, frame_paths, paths, ratios, ratios_from_harness,
    trajectory,
};

/// Image format of the plots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// PNG raster images.
    Png,
    /// SVG vector images.
    Svg,
}

impl Format {
    fn ext(self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Svg => "svg",
        }
    }
}

/// The arguments of `gharial plot`.
#[derive(clap::Args, Debug, Clone)]
pub struct PlotArgs {
    /// A solution file written by `gharial solve --output`, or the merged JSON lines of a
    /// peer-harness run (`.jsonl`: the time ratios against the peers).
    pub solution: String,
    /// Directory of the plots (created if missing).
    #[arg(long, default_value = ".")]
    pub out: String,
    /// Image format.
    #[arg(long, value_enum, default_value = "png")]
    pub format: Format,
}

/// Draws `<problem>-convergence`, `<problem>-trajectory`, for robot problems
/// `<problem>-path` (the paths of the end effector or the base and feet) and for legged
/// ones `<problem>-forces` (contact forces and friction-cone ratios) of `doc` into `dir`;
/// the files written, or the first error.
pub fn draw(doc: &SolutionFile, dir: &Path, format: Format) -> Result<Vec<PathBuf>, String> {
    let file = |what: &str| dir.join(format!("{}-{what}.{}", doc.problem, format.ext()));
    let (c, t) = (file("convergence"), file("trajectory"));
    let title = format!("{} ({})", doc.problem, doc.solver);
    if doc.history.is_empty() {
        return Err(format!("{}: the solution has no iteration history", doc.problem));
    }
    convergence(&[doc.run()], &title, &c).map_err(|e| e.to_string())?;
    trajectory(&doc.trajectory(), &t).map_err(|e| e.to_string())?;
    let mut files = vec![c, t];
    if let Some((spec, model, qs)) = crate::view::robot_of(doc)? {
        let p = file("path");
        let tracks = frame_paths(&model, &qs, &spec.frames).map_err(|e| e.to_string())?;
        let cylinders: Vec<Cylinder> = spec
            .cylinders
            .iter()
            .map(|c| Cylinder {
                centre: c.centre,
                radius: c.radius,
                z: c.z,
            })
            .collect();
        paths(&tracks, &spec.targets, &cylinders, &title, &p).map_err(|e| e.to_string())?;
        files.push(p);
    }
    if let Some(contacts) = contact_forces(&doc.problem, &doc.xs, &doc.us) {
        let contacts = contacts.map_err(|e| e.to_string())?;
        let f = file("forces");
        let feet: Vec<FootForces> = contacts
            .feet
            .iter()
            .enumerate()
            .map(|(k, name)| FootForces {
                label: (*name).to_string(),
                forces: contacts.forces.iter().map(|stage| stage[k]).collect(),
            })
            .collect();
        forces(&feet, doc.dt, contacts.mu, &title, &f).map_err(|e| e.to_string())?;
        files.push(f);
    }
    Ok(files)
}

/// Draws the plots of a solve's JSON document (`gharial solve --plot`); `false` (with a
/// message) if that fails.
pub fn draw_document(doc: &serde_json::Value, dir: &str, format: Format) -> bool {
    let result = serde_json::from_value::<SolutionFile>(doc.clone())
        .map_err(|e| e.to_string())
        .and_then(|d| draw(&d, Path::new(dir), format));
    report("solve", result)
}

fn report(command: &str, result: Result<Vec<PathBuf>, String>) -> bool {
    match result {
        Ok(files) => {
            for f in files {
                out!("plot      written to {}", f.display());
            }
            true
        }
        Err(e) => {
            eprintln!("gharial {command}: {e}");
            false
        }
    }
}

/// Runs `gharial plot`; returns the exit code (0 written, 1 a plot failed, 2 a file that
/// cannot be read or a directory that cannot be made).
pub fn run(args: &PlotArgs) -> i32 {
    if args.solution.ends_with(".jsonl") {
        return run_harness(args);
    }
    let doc = match SolutionFile::read(Path::new(&args.solution)) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("gharial plot: {e}");
            return 2;
        }
    };
    if let Err(e) = std::fs::create_dir_all(&args.out) {
        eprintln!("gharial plot: cannot make {}: {e}", args.out);
        return 2;
    }
    if report("plot", draw(&doc, Path::new(&args.out), args.format)) {
        0
    } else {
        1
    }
}

/// `gharial plot results.jsonl`: the time ratios against the peers of one harness run
/// (its merged JSON lines), as `peers-ratios.<format>`.
fn run_harness(args: &PlotArgs) -> i32 {
    let bars = std::fs::read_to_string(&args.solution)
        .map_err(|e| format!("reading `{}`: {e}", args.solution))
        .and_then(|text| ratios_from_harness(&text).map_err(|e| e.to_string()));
    let bars = match bars {
        Ok(b) => b,
        Err(e) => {
            eprintln!("gharial plot: {e}");
            return 2;
        }
    };
    if let Err(e) = std::fs::create_dir_all(&args.out) {
        eprintln!("gharial plot: cannot make {}: {e}", args.out);
        return 2;
    }
    let file = Path::new(&args.out).join(format!("peers-ratios.{}", args.format.ext()));
    let result = ratios(&bars, "solve time against the peers (one harness run)", &file)
        .map(|_| vec![file])
        .map_err(|e| e.to_string());
    if report("plot", result) { 0 } else { 1 }
}
