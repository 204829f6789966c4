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

/// The solvers' command-line names.
const SOLVERS: [&str; 10] = [
    "proxddp", "ddp", "fddp", "box-ddp", "box-fddp", "sqp", "csqp", "bcl-ddp", "altro", "proxnlp",
];

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
    for solver in SOLVERS {
        let line = text.lines().find(|l| l.split_whitespace().next() == Some(solver));
        assert!(line.is_some(), "`gharial list` misses the solver {solver}: {text}");
    }
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

/// Runs `gharial <args> --output <a temporary file>` and returns the process's output
/// and the JSON document it wrote (`tag` keeps the file names of tests apart).
fn run_with_output(tag: &str, args: &[&str]) -> (Output, serde_json::Value) {
    let path = std::env::temp_dir().join(format!("gharial-cli-{tag}-{}.json", std::process::id()));
    let path_str = path.to_str().expect("UTF-8 temp path");
    let o = gharial(&[args, &["--output", path_str]].concat());
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{args:?} wrote no output ({e}): {}{}", stdout(&o), stderr(&o)));
    std::fs::remove_file(&path).unwrap();
    (o, serde_json::from_str(&text).unwrap())
}

/// The KKT residuals of the primal-dual point written in `doc`, recomputed on `problem`.
fn written_kkt(problem: &gharial::problem::Problem, doc: &serde_json::Value) -> gharial::problem::KktResiduals {
    let (xs, us) = (vectors(&doc["xs"]), vectors(&doc["us"]));
    let (lambdas, nus) = (vectors(&doc["lambdas"]), vectors(&doc["nus"]));
    kkt_residuals(problem, &xs, &us, &lambdas, &nus).unwrap()
}

