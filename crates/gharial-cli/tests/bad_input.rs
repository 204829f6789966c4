//! Random command lines: every invocation ends with exit code 0 (converged), 1 (another
//! status) or 2 (invalid input, with a message and nothing run), never with a panic, and
//! within a time limit.

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use proptest::prelude::*;

/// Invocations per run (each starts the binary once).
const CASES: u32 = 150;

fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e-300".to_string()),
        Just("1e300".to_string()),
        Just("abc".to_string()),
        Just(String::new()),
        Just("exact".to_string()),
        Just("gauss-newton".to_string()),
        Just(usize::MAX.to_string()),
        Just("18446744073709551616".to_string()),
        (1usize..20).prop_map(|v| v.to_string()),
        (1e-9..10.0f64).prop_map(|v| format!("{v:e}")),
    ]
}

fn solve_args() -> impl Strategy<Value = Vec<String>> {
    let problem = prop_oneof![
        Just("lqr"),
        Just("lqr-bounds-term"),
        Just("clqr"),
        Just("se2-car"),
        Just("peers-lqr-box"),
        Just("block-move"),
        Just("no-such-problem"),
    ];
    let option = prop_oneof![
        Just("--tol"),
        Just("--mu-init"),
        Just("--dyn-al-scale"),
        Just("--max-iters"),
        Just("--threads"),
        Just("--active-set-iters"),
        Just("--rollout"),
        Just("--step-acceptance"),
        Just("--merit"),
        Just("--hessian"),
        Just("--penalty-initial"),
        Just("--penalty-scaling"),
        Just("--eps-abs"),
        Just("--max-qp-iters"),
        Just("--penalty-factor"),
        Just("--schedule"),
    ];
    // Every solver, and names that are none.
    let solver = proptest::option::of(prop_oneof![
        Just("proxddp"),
        Just("ddp"),
        Just("fddp"),
        Just("box-ddp"),
        Just("box-fddp"),
        Just("sqp"),
        Just("csqp"),
        Just("bcl-ddp"),
        Just("altro"),
        Just("proxnlp"),
        Just("FDDP"),
        Just("box"),
        Just(""),
    ]);
    (problem, solver, proptest::collection::vec((option, value()), 0..4)).prop_map(|(p, solver, opts)| {
        let mut args = vec!["solve".to_string(), p.to_string()];
        if let Some(s) = solver {
            args.push(format!("--solver={s}"));
        }
        for (o, v) in opts {
            args.push(format!("{o}={v}"));
        }
        args
    })
}

fn riccati_args() -> impl Strategy<Value = Vec<String>> {
    let option = prop_oneof![
        Just("--threads"),
        Just("--horizons"),
        Just("--dims"),
        Just("--extra"),
        Just("--mu"),
        Just("--rounds"),
        Just("--refine"),
    ];
    let dims = prop_oneof![
        Just("2:1:1".to_string()),
        Just("0:1:1".to_string()),
        Just("2:1".to_string()),
        value()
    ];
    (proptest::collection::vec((option, value()), 0..3), dims).prop_map(|(opts, d)| {
        // Small cases and a tiny budget keep every run short.
        let mut args: Vec<String> = ["bench", "riccati", "--budget=0.001", "--horizons=2", "--extra="]
            .iter()
            .map(|s| s.to_string())
            .collect();
        args.push(format!("--dims={d}"));
        for (o, v) in opts {
            let v = if o == "--horizons" && v.parse::<usize>().is_ok_and(|n| n > 64) {
                "8".to_string()
            } else {
                v
            };
            let v = if o == "--dims" || o == "--extra" {
                format!("{v}:1:1")
            } else {
                v
            };
            args.push(format!("{o}={v}"));
        }
        args
    })
}

/// The longest an invocation may take: far beyond any run that stops (a second at
/// most), so that only one that never stops reaches it.
const TIME_LIMIT: Duration = Duration::from_secs(120);

/// Reads a pipe to its end on another thread (so that a long output cannot block the
/// child while it is waited for).
fn drain(mut r: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut s = String::new();
        let _ = r.read_to_string(&mut s);
        s
    })
}

/// Runs the binary with `args`; its exit code, standard output and standard error, or
/// `None` (the process killed) if it has not finished within `limit`.
fn run_with_limit(args: &[String], limit: Duration) -> Option<(Option<i32>, String, String)> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gharial"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let out = drain(child.stdout.take().expect("piped"));
    let err = drain(child.stderr.take().expect("piped"));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for the binary") {
            break Some(status);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let (out, err) = (out.join().expect("stdout reader"), err.join().expect("stderr reader"));
    status.map(|s| (s.code(), out, err))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn random_command_lines_end_with_a_documented_exit_code(args in prop_oneof![solve_args(), riccati_args()]) {
        let o = run_with_limit(&args, TIME_LIMIT);
        prop_assert!(o.is_some(), "{args:?}: still running after {TIME_LIMIT:?}");
        let (code, out, err) = o.unwrap();
        prop_assert!(!err.contains("panicked"), "{args:?}: {err}");
        match code {
            Some(0) => prop_assert!(args[0] != "solve" || out.contains("status    converged"), "{args:?}: {out}"),
            Some(1) => prop_assert!(out.contains("status "), "{args:?}: {out}"),
            Some(2) => {
                prop_assert!(!err.trim().is_empty(), "{args:?}: exit 2 without a message");
                prop_assert!(!out.contains("status "), "{args:?}: exit 2 after a solve");
            }
            other => prop_assert!(false, "{args:?}: exit code {other:?}: {err}"),
        }
    }
}
