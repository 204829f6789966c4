//! Every plot kind rendered from real solves of catalogue problems, as PNG and SVG: the
//! files decode, have the requested size, show the series' colours, and their axes hold
//! the data without wasting the frame; bad inputs are errors.

use std::path::{Path, PathBuf};

use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant, control_bounds};
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver};
use gharial_problems::Example;
use gharial_viz::{
    Cylinder, Error, Figure, FootForces, ProfileCurve, Run, Trajectory, convergence, forces, frame_paths, paths,
    profile, ratios, ratios_from_harness, trajectory,
};

/// A fresh directory for this test's files.
fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gharial-viz-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn solve(ex: &Example, mut solver: Box<dyn Solver>) -> Solution {
    solver.setup(&ex.problem).unwrap();
    solver
        .solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0))
        .unwrap()
        .clone()
}

fn proxddp(ex: &Example) -> Solution {
    solve(ex, Box::new(ProxDdp::new(ex.proxddp.clone())))
}

fn ddp(ex: &Example, v: DdpVariant) -> Solution {
    solve(ex, Box::new(Ddp::new(DdpOptions::new(v))))
}

/// The pixels of a PNG file, after checking its size.
fn png_pixels(path: &Path, size: (u32, u32)) -> image::RgbImage {
    let img = image::open(path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), size, "{}", path.display());
    img
}

/// Pixels of exactly the colour of series `i` (lines are drawn in it).
fn pixels_of(img: &image::RgbImage, rgb: [u8; 3]) -> usize {
    img.pixels().filter(|p| p.0 == rgb).count()
}

fn series_rgb(i: usize) -> [u8; 3] {
    [[31, 119, 180], [214, 39, 40], [44, 160, 44]][i]
}

/// The SVG document: its size, the stroke colours of its lines, its texts.
fn svg_summary(path: &Path) -> ((f64, f64), Vec<String>, Vec<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    let dim = |a: &str| {
        root.attribute(a)
            .unwrap()
            .trim_end_matches("px")
            .parse::<f64>()
            .unwrap()
    };
    let strokes = doc
        .descendants()
        .filter(|n| matches!(n.tag_name().name(), "polyline" | "path" | "line"))
        .filter_map(|n| n.attribute("stroke").map(str::to_string))
        .collect();
    let texts = doc
        .descendants()
        .filter(|n| n.tag_name().name() == "text")
        .filter_map(|n| n.text().map(|t| t.trim().to_string()))
        .collect();
    ((dim("width"), dim("height")), strokes, texts)
}

/// The axis range holds `[lo, hi]` and is no wider than `slack` times its span.
fn assert_tight(range: (f64, f64), lo: f64, hi: f64, slack: f64) {
    assert!(range.0 <= lo && hi <= range.1, "{range:?} does not hold [{lo}, {hi}]");
    let span = (hi - lo).max(1e-12);
    assert!(
        range.1 - range.0 <= slack * span + 1.0 + 1e-12,
        "{range:?} wastes the frame for [{lo}, {hi}]"
    );
}

fn minmax<'a>(v: impl IntoIterator<Item = &'a f64>) -> (f64, f64) {
    v.into_iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)))
}

