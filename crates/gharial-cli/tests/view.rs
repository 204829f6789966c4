//! `gharial view` end to end, in headless Chromium: the page of the UR5 reach plays to its
//! end without a console error, the robot's pixels move between two times, and
//! `--serve` answers with the page. Chromium is Debian's `chromium` (`.ci/run` installs
//! it; `GHARIAL_CHROMIUM` names another binary). Without it the browser test fails,
//! unless `GHARIAL_SKIP_BROWSER=1` says to skip it.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn gharial(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gharial"))
        .args(args)
        .output()
        .expect("the gharial binary runs")
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gharial-cli-view-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The UR5 reach's viewer page, written into `d`.
fn ur5_page(d: &Path) -> PathBuf {
    let (json, html) = (d.join("ur5.json"), d.join("ur5.html"));
    let o = gharial(&["solve", "ur5", "--output", json.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    let o = gharial(&["view", json.to_str().unwrap(), "--out", html.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("viewer    written to"));
    html
}

/// The Chromium binary, or `None` when the test is to be skipped.
fn chromium() -> Option<String> {
    if std::env::var_os("GHARIAL_SKIP_BROWSER").is_some_and(|v| v == "1") {
        eprintln!("GHARIAL_SKIP_BROWSER=1: the browser test is skipped");
        return None;
    }
    let candidates = std::env::var("GHARIAL_CHROMIUM")
        .map(|c| vec![c])
        .unwrap_or_else(|_| vec!["chromium".into(), "chromium-browser".into()]);
    let found = candidates.into_iter().find(|c| {
        Command::new(c)
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    });
    assert!(
        found.is_some(),
        "headless Chromium is needed (apt-get install chromium, or GHARIAL_CHROMIUM=...); GHARIAL_SKIP_BROWSER=1 skips"
    );
    found
}

/// Runs headless Chromium on `url` with `extra` arguments; its standard output.
fn headless(bin: &str, profile: &Path, url: &str, extra: &[&str]) -> String {
    let out = Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--window-size=800,600",
            "--virtual-time-budget=4000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .arg(url)
        .output()
        .expect("chromium runs");
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The attributes of the page's body after it ran (`data-frame`, `data-errors`, ...).
fn body_attr(dom: &str, name: &str) -> String {
    let body = &dom[dom.find("<body").expect("a body element")..];
    let body = &body[..body.find('>').unwrap()];
    let key = format!("{name}=\"");
    let at = body.find(&key).unwrap_or_else(|| panic!("no {name} in {body}")) + key.len();
    body[at..at + body[at..].find('"').unwrap()].to_string()
}

/// Pixels of the robot's skeleton colour (orange, under any shading).
fn robot_pixels(img: &image::RgbImage) -> Vec<(u32, u32)> {
    img.enumerate_pixels()
        .filter(|(_, _, p)| {
            let [r, g, b] = p.0.map(i32::from);
            r > 90 && r > g + 40 && g > b + 20 && b < 80
        })
        .map(|(x, y, _)| (x, y))
        .collect()
}

#[test]
fn the_ur5_reach_plays_in_headless_chromium() {
    let Some(bin) = chromium() else { return };
    let d = dir("browser");
    let html = ur5_page(&d);
    let url = |hash: &str| format!("file://{}#{hash}", html.display());
    let profile = d.join("profile");

    // Played from the start, the animation advances (how far within the browser's
    // virtual-time budget depends on its frame scheduling: on a loaded machine a run
    // may end before the first animation frame, so up to three runs) without a console
    // error.
    let mut frame = 0;
    for _ in 0..3 {
        let dom = headless(&bin, &profile, &url("play"), &["--dump-dom"]);
        assert_eq!(body_attr(&dom, "data-errors"), "0", "console errors: {dom}");
        frame = body_attr(&dom, "data-frame").parse().unwrap();
        if frame > 0 {
            break;
        }
    }
    assert!((1..=100).contains(&frame), "did not play in three runs: frame {frame}");
    // Scrubbed to a time, it shows that node.
    let dom = headless(&bin, &profile, &url("t=0.5"), &["--dump-dom"]);
    assert_eq!(body_attr(&dom, "data-frame"), "50");
    assert_eq!(body_attr(&dom, "data-errors"), "0");

    // Screenshots at the start and the end: the robot is drawn and has moved.
    let mut shots = Vec::new();
    for (k, t) in ["0", "1"].iter().enumerate() {
        let png = d.join(format!("shot{k}.png"));
        headless(
            &bin,
            &profile,
            &url(&format!("t={t}")),
            &[&format!("--screenshot={}", png.display())],
        );
        let img = image::open(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (800, 600));
        shots.push(robot_pixels(&img));
    }
    let (a, b) = (&shots[0], &shots[1]);
    assert!(
        a.len() > 1000 && b.len() > 1000,
        "robot not drawn: {} and {} pixels",
        a.len(),
        b.len()
    );
    let sa: std::collections::HashSet<_> = a.iter().collect();
    let moved = b.iter().filter(|p| !sa.contains(p)).count();
    assert!(moved > 500, "the robot did not move: {moved} new pixels");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn serve_answers_with_the_page() {
    let d = dir("serve");
    let json = d.join("ur5.json");
    assert_eq!(
        gharial(&["solve", "ur5", "--output", json.to_str().unwrap()])
            .status
            .code(),
        Some(0)
    );
    let out = d.join("page.html");
    let mut child = Command::new(env!("CARGO_BIN_EXE_gharial"))
        .args([
            "view",
            json.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--serve",
            "--port",
            "0",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let port: u16 = loop {
        let line = lines.next().expect("a serving line").unwrap();
        if let Some(rest) = line.strip_prefix("serving   http://127.0.0.1:") {
            break rest[..rest.find('/').unwrap()].parse().unwrap();
        }
    };
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    stream.write_all(b"GET / HTTP/1.1\r\nHost: localhost\r\n\r\n").unwrap();
    let mut response = String::new();
    stream.read_to_string(&mut response).unwrap();
    child.kill().ok();
    child.wait().ok();
    assert!(
        response.starts_with("HTTP/1.1 200 OK"),
        "{}",
        &response[..100.min(response.len())]
    );
    assert!(response.ends_with(&std::fs::read_to_string(&out).unwrap()));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn problems_without_a_robot_and_bad_files_exit_with_code_2() {
    let d = dir("bad");
    let json = d.join("lqr.json");
    assert_eq!(
        gharial(&["solve", "lqr", "--output", json.to_str().unwrap()])
            .status
            .code(),
        Some(0)
    );
    for (args, needle) in [
        (vec!["view", json.to_str().unwrap()], "nothing to show"),
        (vec!["view", "/no/such.json"], "no/such"),
    ] {
        let o = gharial(&args);
        assert_eq!(o.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&o.stderr).contains(needle), "{args:?}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// The scene JSON embedded in a viewer page.
fn scene_json(html: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(html).unwrap();
    let start = text.find(r#"<script id="scene" type="application/json">"#).unwrap();
    let rest = &text[start..];
    serde_json::from_str(&rest[rest.find('>').unwrap() + 1..rest.find("</script>").unwrap()]).unwrap()
}

/// Problems without a robot get a sketch; the pendulum's bob ends where its terminal
/// constraint puts the tip, (0, 0, 1).
#[test]
fn sketches_of_the_problems_without_a_robot() {
    let d = dir("sketch");
    for name in ["pendulum", "cartpole", "acrobot", "se2-car"] {
        let (json, html) = (d.join(format!("{name}.json")), d.join(format!("{name}.html")));
        let o = gharial(&["solve", name, "--output", json.to_str().unwrap()]);
        assert!(o.status.code().is_some_and(|c| c <= 1), "{name}");
        let o = gharial(&["view", json.to_str().unwrap(), "--out", html.to_str().unwrap()]);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let scene = scene_json(&html);
        let solution: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let frames = solution["xs"].as_array().unwrap().len();
        assert_eq!(scene["frames"], frames, "{name}");
        assert!(!scene["bodies"].as_array().unwrap().is_empty(), "{name}");
        if name == "pendulum" {
            let bob = &scene["bodies"][1]["poses"][frames - 1];
            let p: Vec<f64> = (9..12).map(|i| bob[i].as_f64().unwrap()).collect();
            assert!(
                p[0].abs() < 1e-9 && p[1].abs() < 1e-4 && (p[2] - 1.0).abs() < 1e-4,
                "{p:?}"
            );
        }
    }
    std::fs::remove_dir_all(&d).ok();
}

/// A legged problem: the plots include the contact forces with their cone ratios, and
/// the viewer draws an arrow at each foot in contact, pointing up (the ground pushes).
#[test]
fn legged_problems_get_force_plots_and_arrows() {
    let d = dir("legged");
    let (json, html) = (d.join("s.json"), d.join("s.html"));
    let o = gharial(&[
        "solve",
        "solo-com-circle",
        "--max-iters",
        "1",
        "--output",
        json.to_str().unwrap(),
    ]);
    assert!(
        o.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = gharial(&["plot", json.to_str().unwrap(), "--out", d.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(d.join("solo-com-circle-forces.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (900, 820), "two panels: forces and cone ratios");
    let o = gharial(&["view", json.to_str().unwrap(), "--out", html.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let scene = scene_json(&html);
    let arrows = scene["arrows"].as_array().unwrap();
    assert_eq!(arrows.len(), scene["frames"].as_u64().unwrap() as usize);
    let first = arrows[0].as_array().unwrap();
    assert_eq!(first.len(), 4);
    assert!(first.iter().all(|a| a["vector"][2].as_f64().unwrap() > 0.0));
    assert!(arrows.last().unwrap().as_array().unwrap().is_empty());
    std::fs::remove_dir_all(&d).ok();
}
