//! Per-instance iteration counts behind `gharial bench profile` (the stagewise-SQP
//! paper's Fig. 1): for each instance of a family, the initial state, the cost of the
//! warm start, and the iterations FDDP and SQP take to the profile's KKT test
//! `max(|gaps|_∞, |Q_u|_∞) ≤ tol` (`-` if not within the budget), and SQP's iterations to
//! its own test, the KKT residual (20) (the test of mim_solvers' `termination_tolerance`).
//! The numbers the Python reproduction `bench/peers/fig1.py` compares
//! with (its `--gharial FILE` reads this output); `--x0` prints the initial states, which
//! that script regenerates from the same random stream.
//!
//! ```text
//! cargo run --release -p gharial-problems --example profile_instances -- \
//!     [FAMILY] [COUNT] [--budget B] [--tol T] [--filter-size F] [--x0] [--log I]
//! ```
//! Defaults: `quadrotor`, 20 instances, budget 100, tol `1e-4`, filter size the
//! iteration limit (the paper's; `--filter-size 1` is mim_solvers' default). `--log I`
//! prints FDDP's and SQP's iteration tables on instance `I`.

use gharial::solvers::ddp::{DdpOptions, DdpVariant};
use gharial::solvers::log::LogSink;
use gharial::solvers::{Callback, InitialGuess, Solver, SolverOptions};
use gharial_problems::Example;
use gharial_problems::profiles;

/// The command-line options.
struct Args {
    family: String,
    count: usize,
    budget: usize,
    tol: f64,
    filter_size: Option<usize>,
    x0: bool,
    log: Option<usize>,
}

fn parse() -> Args {
    let mut a = Args {
        family: "quadrotor".into(),
        count: 20,
        budget: 100,
        tol: 1e-4,
        filter_size: None,
        x0: false,
        log: None,
    };
    let mut positional = 0;
    let mut it = std::env::args().skip(1);
    while let Some(s) = it.next() {
        let mut value = |name: &str| it.next().unwrap_or_else(|| panic!("{name} needs a value"));
        match s.as_str() {
            "--budget" => a.budget = value("--budget").parse().expect("--budget"),
            "--tol" => a.tol = value("--tol").parse().expect("--tol"),
            "--filter-size" => a.filter_size = Some(value("--filter-size").parse().expect("--filter-size")),
            "--log" => a.log = Some(value("--log").parse().expect("--log")),
            "--x0" => a.x0 = true,
            _ if positional == 0 => {
                a.family = s;
                positional += 1;
            }
            _ => a.count = s.parse().expect("COUNT"),
        }
    }
    a
}

/// The options of `variant` as the profile sets them; `own`: SQP's own KKT test at
/// `tol` instead of the callback's.
fn options(variant: DdpVariant, args: &Args, own: bool, log: bool) -> DdpOptions {
    let max_iters = args.budget + 1;
    DdpOptions::new(variant).with(|o| {
        o.tol = args.tol;
        o.max_iters = max_iters;
        o.filter_size = args.filter_size.unwrap_or(max_iters).min(1000);
        if !own {
            o.th_stop = Some(f64::MIN_POSITIVE);
        }
        if log {
            o.log = LogSink::Stderr;
        }
    })
}

/// Iterations to the profile's test (`own`: to the solver's own convergence).
fn iterations(ex: &Example, opts: DdpOptions, own: bool) -> Option<usize> {
    let mut watch = profiles::FirstKkt::new(opts.tol);
    let mut s = SolverOptions::Ddp(opts).build();
    s.setup(&ex.problem).expect("setup");
    let callback: Option<&mut dyn Callback> = if own { None } else { Some(&mut watch) };
    let sol = s
        .solve_with(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0), callback)
        .expect("solve");
    if own {
        sol.status.converged().then_some(sol.iterations)
    } else {
        watch.solved_at(sol)
    }
}

fn main() {
    let args = parse();
    let instances = profiles::family(&args.family, 1, args.count).expect("family");
    if args.x0 {
        println!("X0 = [");
        for ex in &instances {
            let x: Vec<String> = ex.xs0[0].iter().map(|v| format!("{v:?}")).collect();
            println!("    [{}],", x.join(", "));
        }
        println!("]");
    }
    let show = |i: Option<usize>| i.map_or("-".to_string(), |i| i.to_string());
    println!("instance,initial_cost,fddp,sqp,sqp_own");
    for (i, ex) in instances.iter().enumerate() {
        let mut data = gharial::problem::ProblemData::new(&ex.problem, 1).expect("data");
        let cost = data.evaluate(&ex.problem, &ex.xs0, &ex.us0);
        let log = args.log == Some(i);
        let fddp = iterations(ex, options(DdpVariant::Fddp, &args, false, log), false);
        let sqp = iterations(ex, options(DdpVariant::Sqp, &args, false, false), false);
        let own = iterations(ex, options(DdpVariant::Sqp, &args, true, log), true);
        println!("{i},{cost:.17e},{},{},{}", show(fddp), show(sqp), show(own));
    }
}