#[test]
fn solve_writes_a_primal_dual_solution_that_satisfies_the_kkt_conditions() {
    let (o, doc) = run_with_output("test", &["solve", "lqr-bounds-term", "--tol", "1e-8"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("status    converged"), "{text}");
    assert!(text.contains(" iter "), "the iteration table is printed: {text}");

    assert_eq!(doc["problem"], "lqr-bounds-term");
    assert_eq!(doc["converged"], true);
    assert_eq!(doc["settings"]["tol"], 1e-8);
    let (xs, us) = (vectors(&doc["xs"]), vectors(&doc["us"]));
    let ex = gharial_problems::build("lqr-bounds-term").unwrap();
    assert_eq!(xs.len(), ex.problem.horizon() + 1);
    assert_eq!(us.len(), ex.problem.horizon());
    assert_eq!(
        doc["history"].as_array().unwrap().len(),
        doc["iterations"].as_u64().unwrap() as usize
    );
    // The written point is optimal for the problem the library builds under that name.
    let kkt = written_kkt(&ex.problem, &doc);
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
    let err = stderr(&o);
    assert!(err.contains("nope"), "{err}");
    for solver in SOLVERS {
        assert!(err.contains(solver), "the message does not list {solver}: {err}");
    }
}

#[test]
fn an_unconverged_solve_exits_with_code_one() {
    let o = gharial(&["solve", "pendulum", "--max-iters", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).contains("maximum iterations"), "{}", stdout(&o));
}

#[test]
fn step_acceptance_merit_and_dynamics_overrides_reach_the_solver() {
    let (o, doc) = run_with_output(
        "accept",
        &[
            "solve",
            "lqr-bounds-term",
            "--step-acceptance",
            "nonmonotone",
            "--merit",
            "primal",
            "--dyn-al-scale",
            "0.5",
            "--dynamics-step",
            "exact",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(doc["settings"]["step_acceptance"], "NonmonotoneLinesearch");
    assert_eq!(doc["settings"]["merit"], "Primal");
    assert_eq!(doc["settings"]["dyn_al_scale"], 0.5);
    assert_eq!(doc["settings"]["dynamics_step"], "Exact");
    assert_eq!(doc["converged"], true);
    let ex = gharial_problems::build("lqr-bounds-term").unwrap();
    let kkt = written_kkt(&ex.problem, &doc);
    assert!(kkt.max() < ex.proxddp.tol, "{kkt:?}");

    let o = gharial(&["solve", "lqr", "--step-acceptance", "nope"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("filter"), "{}", stderr(&o));
}

/// ALTRO's own options reach it: with the authors' settings for the car escape and the
/// infeasible start, the command line solves it to their 1e-8 (from the rollout of the
/// guess's controls ALTRO does not, `tests/altro_escape.rs` of the catalogue).
#[test]
fn altro_options_reach_the_solver() {
    let (o, doc) = run_with_output(
        "altro",
        &[
            "solve",
            "car-escape",
            "--solver",
            "altro",
            "--infeasible-start",
            "--penalty-initial",
            "10",
            "--penalty-scaling",
            "100",
            "--tol",
            "1e-8",
            "--max-iters",
            "20",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("infeasible_start true [option; default false]"),
        "{}",
        stdout(&o)
    );
    assert_eq!(doc["settings"]["infeasible_start"], "true");
    assert_eq!(doc["settings"]["penalty_initial"], 10.0);
    assert_eq!(doc["settings"]["penalty_scaling"], 100.0);
    assert_eq!(doc["settings"]["projected_newton"], "true");
    assert_eq!(doc["converged"], true);
    // The solution's dynamics and constraints (wall discs, goal), evaluated here.
    let kkt = written_kkt(&gharial_problems::build("car-escape").unwrap().problem, &doc);
    assert!(kkt.primal() <= 1e-8, "{kkt:?}");
}

/// The settings a `gharial solve --output` run reports, and its exit code.
fn solve_settings(args: &[&str]) -> (Option<i32>, serde_json::Value) {
    let (o, doc) = run_with_output(&format!("settings-{}", args[1]), args);
    (o.status.code(), doc)
}

/// CSQP's QP tolerances, BCL-DDP's strategies and ProxNLP's shared options reach the
/// solvers; BCL-DDP with the penalty multiplied by 3 after every iteration stalls on
/// the ECDDP cart-pole (the paper's Fig. 4) where the BCL rules converge.
#[test]
fn csqp_bcl_ddp_and_proxnlp_options_reach_the_solvers() {
    let (code, doc) = solve_settings(&[
        "solve",
        "peers-lqr-box",
        "--solver",
        "csqp",
        "--eps-abs",
        "1e-6",
        "--eps-rel",
        "1e-7",
        "--max-qp-iters",
        "5000",
    ]);
    assert_eq!(code, Some(0));
    assert_eq!(doc["settings"]["eps_abs"], 1e-6);
    assert_eq!(doc["settings"]["eps_rel"], 1e-7);
    assert_eq!(doc["settings"]["max_qp_iters"], 5000);
    assert_kkt_point("peers-lqr-box", &doc, 1e-6);

    let fig4 = [
        "solve",
        "ecddp-cartpole",
        "--solver",
        "bcl-ddp",
        "--schedule",
        "every-iteration",
        "--penalty-factor",
        "3",
    ];
    let (code, doc) = solve_settings(&fig4);
    assert_eq!(code, Some(1), "{doc}");
    assert_eq!(doc["settings"]["schedule"], "EveryIteration");
    assert_eq!(doc["settings"]["penalty_factor"], 3.0);
    assert_eq!(doc["converged"], false);
    let (code, doc) = solve_settings(&[
        "solve",
        "ecddp-cartpole",
        "--solver",
        "bcl-ddp",
        "--penalty-update",
        "adaptive",
        "--multipliers",
        "affine",
        "--inner",
        "fddp",
        "--mu-init",
        "100",
    ]);
    assert_eq!(code, Some(0), "{doc}");
    for (key, value) in [
        ("penalty", "Adaptive"),
        ("multipliers", "Affine"),
        ("inner", "fddp"),
        ("schedule", "Bcl"),
    ] {
        assert_eq!(doc["settings"][key], value, "{key}");
    }
    assert_eq!(doc["settings"]["mu_init"], 100.0);

    let (code, doc) = solve_settings(&[
        "solve",
        "lqr-bounds",
        "--solver",
        "proxnlp",
        "--mu-init",
        "1e-3",
        "--step-acceptance",
        "nonmonotone",
    ]);
    assert_eq!(code, Some(0), "{doc}");
    assert_eq!(doc["settings"]["mu_init"], 1e-3);
    assert_eq!(doc["settings"]["step_acceptance"], "NonmonotoneLinesearch");
    assert_kkt_point("lqr-bounds", &doc, 1e-6);
}

/// The solution of `solve --output` on `problem` satisfies the KKT conditions to `tol`,
/// recomputed here from its states, controls and multipliers.
fn assert_kkt_point(problem: &str, doc: &serde_json::Value, tol: f64) {
    let kkt = written_kkt(&gharial_problems::build(problem).unwrap().problem, doc);
    assert!(kkt.max() <= tol, "{problem}: {kkt:?}");
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
        (
            &[
                "bench",
                "riccati",
                "--mu",
                "0",
                "--dims",
                "2:1:1",
                "--horizons",
                "2",
                "--extra=",
            ],
            "take mu > 0",
        ),
        (&["bench", "solve", "--repeats", "0"], "--repeats"),
        (&["bench", "peers", "--repeats", "0"], "--repeats"),
        (&["bench", "peers", "--lqr-umax=-1"], "--lqr-umax"),
        (&["solve", "lqr", "--threads", "0"], "--threads"),
        (&["solve", "lqr", "--max-iters", "0"], "--max-iters"),
        (&["solve", "lqr", "--mu-init", "nan"], "--mu-init"),
        (&["solve", "lqr", "--tol", "inf"], "--tol"),
        (&["solve", "lqr", "--output", unwritable], "cannot write"),
        (&["solve", "lqr", "--active-set-iters", "101"], "--active-set-iters"),
        (&["solve", "lqr", "--solver", "fddp", "--mu-init", "1"], "--mu-init"),
        (
            &["solve", "lqr", "--solver", "box-ddp", "--step-acceptance", "filter"],
            "--step-acceptance",
        ),
        (&["solve", "lqr", "--solver", "ddp", "--rollout", "linear"], "--rollout"),
        (&["solve", "lqr", "--infeasible-start"], "--infeasible-start"),
        (&["solve", "lqr", "--eps-abs", "1e-3"], "--eps-abs"),
        (
            &["solve", "lqr", "--solver", "csqp", "--max-qp-iters", "0"],
            "--max-qp-iters",
        ),
        (&["solve", "lqr", "--solver", "fddp", "--schedule", "bcl"], "--schedule"),
        (&["solve", "lqr", "--solver", "bcl-ddp", "--inner", "sqp"], "--inner"),
        (
            &["solve", "lqr", "--solver", "bcl-ddp", "--penalty-factor", "1"],
            "penalty_factor",
        ),
        (&["solve", "lqr", "--solver", "ddp", "--mu-init", "1"], "--mu-init"),
        (&["solve", "lqr", "--solver", "fddp", "--square-root"], "--square-root"),
        (
            &["solve", "lqr", "--solver", "altro", "--penalty-scaling", "0"],
            "--penalty-scaling",
        ),
        (
            &["solve", "lqr", "--solver", "altro", "--penalty-scaling", "0.5"],
            "penalty_scaling",
        ),
        (
            &["solve", "lqr", "--solver", "altro", "--penalty-initial", "nan"],
            "--penalty-initial",
        ),
        (
            &["solve", "lqr", "--solver", "fddp", "--output", unwritable],
            "cannot write",
        ),
        (&["solve", "lqr-bounds", "--solver", "ddp"], "u_box"),
        (&["solve", "lqr", "--solver", "FDDP"], "box-fddp"),
        (
            &["bench", "solve", "lqr", "--solver", "fddp", "--merit", "primal"],
            "--merit",
        ),
        (
            &["bench", "solve", "lqr", "--solver", "ddp", "--active-set-iters", "101"],
            "--active-set-iters",
        ),
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
    // The DDP family's table, from the solver itself.
    let legend = gharial::solvers::ddp::TABLE.legend();
    assert!(
        help.contains(&legend),
        "`solve --help` lacks the DDP family's columns:\n{help}"
    );
    for column in ["stop", "dV_exp", "gaps", "|Q_u|", "reg"] {
        assert!(legend.lines().any(|l| l.starts_with(column)), "{column}");
    }
    // The DDP family's settings line: its defaults, and the options given.
    let text = stdout(&gharial(&["solve", "peers-lqr", "--solver", "fddp", "--tol", "1e-7"]));
    assert!(
        text.contains("solver    FDDP (tol 1e-7 [option; default 1e-6], max_iters 300,"),
        "{text}"
    );
    assert!(!text.contains("[problem"), "{text}");
    assert!(
        text.contains(&gharial::solvers::ddp::TABLE.header().to_string()),
        "{text}"
    );
}

/// Solves `problem` with `solver` writing the JSON output; returns the document (its
/// `solver`, `converged` and history checked) and the catalogue's example.
fn solve_to_json(problem: &str, solver: &str, extra: &[&str]) -> (serde_json::Value, gharial_problems::Example) {
    let args = [&["solve", problem, "--solver", solver], extra].concat();
    let (o, doc) = run_with_output(&format!("{solver}-{problem}"), &args);
    assert_eq!(o.status.code(), Some(0), "{args:?}: {}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("status    converged"), "{}", stdout(&o));
    assert_eq!(doc["solver"], solver);
    assert_eq!(doc["converged"], true);
    let history = doc["history"].as_array().unwrap();
    assert_eq!(history.len(), doc["iterations"].as_u64().unwrap() as usize);
    (doc, gharial_problems::build(problem).unwrap())
}

/// The KKT residuals of the written primal-dual point, recomputed from the problem the
/// library builds under that name, and the cost of the written trajectory.
fn check_written_solution(doc: &serde_json::Value, ex: &gharial_problems::Example, tol: f64) {
    let kkt = written_kkt(&ex.problem, doc);
    assert!(kkt.max() < tol, "{kkt:?}");
    let (xs, us) = (vectors(&doc["xs"]), vectors(&doc["us"]));
    let cost = gharial_problems::total_cost(&ex.problem, &xs, &us).unwrap();
    assert!((cost - doc["cost"].as_f64().unwrap()).abs() < 1e-12 * cost.abs().max(1.0));
}

#[test]
fn fddp_solves_the_peers_lqr_to_a_kkt_point() {
    let (doc, ex) = solve_to_json("peers-lqr", "fddp", &["--tol", "1e-8"]);
    assert_eq!(doc["settings"]["tol"], 1e-8);
    assert_eq!(doc["settings"]["max_iters"], 300);
    assert!(doc["settings"].get("mu_init").is_none(), "{}", doc["settings"]);
    // An LQ problem: one exact step (regularisation 0), whose expected decrease is the
    // actual one.
    let row = &doc["history"][0];
    assert_eq!(row["alpha"], 1.0);
    let (expected, actual) = (
        row["expected_decrease"].as_f64().unwrap(),
        row["decrease"].as_f64().unwrap(),
    );
    assert!(expected > 0.0 && (expected - actual).abs() < 1e-9 * expected, "{row}");
    check_written_solution(&doc, &ex, 1e-8);
}

#[test]
fn box_fddp_solves_the_peers_box_lqr_to_a_kkt_point_within_the_bounds() {
    let (doc, ex) = solve_to_json("peers-lqr-box", "box-fddp", &[]);
    check_written_solution(&doc, &ex, 1e-6);
    // The bounds |u| <= 0.05 hold and some are active.
    let us = vectors(&doc["us"]);
    let u_max = us.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs()));
    assert!((u_max - 0.05).abs() < 1e-12, "largest |u| = {u_max}");
    // The same optimum as ProxDDP's (an independent algorithm) to the tolerance.
    let (prox, _) = solve_to_json("peers-lqr-box", "proxddp", &[]);
    let (c, c_prox) = (doc["cost"].as_f64().unwrap(), prox["cost"].as_f64().unwrap());
    assert!((c - c_prox).abs() < 1e-6 * c_prox, "box-fddp {c}, proxddp {c_prox}");
}

#[test]
fn a_problem_the_solver_does_not_take_is_refused_naming_the_constraint() {
    let o = gharial(&["solve", "lqr-bounds", "--solver", "ddp"]);
    assert_eq!(o.status.code(), Some(2), "{}", stdout(&o));
    let err = stderr(&o);
    assert!(err.contains("ddp") && err.contains("u_box"), "{err}");
    assert!(!stdout(&o).contains("status"), "{}", stdout(&o));
    // The box variants take the same problem.
    let o = gharial(&["solve", "lqr-bounds", "--solver", "box-ddp"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
}

#[test]
fn bench_solve_lists_the_problems_a_solver_does_not_take_as_skipped() {
    let o = gharial(&[
        "bench",
        "solve",
        "peers-lqr",
        "lqr-bounds",
        "--solver",
        "fddp",
        "--repeats",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let text = stdout(&o);
    let line = |name: &str| {
        text.lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("no line for {name}: {text}"))
    };
    assert!(line("peers-lqr").contains("converged"), "{text}");
    assert!(
        line("lqr-bounds").contains("skipped") && line("lqr-bounds").contains("u_box"),
        "{text}"
    );
}

/// ProxNLP solves the UR5 reaching (101 states of 12, 100 controls of 6, 1212 equality
/// rows: 3024 KKT rows, beyond the dense solve) through its sparse KKT solve.
#[test]
fn bench_solve_runs_proxnlp_on_the_ur5_with_the_sparse_kkt() {
    let o = gharial(&["bench", "solve", "ur5", "lqr", "--solver", "proxnlp", "--repeats", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let text = stdout(&o);
    let line = |name: &str| {
        text.lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap()
    };
    assert!(line("ur5").contains("converged"), "{text}");
    assert!(line("lqr").contains("converged"), "{text}");
}

/// `--all-solvers`: a row per problem and solver, the same optimum from every solver that
/// takes a problem (costs to 1e-6 relative: the solvers' tolerances differ), and the
/// matrix with `-` where a solver does not take the problem.
#[test]
fn bench_solve_all_solvers_prints_the_matrix_of_problems_by_solvers() {
    let o = gharial(&["bench", "solve", "lqr", "lqr-bounds", "--all-solvers", "--repeats", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let text = stdout(&o);
    for problem in ["lqr", "lqr-bounds"] {
        let costs: Vec<f64> = text
            .lines()
            .map(|l| l.split_whitespace().collect::<Vec<_>>())
            .filter(|w| w.first() == Some(&problem) && w.get(3) == Some(&"converged"))
            .map(|w| w[w.len() - 4].parse().expect("the cost column"))
            .collect();
        let takers = if problem == "lqr" { SOLVERS.len() } else { 6 };
        assert_eq!(costs.len(), takers, "{problem}: {text}");
        for c in &costs {
            assert!((c - costs[0]).abs() < 1e-6 * costs[0].abs(), "{problem}: {costs:?}");
        }
    }
    let matrix = text.split("not taken").nth(1).expect("the matrix");
    let row = |name: &str| -> Vec<String> {
        let line = matrix
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap();
        line.split("  ")
            .map(str::trim)
            .filter(|c| !c.is_empty())
            .skip(1)
            .map(String::from)
            .collect()
    };
    let header: Vec<&str> = matrix.lines().nth(1).unwrap().split_whitespace().skip(1).collect();
    assert_eq!(header, SOLVERS, "{matrix}");
    assert!(row("lqr").iter().all(|c| c.starts_with("1 / ")), "{matrix}");
    let taken: Vec<bool> = row("lqr-bounds").iter().map(|c| c != "-").collect();
    let takes_bounds = ["proxddp", "box-ddp", "box-fddp", "csqp", "altro", "proxnlp"];
    let expected: Vec<bool> = SOLVERS.iter().map(|s| takes_bounds.contains(s)).collect();
    assert_eq!(taken, expected, "{matrix}");
}

#[test]
fn bench_peers_runs_the_solvers_asked_for() {
    let o = gharial(&[
        "bench",
        "peers",
        "--problems",
        "lqr",
        "--solvers",
        "SQP,FDDP",
        "--repeats",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let lines: Vec<serde_json::Value> = stdout(&o)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    let solvers: Vec<&str> = lines.iter().map(|l| l["solver"].as_str().unwrap()).collect();
    // In the table's order, each once, and solved to the same optimum.
    assert_eq!(solvers, ["FDDP", "SQP"]);
    let costs: Vec<f64> = lines.iter().map(|l| l["final_cost"].as_f64().unwrap()).collect();
    assert!((costs[0] - costs[1]).abs() < 1e-9 * costs[0], "{costs:?}");
    let o = gharial(&["bench", "peers", "--problems", "lqr", "--solvers", "FDDP,Crocoddyl"]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("unknown solver `Crocoddyl`") && e.contains("BoxFDDP"), "{e}");
    assert!(stdout(&o).is_empty());
}

#[test]
fn bench_peers_reports_every_solver_on_the_problems_it_takes() {
    let dir = std::env::temp_dir().join(format!("gharial-cli-peers-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let o = gharial(&[
        "bench",
        "peers",
        "--problems",
        "lqr,lqr_box",
        "--repeats",
        "1",
        "--traj-dir",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let lines: Vec<serde_json::Value> = stdout(&o)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    let solvers = |problem: &str| -> Vec<String> {
        lines
            .iter()
            .filter(|l| l["problem"] == problem)
            .map(|l| l["solver"].as_str().unwrap().to_string())
            .collect()
    };
    let all = [
        "ProxDDP",
        "ProxDDP_ls",
        "ProxDDP_as",
        "DDP",
        "FDDP",
        "BoxDDP",
        "BoxFDDP",
        "SQP",
        "CSQP",
        "BCL-DDP",
        "ALTRO",
        "ProxNLP",
    ];
    assert_eq!(solvers("lqr"), all);
    assert_eq!(
        solvers("lqr_box"),
        [
            "ProxDDP",
            "ProxDDP_ls",
            "ProxDDP_as",
            "BoxDDP",
            "BoxFDDP",
            "CSQP",
            "ALTRO",
            "ProxNLP"
        ]
    );
    // All solvers of one problem together.
    assert!(lines[..all.len()].iter().all(|l| l["problem"] == "lqr"));
    let params = gharial_problems::peers::PeersLqrParams::default();
    for l in &lines {
        let (problem, solver) = (l["problem"].as_str().unwrap(), l["solver"].as_str().unwrap());
        assert_eq!(l["converged"], true, "{l}");
        for key in [
            "iters",
            "init_cost",
            "final_cost",
            "time_ms",
            "time_ms_min",
            "prim_res",
            "dual_res",
            "model_eval_ms",
            "model_deriv_ms",
            "settings",
        ] {
            assert!(!l[key].is_null(), "{key} missing: {l}");
        }
        // The trajectory written is the solution reported: its cost, recomputed.
        let variant = if problem == "lqr" {
            gharial_problems::peers::PeersVariant::Lqr
        } else {
            gharial_problems::peers::PeersVariant::Box
        };
        let ex = gharial_problems::peers::build(&params, variant).unwrap();
        let path = dir.join(format!("{problem}__gharial_{solver}.txt"));
        let (xs, us) = read_traj(&std::fs::read_to_string(&path).unwrap());
        let cost = gharial_problems::total_cost(&ex.problem, &xs, &us).unwrap();
        let reported = l["final_cost"].as_f64().unwrap();
        assert!(
            (cost - reported).abs() < 1e-12 * reported,
            "{problem} {solver}: {cost} vs {reported}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
    let settings = lines.iter().find(|l| l["solver"] == "FDDP").unwrap()["settings"].clone();
    assert_eq!(settings, "tol=1e-6 th_stop=tol^2*N variant=fddp reg_init=0 threads=1");
    // Every solver reaches the same optimum of each problem (the DDP family to its
    // tolerance, tol^2 N on the expected decrease).
    for problem in ["lqr", "lqr_box"] {
        let costs: Vec<f64> = lines
            .iter()
            .filter(|l| l["problem"] == problem)
            .map(|l| l["final_cost"].as_f64().unwrap())
            .collect();
        let (lo, hi) = costs
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &c| (a.min(c), b.max(c)));
        assert!(hi - lo < 1e-5 * lo, "{problem}: final costs {costs:?}");
    }
}

/// A trajectory file of the peer harness: `x ...` lines, then `u ...` lines.
fn read_traj(text: &str) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let (mut xs, mut us) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let mut words = line.split_whitespace();
        let kind = words.next().expect("a tag");
        let v: Vec<f64> = words.map(|w| w.parse().expect("a number")).collect();
        match kind {
            "x" => xs.push(v),
            "u" => us.push(v),
            other => panic!("unknown line tag {other}"),
        }
    }
    (xs, us)
}

#[test]
fn simulate_writes_a_closed_loop_that_the_plant_replays() {
    let path = std::env::temp_dir().join(format!("gharial-cli-sim-{}.json", std::process::id()));
    let path_str = path.to_str().expect("UTF-8 temp path");
    for solver in ["proxddp", "fddp"] {
        let args = [
            "simulate",
            "ur5-circle-mpc",
            "--duration",
            "0.5",
            "--max-iters",
            "2",
            "--solver",
            solver,
            "--output",
            path_str,
        ];
        let o = gharial(&args);
        assert!(o.status.success(), "{solver}: {}", stderr(&o));
        let text = stdout(&o);
        assert!(
            text.contains("cycle time (ms)") && text.contains("mean tool error"),
            "{text}"
        );
        let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let (xs, us) = (vectors(&doc["xs"]), vectors(&doc["us"]));
        assert_eq!((xs.len(), us.len()), (501, 500));
        let cycles = doc["cycles"].as_array().unwrap();
        assert_eq!(cycles.len(), 10);
        assert!(cycles.iter().all(|c| c["iterations"].as_u64().unwrap() <= 2));
        let mean = doc["metrics"]["mean tool error"]["value"].as_f64().unwrap();
        assert!(mean.is_finite() && mean < 0.05, "{solver}: {mean}");
        // The record is the plant's own trajectory under the recorded controls.
        let mut sc = gharial_problems::mpc::scenario("ur5-circle-mpc").unwrap();
        assert_eq!(&xs[0][..], sc.example.problem.x0().unwrap());
        let mut next = vec![0.0; 12];
        for k in (0..500).step_by(37) {
            sc.plant.step(k, &xs[k], &us[k], &mut next).unwrap();
            let d = (0..12).map(|i| (next[i] - xs[k + 1][i]).abs()).fold(0.0, f64::max);
            assert!(d < 1e-12, "{solver}: step {k}: {d:e}");
        }
    }
    std::fs::remove_file(&path).ok();
    for (args, what) in [
        (vec!["simulate", "nope"], "unknown MPC scenario"),
        (vec!["simulate", "ur5-circle-mpc", "--duration", "1e9"], "at most 5000"),
        (vec!["simulate", "solo-walk-mpc", "--duration", "0"], "duration"),
        (
            vec!["simulate", "solo-walk-mpc", "--duration", "1e-4"],
            "one plant step",
        ),
        (
            vec!["simulate", "ur5-circle-mpc", "--output", "/nonexistent/dir/x.json"],
            "cannot write",
        ),
        (
            vec!["simulate", "ur5-circle-mpc", "--solver", "fddp", "--mu-init", "0.1"],
            "does not take",
        ),
        (vec!["simulate", "ur5-circle-mpc", "--payload", "-1"], "payload"),
        (vec!["simulate", "ur5-circle-mpc", "--payload", "1e3"], "at most 100 kg"),
        (vec!["simulate", "solo-walk-mpc", "--push", "1,0.3"], "T,VX,VY,VZ"),
        (vec!["simulate", "solo-walk-mpc", "--push", "1,nan,0,0"], "finite"),
        (vec!["simulate", "solo-walk-mpc", "--push", "1,11,0,0"], "±10 m/s"),
        (vec!["simulate", "solo-walk-mpc", "--slope", "0.4"], "±0.3 rad"),
        (vec!["simulate", "solo-walk-mpc", "--speed", "-2"], "±1 m/s"),
        (
            vec!["simulate", "ur5-circle-mpc", "--cycle-budget", "1e300"],
            "cycle_budget",
        ),
        (
            vec!["simulate", "ur5-circle-mpc", "--cycle-budget", "0"],
            "milliseconds",
        ),
        (
            vec!["simulate", "ur5-circle-mpc", "--push", "0.1,0,0.3,0"],
            "no floating base",
        ),
    ] {
        let o = gharial(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(what), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn solve_writes_the_figures_of_an_experiment() {
    let dir = std::env::temp_dir().join(format!("gharial-cli-fig-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let d = dir.to_str().unwrap();
    let o = gharial(&["solve", "solo-jump", "--figures", d]);
    assert!(o.status.success(), "{}", stderr(&o));
    let conv = std::fs::read_to_string(dir.join("solo-jump-convergence.csv")).unwrap();
    let rows: Vec<&str> = conv.lines().collect();
    assert!(rows[0].starts_with("iter,prim_err,dual_err"), "{}", rows[0]);
    // One row per iteration of the printed table, the last below the tolerance.
    let last: Vec<f64> = rows.last().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    assert!(rows.len() > 10 && last[1] < 1e-6 && last[2] < 1e-5, "{last:?}");
    let traj = std::fs::read_to_string(dir.join("solo-jump-trajectory.csv")).unwrap();
    assert_eq!(traj.lines().count(), 1 + 61, "a header and one row per node");
    std::fs::remove_dir_all(&dir).ok();
    // A directory that cannot be made (below a file) is refused; a missing one is made.
    let file = std::env::temp_dir().join(format!("gharial-cli-file-{}", std::process::id()));
    std::fs::write(&file, "x").unwrap();
    let below = file.join("sub");
    let o = gharial(&["solve", "lqr", "--figures", below.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot create the directory"), "{}", stderr(&o));
    std::fs::remove_file(&file).ok();
    let fresh = std::env::temp_dir().join(format!("gharial-cli-new-{}/plots", std::process::id()));
    let o = gharial(&["solve", "lqr", "--plot", fresh.to_str().unwrap()]);
    assert!(o.status.success() && fresh.is_dir(), "{}", stderr(&o));
    std::fs::remove_dir_all(fresh.parent().unwrap()).ok();
    let o = gharial(&["solve", "lqr", "--figures", std::env::temp_dir().to_str().unwrap()]);
    assert!(o.status.success() && stdout(&o).contains("no figure data"));
}

#[test]
fn simulate_walks_solo_on_a_slope_given_on_the_command_line() {
    let o = gharial(&[
        "simulate",
        "solo-walk-mpc",
        "--slope",
        "-0.05",
        "--speed",
        "0.1",
        "--duration",
        "0.12",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("cycles    10 (120 plant steps)"), "{text}");
    assert!(text.contains("max friction-cone violation"), "{text}");
    // A payload and a push on the command line reach the plant: the closed loop differs.
    let args = ["simulate", "solo-walk-mpc", "--duration", "0.06", "--output"];
    let dir = std::env::temp_dir();
    let run = |extra: &[&str], file: &str| -> Vec<Vec<f64>> {
        let path = dir.join(format!("gharial-cli-{}-{file}", std::process::id()));
        let mut all: Vec<&str> = args.to_vec();
        all.push(path.to_str().unwrap());
        all.extend_from_slice(extra);
        let o = gharial(&all);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        std::fs::remove_file(&path).ok();
        serde_json::from_value(v["xs"].clone()).unwrap()
    };
    let plain = run(&[], "plain.json");
    let pushed = run(&["--push", "0.03,0,0.25,0"], "push.json");
    let loaded = run(&["--payload", "0.5"], "payload.json");
    let vy = plain[30].len() - 18 + 1;
    assert!((pushed[30][vy] - plain[30][vy] - 0.25).abs() < 1e-12);
    assert!((loaded[50][2] - plain[50][2]).abs() > 1e-4);
}

/// A push the Solo-12's controller cannot absorb stops the loop where the plant diverges
/// (a velocity above `solo_walk::DIVERGED`) or the robot falls: the summary, the stop
/// and the record of the steps done are still given, with exit code 1.
#[test]
fn simulate_reports_a_fall_with_the_record_up_to_it() {
    let path = std::env::temp_dir().join(format!("gharial-cli-{}-fall.json", std::process::id()));
    let args = [
        "simulate",
        "solo-walk-mpc",
        "--duration",
        "0.5",
        "--push",
        "0.02,3,0,0",
        "--output",
    ];
    let mut all = args.to_vec();
    all.push(path.to_str().unwrap());
    let o = gharial(&all);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("diverged") || err.contains("the robot fell"), "{err}");
    assert!(stdout(&o).contains("min base height"), "{}", stdout(&o));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_file(&path).ok();
    let step = v["stopped"]["step"].as_u64().unwrap() as usize;
    assert!(step > 20 && step < 500, "{step}");
    assert_eq!(v["xs"].as_array().unwrap().len(), step + 1);
    assert_eq!(v["us"].as_array().unwrap().len(), step);
    // Standing still commanded: the velocity error is in m/s, not relative to 0.
    let o = gharial(&["simulate", "solo-walk-mpc", "--duration", "0.1", "--speed", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("velocity error (command 0)"), "{}", stdout(&o));
    // The JSON statuses are the machine names of Python's `Results.status`.
    let (_, doc) = run_with_output("status", &["solve", "pendulum", "--max-iters", "2"]);
    assert_eq!(doc["status"], "max_iterations");
}
