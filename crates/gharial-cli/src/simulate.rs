//! `gharial simulate`: a receding-horizon scenario in closed loop, with the distribution
//! of its cycle times, its iterations and statuses, its metrics, and optional JSON output.

use std::collections::BTreeMap;
use std::time::Duration;

use gharial::mpc::Record;
use gharial_problems::mpc::{Metric, Mismatch, MpcScenario, ScenarioSettings};
use serde_json::json;

use crate::solver_choice::SolverArgs;

/// The arguments of `gharial simulate`.
#[derive(clap::Args, Debug, Clone)]
pub struct SimulateArgs {
    /// Scenario name (see `gharial list`).
    pub scenario: String,
    /// Simulated time in seconds (at most 5000: the record keeps every plant state).
    #[arg(long, default_value_t = std::f64::consts::PI, value_parser = real)]
    pub duration: f64,
    /// Solo-12 walking only: tilt of the (unmodelled) ground about y, in radians (at most
    /// 0.3; `solo-walk-mpc --slope 0.1` is `solo-walk-mpc-slope`).
    #[arg(long, value_parser = real, allow_negative_numbers = true)]
    pub slope: Option<f64>,
    /// Solo-12 walking only: the forward base velocity command in m/s (at most 1).
    #[arg(long, value_parser = real, allow_negative_numbers = true)]
    pub speed: Option<f64>,
    /// Mass in kg of a payload the plant carries and the controller does not model: on the
    /// Solo-12's base at its centre of mass, at the UR5's tool frame (at most 100).
    #[arg(long, value_parser = real, allow_negative_numbers = true)]
    pub payload: Option<f64>,
    /// Floating-base robots only: a push at time T (s) changing the base's linear
    /// velocity by (VX, VY, VZ) m/s in the base frame (each at most 10 in magnitude), as
    /// `T,VX,VY,VZ` (repeatable).
    #[arg(long, value_parser = push, allow_negative_numbers = true)]
    pub push: Vec<(f64, [f64; 3])>,
    /// Wall-time budget of each MPC cycle in milliseconds (default: none; the iteration
    /// budget is `--max-iters`, default the scenario's).
    #[arg(long, value_parser = real, allow_negative_numbers = true)]
    pub cycle_budget: Option<f64>,
    /// Write the closed loop (states, controls, cycles, metrics) to this JSON file.
    #[arg(long)]
    pub output: Option<String>,
    // The solver and its options (last: their help headings follow).
    #[command(flatten)]
    pub solver: SolverArgs,
}

/// A finite number of either sign (the scenario checks its range).
fn real(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(format!("must be a finite number, got {v}")),
        Err(e) => Err(e.to_string()),
    }
}

/// A push `T,VX,VY,VZ`: four finite numbers (the scenario checks their ranges).
fn push(s: &str) -> Result<(f64, [f64; 3]), String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [t, vx, vy, vz] = parts[..] else {
        return Err(format!("expected T,VX,VY,VZ (four numbers), got `{s}`"));
    };
    Ok((real(t)?, [real(vx)?, real(vy)?, real(vz)?]))
}

/// The scenario of the command line: by name, with the walking parameters, the model
/// mismatch and the pushes if given.
fn build_scenario(args: &SimulateArgs) -> gharial::Result<MpcScenario> {
    let mut settings = ScenarioSettings::default();
    settings.slope = args.slope;
    settings.speed = args.speed;
    settings.mismatch = Mismatch::payload(args.payload.unwrap_or(0.0));
    let mut sc = gharial_problems::mpc::scenario_with(&args.scenario, &settings)?;
    sc.check_duration(args.duration)?;
    for &(t, dv) in &args.push {
        sc.push_base(t, dv)?;
    }
    Ok(sc)
}