#[test]
fn convergence_of_several_solvers_on_one_plot() {
    let dir = out_dir("convergence");
    let ex = gharial_problems::build("ur5").unwrap();
    let runs = [
        Run::from_solution("ProxDDP", &proxddp(&ex)),
        Run::from_solution("FDDP", &ddp(&ex, DdpVariant::Fddp)),
    ];
    for ext in ["png", "svg"] {
        let path = dir.join(format!("ur5.{ext}"));
        let fig = convergence(&runs, "UR5 reach", &path).unwrap();
        let p = &fig.panels[0];
        assert!(p.log_y);
        let rows = runs.iter().map(|r| r.prim_err.len()).max().unwrap();
        assert_eq!(p.x, (0.0, (rows - 1) as f64));
        let positive: Vec<f64> = runs
            .iter()
            .flat_map(|r| r.prim_err.iter().chain(&r.dual_err))
            .copied()
            .filter(|v| *v > 0.0)
            .collect();
        let (lo, hi) = minmax(&positive);
        // Whole decades around the data, not one more.
        assert!(
            p.y.0 <= lo && lo < 10.0 * p.y.0 && hi <= p.y.1 && p.y.1 < 10.0 * hi,
            "{:?} for [{lo}, {hi}]",
            p.y
        );
        if ext == "png" {
            let img = png_pixels(&path, (900, 560));
            for i in 0..2 {
                assert!(pixels_of(&img, series_rgb(i)) > 200, "series {i} not drawn");
            }
        } else {
            let (size, strokes, texts) = svg_summary(&path);
            assert_eq!(size, (900.0, 560.0));
            assert!(
                strokes.iter().any(|s| s == "#1F77B4") && strokes.iter().any(|s| s == "#D62728"),
                "{strokes:?}"
            );
            for t in ["iteration", "ProxDDP primal", "FDDP dual", "UR5 reach"] {
                assert!(texts.iter().any(|x| x.contains(t)), "no text `{t}` in {texts:?}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
/// The AL iterations of a constrained ProxDDP solve are marked with their penalty.

#[test]
fn outer_iterations_are_marked_with_their_penalty() {
    let dir = out_dir("outer");
    let ex = gharial_problems::build("quadrotor-slalom").unwrap();
    let sol = proxddp(&ex);
    let run = Run::from_solution("ProxDDP", &sol);
    assert!(sol.al_iterations >= 3, "the solve needs outer iterations");
    let path = dir.join("outer.svg");
    convergence(&[run], "quadrotor slalom", &path).unwrap();
    let (_, _, texts) = svg_summary(&path);
    let marks: Vec<&String> = texts.iter().filter(|t| t.starts_with("μ=")).collect();
    assert_eq!(marks.len(), sol.al_iterations, "{texts:?}");
    // The last mark shows the final penalty.
    assert_eq!(marks.last().unwrap().as_str(), format!("μ={:.0e}", sol.mu));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn trajectories_with_their_control_bounds() {
    let dir = out_dir("trajectory");
    for (name, variant) in [
        ("lqr-bounds", Some(DdpVariant::BoxFddp)),
        ("pendulum", None),
        ("ur5", Some(DdpVariant::Fddp)),
    ] {
        let ex = gharial_problems::build(name).unwrap();
        let sol = match variant {
            Some(v) => ddp(&ex, v),
            None => proxddp(&ex),
        };
        let (u_lower, u_upper) = control_bounds(&ex.problem, &sol.xs, &sol.us).unwrap_or_default();
        let traj = Trajectory {
            title: name.to_string(),
            dt: ex.dt,
            xs: sol.xs.clone(),
            us: sol.us.clone(),
            u_lower,
            u_upper,
        };
        for ext in ["png", "svg"] {
            let path = dir.join(format!("{name}.{ext}"));
            let fig: Figure = trajectory(&traj, &path).unwrap();
            assert_eq!(fig.panels.len(), 2);
            let t_end = ex.dt.unwrap_or(1.0) * ex.problem.horizon() as f64;
            for p in &fig.panels {
                assert!((p.x.1 - t_end).abs() < 1e-12 && p.x.0 == 0.0, "{:?}", p.x);
            }
            let (lo, hi) = minmax(sol.xs.iter().flatten());
            assert_tight(fig.panels[0].y, lo, hi, 1.2);
            let bounds = traj.u_lower.iter().chain(&traj.u_upper).flatten();
            let (lo, hi) = minmax(sol.us.iter().flatten().chain(bounds));
            assert_tight(fig.panels[1].y, lo, hi, 1.2);
            if ext == "png" {
                let img = png_pixels(&path, (900, 720));
                assert!(pixels_of(&img, series_rgb(0)) > 100, "{name}: no line drawn");
            }
        }
        if name == "lqr-bounds" {
            // The bounds are active: the controls touch the dashed lines at ±0.15.
            assert_eq!(traj.u_upper[0], vec![0.15; 3]);
            let umax = sol.us.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs()));
            assert!((umax - 0.15).abs() < 1e-6, "{umax}");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
/// The profile of real iteration counts: two solvers on a randomised family.

#[test]
fn profile_of_iteration_counts() {
    let dir = out_dir("profile");
    let family = gharial_problems::profiles::family("reach", 3, 4).unwrap();
    let budgets: Vec<f64> = (0..=60).map(f64::from).collect();
    let curve = |label: &str, iters: &[usize], converged: &[bool]| ProfileCurve {
        label: label.to_string(),
        budget: budgets.clone(),
        solved: budgets
            .iter()
            .map(|&b| {
                let n = iters
                    .iter()
                    .zip(converged)
                    .filter(|&(&k, &c)| c && k as f64 <= b)
                    .count();
                n as f64 / iters.len() as f64
            })
            .collect(),
    };
    let mut curves = Vec::new();
    for label in ["ProxDDP", "FDDP"] {
        let sols: Vec<Solution> = family
            .iter()
            .map(|ex| {
                if label == "FDDP" {
                    ddp(ex, DdpVariant::Fddp)
                } else {
                    proxddp(ex)
                }
            })
            .collect();
        let iters: Vec<usize> = sols.iter().map(|s| s.iterations).collect();
        let conv: Vec<bool> = sols.iter().map(|s| s.status.converged()).collect();
        curves.push(curve(label, &iters, &conv));
    }
    assert!(
        curves.iter().any(|c| *c.solved.last().unwrap() > 0.0),
        "nothing solved: {curves:?}"
    );
    for ext in ["png", "svg"] {
        let path = dir.join(format!("profile.{ext}"));
        let fig = profile(&curves, "reach family", &path).unwrap();
        assert_eq!(fig.panels[0].y, (0.0, 105.0));
        assert!(fig.panels[0].x.0 <= 0.0 && fig.panels[0].x.1 >= 60.0);
        if ext == "png" {
            let img = png_pixels(&path, (900, 560));
            for i in 0..2 {
                assert!(pixels_of(&img, series_rgb(i)) > 100, "curve {i} not drawn: {curves:?}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_inputs_are_errors() {
    let dir = out_dir("bad");
    let run = Run {
        label: "a".into(),
        prim_err: vec![1.0, 0.1],
        dual_err: vec![1.0],
        ..Run::default()
    };
    let e = convergence(&[run], "t", &dir.join("c.png")).unwrap_err();
    assert!(
        matches!(e, Error::Invalid(_)) && e.to_string().contains("1 dual"),
        "{e}"
    );
    assert!(matches!(
        convergence(&[], "t", &dir.join("c.png")),
        Err(Error::Invalid(_))
    ));
    let ok = Run {
        label: "a".into(),
        prim_err: vec![1.0, f64::NAN, 0.0],
        dual_err: vec![1.0, 1e-3, 1e-9],
        ..Run::default()
    };
    let e = convergence(std::slice::from_ref(&ok), "t", &dir.join("c.pdf")).unwrap_err();
    assert!(matches!(e, Error::Format(_)), "{e}");
    let e = convergence(std::slice::from_ref(&ok), "t", &dir.join("missing/c.png")).unwrap_err();
    assert!(matches!(e, Error::Backend { .. }), "{e}");
    // NaN and zero residuals are drawn around (the axis from the positive values).
    let fig = convergence(&[ok], "t", &dir.join("c.svg")).unwrap();
    assert_eq!(fig.panels[0].y, (1e-9, 1.0));

    let mut traj = Trajectory {
        title: "t".into(),
        dt: Some(0.1),
        xs: vec![vec![0.0, 1.0]; 3],
        us: vec![vec![0.5]; 2],
        ..Trajectory::default()
    };
    trajectory(&traj, &dir.join("t.png")).unwrap();
    traj.xs[1][0] = f64::INFINITY;
    let e = trajectory(&traj, &dir.join("t.png")).unwrap_err();
    assert!(e.to_string().contains("xs[1][0]"), "{e}");
    traj.xs[1][0] = 0.0;
    traj.us.pop();
    assert!(
        trajectory(&traj, &dir.join("t.png"))
            .unwrap_err()
            .to_string()
            .contains("controls")
    );
    traj.us.push(vec![0.5]);
    traj.u_lower = vec![vec![-1.0, 0.0]; 2];
    assert!(
        trajectory(&traj, &dir.join("t.png"))
            .unwrap_err()
            .to_string()
            .contains("u_lower")
    );
    traj.u_lower.clear();
    traj.dt = Some(0.0);
    assert!(
        trajectory(&traj, &dir.join("t.png"))
            .unwrap_err()
            .to_string()
            .contains("time step")
    );

    let bad = ProfileCurve {
        label: "s".into(),
        budget: vec![1.0, 1.0],
        solved: vec![0.0, 0.5],
    };
    assert!(
        profile(&[bad], "p", &dir.join("p.png"))
            .unwrap_err()
            .to_string()
            .contains("increasing")
    );
    let bad = ProfileCurve {
        label: "s".into(),
        budget: vec![1.0],
        solved: vec![1.5],
    };
    assert!(
        profile(&[bad], "p", &dir.join("p.png"))
            .unwrap_err()
            .to_string()
            .contains("[0, 1]")
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The quadrotor's path in three projections: it starts at x0, ends at the target, the
/// axes have equal scales and hold the path and the cylinders.
#[test]
fn paths_of_the_quadrotor_slalom_with_its_obstacles() {
    let dir = out_dir("paths");
    let ex = gharial_problems::build("quadrotor-slalom").unwrap();
    let sol = proxddp(&ex);
    let scene = gharial_problems::scenes::robot_scene("quadrotor-slalom").unwrap();
    let model = gharial_multibody::Model::from_urdf_str(scene.urdf, scene.root).unwrap();
    let qs: Vec<Vec<f64>> = sol.xs.iter().map(|x| x[..model.nq()].to_vec()).collect();
    let tracks = frame_paths(&model, &qs, &scene.frames).unwrap();
    let end = *tracks[0].points.last().unwrap();
    let target = scene.targets[0];
    assert!((0..3).all(|i| (end[i] - target[i]).abs() < 1e-3), "{end:?}");
    assert!((0..3).all(|i| (tracks[0].points[0][i] - sol.xs[0][i]).abs() < 1e-12));
    let cylinders: Vec<Cylinder> = scene
        .cylinders
        .iter()
        .map(|c| Cylinder {
            centre: c.centre,
            radius: c.radius,
            z: c.z,
        })
        .collect();
    let fig = paths(&tracks, &scene.targets, &cylinders, "slalom", &dir.join("p.png")).unwrap();
    assert_eq!(fig.panels.len(), 3);
    for (p, (i, j)) in fig.panels.iter().zip([(0, 1), (0, 2), (1, 2)]) {
        assert!((p.x.1 - p.x.0 - (p.y.1 - p.y.0)).abs() < 1e-12, "unequal scales {p:?}");
        let (lo_i, hi_i) = minmax(tracks[0].points.iter().map(|q| &q[i]));
        let (lo_j, hi_j) = minmax(tracks[0].points.iter().map(|q| &q[j]));
        assert!(
            p.x.0 <= lo_i && hi_i <= p.x.1 && p.y.0 <= lo_j && hi_j <= p.y.1,
            "{p:?}"
        );
        if j == 2 {
            assert!(p.y.0 <= 0.0 && p.y.1 >= 2.0, "the cylinders' heights: {p:?}");
        }
    }
    let img = png_pixels(&dir.join("p.png"), (1200, 440));
    assert!(pixels_of(&img, series_rgb(0)) > 200);
    let e = frame_paths(&model, &qs, &["no_such_frame"]).unwrap_err();
    assert!(e.to_string().contains("no_such_frame"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The standing Solo's contact forces: each foot carries a quarter of the weight, and the
/// cone ratios are drawn on an axis that holds them and the cone's edge.
#[test]
fn contact_forces_and_cone_ratios() {
    let dir = out_dir("forces");
    let ex = gharial_problems::build("solo-com-circle").unwrap();
    let c = gharial_problems::scenes::contact_forces("solo-com-circle", &ex.xs0, &ex.us0)
        .unwrap()
        .unwrap();
    let feet: Vec<FootForces> = c
        .feet
        .iter()
        .enumerate()
        .map(|(k, n)| FootForces {
            label: n.to_string(),
            forces: c.forces.iter().map(|s| s[k]).collect(),
        })
        .collect();
    let fig = forces(&feet, ex.dt, c.mu, "standing", &dir.join("f.png")).unwrap();
    assert_eq!(fig.panels.len(), 2);
    let fz: Vec<f64> = feet.iter().flat_map(|f| f.forces.iter().map(|v| v[2])).collect();
    let (lo, hi) = minmax(&fz);
    assert_tight(fig.panels[0].y, lo, hi, 1.2);
    assert!(fig.panels[1].y.0 <= 0.0 && fig.panels[1].y.1 >= 1.0);
    assert_eq!(png_pixels(&dir.join("f.png"), (900, 820)).dimensions(), (900, 820));
    // Without a friction coefficient, one panel.
    let fig = forces(&feet, ex.dt, None, "standing", &dir.join("g.svg")).unwrap();
    assert_eq!(fig.panels.len(), 1);
    let mut bad = feet.clone();
    bad[1].forces.pop();
    assert!(forces(&bad, None, None, "x", &dir.join("h.png")).is_err());
    assert!(forces(&feet, None, Some(0.0), "x", &dir.join("h.png")).is_err());
    std::fs::remove_dir_all(&dir).ok();
}

/// The ratios of a real harness run (`tests/data/peers-run.jsonl`: the fields the ratios
/// use of the merged records of one run of the peer harness with gharial, 2026-12-03):
/// each bar is gharial's median time over the same-named peer solver's, only where both
/// converged.
#[test]
fn time_ratios_of_a_harness_run() {
    let dir = out_dir("ratios");
    let text = include_str!("data/peers-run.jsonl");
    let bars = ratios_from_harness(text).unwrap();
    let rows: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let time = |problem: &str, lib: &str, solver: &str| {
        let r = rows
            .iter()
            .find(|r| r["problem"] == problem && r["lib"] == lib && r["solver"] == solver)
            .unwrap();
        (r["time_ms"].as_f64().unwrap(), r["converged"].as_bool().unwrap())
    };
    let fddp = bars
        .iter()
        .find(|b| b.problem == "ur5" && b.pair == "FDDP / crocoddyl")
        .unwrap();
    assert_eq!(
        fddp.ratio,
        time("ur5", "gharial", "FDDP").0 / time("ur5", "crocoddyl", "FDDP").0
    );
    // mim_solvers' CSQP did not converge on pendulum_box_term: no bar.
    assert!(!time("pendulum_box_term", "mim_solvers", "CSQP").1);
    assert!(
        !bars
            .iter()
            .any(|b| b.problem == "pendulum_box_term" && b.pair == "CSQP / mim_solvers")
    );
    let fig = ratios(&bars, "one harness run", &dir.join("r.png")).unwrap();
    let lo = bars.iter().map(|b| b.ratio).fold(f64::INFINITY, f64::min);
    let hi = bars.iter().map(|b| b.ratio).fold(0.0, f64::max);
    let y = fig.panels[0].y;
    assert!(y.0 <= lo && hi <= y.1 && y.1 >= 2.0, "{y:?}");
    assert!(pixels_of(&png_pixels(&dir.join("r.png"), (1000, 520)), series_rgb(0)) > 100);
    assert!(ratios_from_harness("{\"a\": 1}").is_err());
    assert!(ratios_from_harness(&rows[0].to_string()).is_err(), "no gharial record");
    std::fs::remove_dir_all(&dir).ok();
}
