//! The `gharial` binary end to end: listing, solving with the JSON output checked
//! against the problem itself (KKT residuals recomputed from the written trajectory),
//! and clear errors with a non-zero exit code on bad input.

use std::process::{Command, Output};

use gharial::problem::kkt_residuals;

fn gharial(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gharial"))
        .args(args)
        .output()
        .expect("the gharial binary runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn list_names_every_catalogue_problem() {
    let o = gharial(&["list"]);
    assert!(o.status.success());
    let text = stdout(&o);
    assert!(text.contains("proxddp"));
    for info in gharial_problems::catalogue() {
        assert!(text.contains(info.name), "`gharial list` misses {}", info.name);
    }
}

fn vectors(v: &serde_json::Value) -> Vec<Vec<f64>> {
    v.as_array()
        .expect("array of vectors")
        .iter()
        .map(|x| {
            x.as_array()
                .expect("vector")
                .iter()
                .map(|e| e.as_f64().expect("number"))
                .collect()
        })
        .collect()
}

#[test]
fn solve_writes_a_primal_dual_solution_that_satisfies_the_kkt_conditions() {
    let path = std::env::temp_dir().join(format!("gharial-cli-test-{}.json", std::process::id()));
    let path_str = path.to_str().expect("UTF-8 temp path");
    let o = gharial(&["solve", "lqr-bounds-term", "--tol", "1e-8", "--output", path_str]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("status    converged"), "{text}");
    assert!(text.contains(" iter "), "the iteration table is printed: {text}");

    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(doc["problem"], "lqr-bounds-term");
    assert_eq!(doc["converged"], true);
    assert_eq!(doc["settings"]["tol"], 1e-8);
    let (xs, us) = (vectors(&doc["xs"]), vectors(&doc["us"]));
    let (lambdas, nus) = (vectors(&doc["lambdas"]), vectors(&doc["nus"]));
    let ex = gharial_problems::build("lqr-bounds-term").unwrap();
    assert_eq!(xs.len(), ex.problem.horizon() + 1);
    assert_eq!(us.len(), ex.problem.horizon());
    assert_eq!(
        doc["history"].as_array().unwrap().len(),
        doc["iterations"].as_u64().unwrap() as usize
    );
    // The written point is optimal for the problem the library builds under that name.
    let kkt = kkt_residuals(&ex.problem, &xs, &us, &lambdas, &nus).unwrap();
    assert!(kkt.max() < 1e-8, "{kkt:?}");
    // The bounds |u| <= 0.15 hold and some are active.
    let u_max = us.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs()));
    assert!((u_max - 0.15).abs() < 1e-8, "largest |u| = {u_max}");
    // The cost reported is the cost of the written trajectory.
    let cost = gharial_problems::total_cost(&ex.problem, &xs, &us).unwrap();
    assert!((cost - doc["cost"].as_f64().unwrap()).abs() < 1e-12 * cost.abs().max(1.0));
}