/// Runs `gharial simulate`; returns the process exit code (0: every cycle returned a
/// finite plan, 1: the loop stopped on an error (the summary and the record cover the
/// steps done), 2: invalid input).
pub fn run(args: &SimulateArgs) -> i32 {
    if let Err(e) = args.solver.check() {
        eprintln!("gharial simulate: {e}");
        return 2;
    }
    let mut sc = match build_scenario(args) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("gharial simulate: {e}");
            return 2;
        }
    };
    let mut output = match crate::Output::create("simulate", args.output.as_deref()) {
        Ok(o) => o,
        Err(code) => return code,
    };
    if let Some(n) = args.solver.common.max_iters {
        sc.options.max_iters = n;
    }
    if let Some(ms) = args.cycle_budget {
        sc.options.max_time = match gharial_problems::mpc::cycle_budget_ms(ms) {
            Ok(t) => t,
            Err(e) => {
                eprintln!("gharial simulate: {e}");
                return 2;
            }
        };
    }
    let config = args.solver.config(&sc.example);
    let mut mpc = match sc.controller(config.options.build()) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("gharial simulate: {e}");
            return 2;
        }
    };
    out!(
        "scenario  {}: horizon {} x {} ms, plant step {} ms, MPC every {} ms, at most {} {} iterations per cycle",
        sc.name,
        sc.example.problem.horizon(),
        sc.example.dt.unwrap_or(0.0) * 1e3,
        sc.plant_dt * 1e3,
        sc.plant_dt * sc.steps_per_cycle as f64 * 1e3,
        sc.options.max_iters,
        config.kind.name()
    );
    let rec = match sc.run(&mut mpc, args.duration) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("gharial simulate: {e}");
            return 1;
        }
    };
    // A loop that diverged may hold states where a metric cannot be evaluated: the
    // record is still printed and written.
    let (metrics, metrics_ok) = match sc.metrics(&rec) {
        Ok(m) => (m, true),
        Err(e) => {
            eprintln!("gharial simulate: metrics: {e}");
            (Vec::new(), false)
        }
    };
    print_summary(&rec, &metrics);
    if let Some(s) = &rec.stopped {
        eprintln!(
            "gharial simulate: the closed loop stopped at plant step {} (t = {:.3} s): {}",
            s.step,
            s.step as f64 * sc.plant_dt,
            s.reason
        );
    }
    let written = output
        .as_mut()
        .is_none_or(|o| o.write_json("simulate", "record", &record_json(&sc, &rec, &metrics)));
    if written && metrics_ok && rec.stopped.is_none() {
        0
    } else {
        1
    }
}

/// The `q`-quantile of sorted durations, in milliseconds.
fn quantile_ms(sorted: &[Duration], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i].as_secs_f64() * 1e3
}

fn print_summary(rec: &Record, metrics: &[Metric]) {
    let times = rec.sorted_solve_times();
    let iters: Vec<usize> = rec.cycles.iter().map(|c| c.iterations).collect();
    let total: usize = iters.iter().sum();
    let mut statuses: BTreeMap<String, usize> = BTreeMap::new();
    for c in &rec.cycles {
        *statuses.entry(c.status.to_string()).or_default() += 1;
    }
    out!(
        "cycles    {} ({} plant steps), iterations {} (mean {:.2}, max {})",
        rec.cycles.len(),
        rec.us.len(),
        total,
        total as f64 / rec.cycles.len().max(1) as f64,
        iters.iter().max().copied().unwrap_or(0)
    );
    let s: Vec<String> = statuses.iter().map(|(k, v)| format!("{k} {v}")).collect();
    out!("statuses  {}", s.join(", "));
    out!(
        "cycle time (ms)  median {:.3}, p99 {:.3}, max {:.3}, min {:.3}",
        quantile_ms(&times, 0.5),
        quantile_ms(&times, 0.99),
        quantile_ms(&times, 1.0),
        quantile_ms(&times, 0.0)
    );
    for m in metrics {
        out!("{:<16} {:.6} {}", m.name, m.value, m.unit);
    }
}

fn record_json(sc: &MpcScenario, rec: &Record, metrics: &[Metric]) -> serde_json::Value {
    let cycles: Vec<_> = rec
        .cycles
        .iter()
        .map(|c| {
            json!({
                "step": c.step,
                "time": c.step as f64 * sc.plant_dt,
                "solve_time_ms": c.solve_time.as_secs_f64() * 1e3,
                "iterations": c.iterations,
                "status": c.status.name(),
                "cost": c.cost,
                "prim_err": c.prim_err,
                "dual_err": c.dual_err,
            })
        })
        .collect();
    let metrics: serde_json::Map<String, serde_json::Value> = metrics
        .iter()
        .map(|m| (m.name.to_string(), json!({"value": m.value, "unit": m.unit})))
        .collect();
    json!({
        "scenario": sc.name,
        "plant_dt": sc.plant_dt,
        "steps_per_cycle": sc.steps_per_cycle,
        "xs": rec.xs,
        "us": rec.us,
        "cycles": cycles,
        "metrics": metrics,
        "stopped": rec.stopped.as_ref().map(|s| json!({
            "step": s.step,
            "time": s.step as f64 * sc.plant_dt,
            "reason": s.reason,
        })),
    })
}
