//! `gharial solve --plot` and `gharial plot`: the plots of a solve, from the solve itself
//! and from its JSON file, are the same images; the control bounds travel in the file;
//! bad input exits with code 2.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn gharial(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gharial"))
        .args(args)
        .output()
        .expect("the gharial binary runs")
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gharial-cli-plot-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn png(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

#[test]
fn solve_plot_and_plot_of_the_file_draw_the_same_images() {
    let d = dir("same");
    let (a, b) = (d.join("a"), d.join("b"));
    std::fs::create_dir_all(&a).unwrap();
    let json = d.join("sol.json");
    let o = gharial(&[
        "solve",
        "lqr-bounds",
        "--solver",
        "box-fddp",
        "--plot",
        a.to_str().unwrap(),
        "--output",
        json.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // The bounds |u| <= 0.15 of every stage are in the file.
    let upper = doc["u_upper"].as_array().unwrap();
    assert_eq!(upper.len(), 20);
    assert!(
        upper
            .iter()
            .flat_map(|r| r.as_array().unwrap())
            .all(|v| v.as_f64() == Some(0.15))
    );
    let o = gharial(&["plot", json.to_str().unwrap(), "--out", b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    for kind in ["convergence", "trajectory"] {
        let file = format!("lqr-bounds-{kind}.png");
        let (ia, ib) = (png(&a.join(&file)), png(&b.join(&file)));
        assert_eq!(ia.dimensions(), ib.dimensions());
        assert!(ia == ib, "{file} differs between solve --plot and plot");
        let white = ia.pixels().filter(|p| p.0 == [255, 255, 255]).count();
        assert!(white < ia.pixels().count(), "{file} is blank");
    }
    let o = gharial(&[
        "plot",
        json.to_str().unwrap(),
        "--out",
        b.to_str().unwrap(),
        "--format",
        "svg",
    ]);
    assert_eq!(o.status.code(), Some(0));
    let svg = std::fs::read_to_string(b.join("lqr-bounds-trajectory.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("bounds"),
        "{}",
        &svg[..200.min(svg.len())]
    );
    // Unbounded problems: no bounds in the file, plots all the same.
    let json2 = d.join("ur5.json");
    let o = gharial(&["solve", "ur5", "--solver", "fddp", "--output", json2.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json2).unwrap()).unwrap();
    assert!(
        doc["u_upper"].as_array().unwrap()[0]
            .as_array()
            .unwrap()
            .iter()
            .all(|v| v.is_null())
    );
    let o = gharial(&["plot", json2.to_str().unwrap(), "--out", b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(png(&b.join("ur5-trajectory.png")).dimensions(), (900, 720));
    // A robot problem also gets the path of its end effector.
    assert_eq!(png(&b.join("ur5-path.png")).dimensions(), (1200, 440));
    assert!(!b.join("lqr-bounds-path.png").exists());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn bad_plot_input_exits_with_code_2() {
    let d = dir("bad");
    let not_solution = d.join("x.json");
    std::fs::write(&not_solution, "{\"a\": 1}").unwrap();
    let file = d.join("file");
    std::fs::write(&file, "").unwrap();
    let cases: [(&[&str], &str); 5] = [
        (
            &["bench", "profile", "reach", "--count", "1", "--plot", "p.pdf"],
            "png or .svg",
        ),
        (&["plot", "/no/such/file.json"], "no/such"),
        (&["plot", not_solution.to_str().unwrap()], "missing field"),
        (&["plot", not_solution.to_str().unwrap(), "--format", "pdf"], "pdf"),
        (
            &["solve", "lqr", "--plot", file.to_str().unwrap()],
            "cannot create the directory",
        ),
    ];
    for (args, needle) in cases {
        let o = gharial(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(String::from_utf8_lossy(&o.stdout).is_empty(), "{args:?} printed output");
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn bench_profile_draws_its_curves() {
    let d = dir("profile");
    let (png_path, csv) = (d.join("p.png"), d.join("p.csv"));
    let o = gharial(&[
        "bench",
        "profile",
        "reach",
        "--count",
        "2",
        "--solvers",
        "fddp,proxddp",
        "--max-budget",
        "30",
        "--plot",
        png_path.to_str().unwrap(),
        "--output",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let img = png(&png_path);
    assert_eq!(img.dimensions(), (900, 560));
    // Both curves are drawn (the first two series colours).
    for rgb in [[31u8, 119, 180], [214, 39, 40]] {
        assert!(img.pixels().filter(|p| p.0 == rgb).count() > 50, "{rgb:?} missing");
    }
    std::fs::remove_dir_all(&d).ok();
}