#[test]
fn bad_input_gives_a_message_and_a_failure_code() {
    let o = gharial(&["solve", "no-such-problem"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("no-such-problem") && err.contains("pendulum"), "{err}");

    let o = gharial(&["solve", "lqr", "--tol=-1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("tol"), "{}", stderr(&o));

    let o = gharial(&["solve", "lqr", "--dyn-al-scale=0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--dyn-al-scale"), "{}", stderr(&o));

    let o = gharial(&["solve", "lqr", "--solver", "nope"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("proxddp"));
}

#[test]
fn an_unconverged_solve_exits_with_code_one() {
    let o = gharial(&["solve", "pendulum", "--max-iters", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).contains("maximum iterations"), "{}", stdout(&o));
}

#[test]
fn step_acceptance_merit_and_dynamics_scale_overrides_reach_the_solver() {
    let path = std::env::temp_dir().join(format!("gharial-cli-accept-{}.json", std::process::id()));
    let path_str = path.to_str().expect("UTF-8 temp path");
    let o = gharial(&[
        "solve",
        "lqr-bounds-term",
        "--step-acceptance",
        "nonmonotone",
        "--merit",
        "primal",
        "--dyn-al-scale",
        "0.5",
        "--output",
        path_str,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(doc["settings"]["step_acceptance"], "NonmonotoneLinesearch");
    assert_eq!(doc["settings"]["merit"], "Primal");
    assert_eq!(doc["settings"]["dyn_al_scale"], 0.5);
    assert_eq!(doc["converged"], true);
    let ex = gharial_problems::build("lqr-bounds-term").unwrap();
    let (xs, us) = (vectors(&doc["xs"]), vectors(&doc["us"]));
    let (lambdas, nus) = (vectors(&doc["lambdas"]), vectors(&doc["nus"]));
    let kkt = kkt_residuals(&ex.problem, &xs, &us, &lambdas, &nus).unwrap();
    assert!(kkt.max() < ex.proxddp.tol, "{kkt:?}");

    let o = gharial(&["solve", "lqr", "--step-acceptance", "nope"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("filter"), "{}", stderr(&o));
}

/// Every invalid invocation exits with code 2, names the offending option or value in
/// its message, and runs nothing.
#[test]
fn invalid_options_are_refused_before_any_work() {
    let dir = std::env::temp_dir().join(format!("gharial-cli-missing-{}", std::process::id()));
    let unwritable = dir.join("sub/solution.json");
    let unwritable = unwritable.to_str().expect("UTF-8 temp path");
    let cases: &[(&[&str], &str)] = &[
        (&["bench", "riccati", "--threads", "0"], "--threads"),
        (&["bench", "riccati", "--threads", "1,0"], "--threads"),
        (&["bench", "riccati", "--budget", "nan"], "--budget"),
        (&["bench", "riccati", "--budget", "inf"], "--budget"),
        (&["bench", "riccati", "--horizons", "0"], "--horizons"),
        (&["bench", "riccati", "--rounds", "0"], "--rounds"),
        (&["bench", "riccati", "--dims", "0:1:1"], "nx and N"),
        (&["bench", "riccati", "--extra", "4:2:2:0"], "nx and N"),
        (&["bench", "solve", "--repeats", "0"], "--repeats"),
        (&["bench", "peers", "--repeats", "0"], "--repeats"),
        (&["bench", "peers", "--lqr-umax=-1"], "--lqr-umax"),
        (&["solve", "lqr", "--threads", "0"], "--threads"),
        (&["solve", "lqr", "--max-iters", "0"], "--max-iters"),
        (&["solve", "lqr", "--mu-init", "nan"], "--mu-init"),
        (&["solve", "lqr", "--tol", "inf"], "--tol"),
        (&["solve", "lqr", "--output", unwritable], "cannot write"),
        (&["solve", "lqr", "--active-set-iters", "101"], "--active-set-iters"),
        (&["bench", "riccati", "--rounds", "18446744073709551615"], "--rounds"),
        (&["bench", "riccati", "--refine", "1000000"], "--refine"),
        (&["bench", "riccati", "--horizons", "1000000000"], "--horizons"),
        (&["bench", "riccati", "--horizons", "1000000"], "GiB"),
        (&["bench", "riccati", "--dims", "100000:1:1"], "at most"),
        (&["bench", "riccati", "--budget", "1e9"], "--budget"),
        (&["bench", "solve", "--repeats", "18446744073709551615"], "--repeats"),
        (&["bench", "peers", "--lqr-N", "1000000", "--lqr-nx", "100"], "GiB"),
    ];
    for (args, needle) in cases {
        let o = gharial(args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            stdout(&o).is_empty() || !stdout(&o).contains("status"),
            "{args:?} ran a solve"
        );
    }
}

#[test]
fn huge_iteration_limits_are_accepted_without_reserving_memory_for_them() {
    for limit in ["1000000000000", &usize::MAX.to_string()] {
        let o = gharial(&["solve", "pendulum", "--max-iters", limit]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        assert!(
            stdout(&o).contains(&format!("max_iters {limit} [option; default 300]")),
            "{}",
            stdout(&o)
        );
    }
}

#[test]
fn the_header_says_which_settings_the_problem_recommends() {
    let o = gharial(&["solve", "pendulum", "--tol", "1e-7"]);
    let text = stdout(&o);
    assert!(text.contains("mu_init 1 [problem; default 0.01]"), "{text}");
    assert!(text.contains("tol 1e-7 [option; default 1e-6]"), "{text}");
    let help = stdout(&gharial(&["solve", "--help"]));
    for column in ["inner_crit", "dphi0", "dM", "preg", "al "] {
        assert!(help.contains(column), "`solve --help` does not explain {column}");
    }
}
