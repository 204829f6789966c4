//! `gharial bench profile` end to end: the CSV of a small run has one non-decreasing
//! curve in [0, 1] per solver, its last row agrees with solves run here, and bad input
//! exits with code 2.

use std::process::{Command, Output};

use gharial::solvers::ddp::{Ddp, DdpOptions, DdpVariant};
use gharial::solvers::{InitialGuess, Solver};

fn gharial(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gharial"))
        .args(args)
        .output()
        .expect("the gharial binary runs")
}

/// The CSV's header and rows.
fn read_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(str::to_string).collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

#[test]
fn pendulum_profile_has_monotone_fractions_per_solver() {
    let path = std::env::temp_dir().join(format!("gharial-profile-{}.csv", std::process::id()));
    let o = gharial(&[
        "bench",
        "profile",
        "pendulum",
        "--count",
        "4",
        "--max-budget",
        "20",
        "--output",
        path.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (header, rows) = read_csv(&path);
    std::fs::remove_file(&path).ok();
    assert_eq!(header, ["budget", "ddp", "fddp", "fddp-filter", "sqp", "proxddp"]);
    assert_eq!(rows.len(), 20);
    for (b, row) in rows.iter().enumerate() {
        assert_eq!(row[0], (b + 1) as f64, "budget column");
        for (s, v) in row[1..].iter().enumerate() {
            assert!((0.0..=1.0).contains(v), "{} at budget {}: {v}", header[s + 1], b + 1);
            // Four instances: multiples of 1/4.
            assert_eq!((v * 4.0).fract(), 0.0, "{v}");
            if b > 0 {
                assert!(
                    *v >= rows[b - 1][s + 1],
                    "{} decreases at budget {}",
                    header[s + 1],
                    b + 1
                );
            }
        }
    }
    // The summary on standard output names every solver.
    let text = String::from_utf8_lossy(&o.stdout);
    for s in &header[1..] {
        assert!(
            text.lines().any(|l| l.starts_with(s.as_str())),
            "summary misses {s}: {text}"
        );
    }
}

#[test]
fn the_own_criterion_matches_solves_run_here() {
    // With `--criterion own`, SQP's fraction within the largest budget is the fraction of
    // instances SQP converges on with that iteration limit (+1) at tol 1e-4.
    let path = std::env::temp_dir().join(format!("gharial-profile-own-{}.csv", std::process::id()));
    let o = gharial(&[
        "bench",
        "profile",
        "pendulum",
        "--count",
        "4",
        "--max-budget",
        "30",
        "--solvers",
        "sqp",
        "--criterion",
        "own",
        "--output",
        path.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (_, rows) = read_csv(&path);
    std::fs::remove_file(&path).ok();
    let mut solved = 0;
    for ex in gharial_problems::profiles::family("pendulum", 1, 4).unwrap() {
        let mut sqp = Ddp::new(DdpOptions::new(DdpVariant::Sqp).with(|o| {
            o.tol = 1e-4;
            o.max_iters = 31;
            o.filter_size = 31;
        }));
        sqp.setup(&ex.problem).unwrap();
        let sol = sqp.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
        if sol.status.converged() && sol.iterations <= 30 {
            solved += 1;
        }
    }
    assert_eq!(rows[29][1], solved as f64 / 4.0);
}

#[test]
fn bad_input_exits_with_code_2() {
    for args in [
        &["bench", "profile", "taichi", "--count", "2"][..],
        &["bench", "profile", "pendulum", "--solvers", "newton"],
        &["bench", "profile", "pendulum", "--count", "0"],
        &["bench", "profile", "pendulum", "--count", "100000"],
        &["bench", "profile", "pendulum", "--max-budget", "0"],
        &["bench", "profile", "pendulum", "--max-budget", "5000"],
        &["bench", "profile", "pendulum", "--tol", "-1"],
        &["bench", "profile", "pendulum", "--criterion", "best"],
    ] {
        let o = gharial(args);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!o.stderr.is_empty(), "{args:?}: no message");
    }
    let o = gharial(&["bench", "profile", "taichi"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("unknown family `taichi`") && e.contains("humanoid"), "{e}");
}
