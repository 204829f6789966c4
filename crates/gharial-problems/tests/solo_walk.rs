//! The Solo-12 trot in closed loop (`solo-walk-mpc`, `solo-walk-mpc-slope`): the gait
//! schedule, the first OCP, short closed loops on flat ground, up and down the slope (the
//! base stays up, the base follows the command, the stance forces stay in their friction
//! cones), and no allocation per MPC cycle with the plant stepping in between.

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

use gharial::mpc::Record;
use gharial::solvers::proxddp::ProxDdp;
use gharial_problems::mpc::{Metric, MpcScenario, scenario};
use gharial_problems::solo_walk::{COMMAND, DT, Gait, HORIZON, Phase, WalkTask};

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

fn metric(ms: &[Metric], name: &str) -> f64 {
    ms.iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("metric {name}"))
        .value
}

/// `seconds` of closed loop of scenario `name`, with its metrics.
fn closed_loop(name: &str, seconds: f64) -> (MpcScenario, Record, Vec<Metric>) {
    run_closed_loop(name, scenario(name).unwrap(), seconds)
}

/// `seconds` of closed loop of `sc` (reported as `name`), with its metrics.
fn run_closed_loop(name: &str, mut sc: MpcScenario, seconds: f64) -> (MpcScenario, Record, Vec<Metric>) {
    let mut mpc = sc.controller(ProxDdp::new(sc.example.proxddp.clone())).unwrap();
    let rec = sc.run(&mut mpc, seconds).unwrap();
    let ms = sc.metrics(&rec).unwrap();
    for m in &ms {
        eprintln!("{name}: {} = {:.4} {}", m.name, m.value, m.unit);
    }
    (sc, rec, ms)
}

#[test]
fn the_gait_is_a_periodic_trot() {
    let g = Gait::default();
    assert_eq!(g.period(), 40);
    let phases: Vec<Phase> = (0..80).map(|k| g.phase(k)).collect();
    assert_eq!(phases[..2], [Phase::FourFeet; 2]);
    assert!(phases[2..20].iter().all(|&p| p == Phase::FlHr));
    assert_eq!(phases[20..22], [Phase::FourFeet; 2]);
    assert!(phases[22..40].iter().all(|&p| p == Phase::FrHl));
    assert_eq!(phases[..40], phases[40..]);
    // Diagonal pairs: each foot swings once per period, opposite to its diagonal partner.
    for k in 0..40 {
        let s = g.phase(k).stance();
        assert_eq!(s[0], s[3], "node {k}");
        assert_eq!(s[1], s[2], "node {k}");
        assert!(s[0] || s[1], "node {k}: a foot pair is always down");
    }
    // FR and HL land at node 20, FL and HR at node 0 of the next period (node 40).
    assert_eq!(g.touchdowns(20), [false, true, true, false]);
    assert_eq!(g.touchdowns(40), [true, false, false, true]);
    assert_eq!(g.touchdowns(0), [false; 4]);
    assert!((1..20).all(|k| g.touchdowns(k) == [false; 4]));
}

#[test]
fn the_first_ocp_converges_and_starts_walking() {
    let task = WalkTask::new(Gait::default(), COMMAND).unwrap();
    let plan = task.first_plan(300).unwrap();
    eprintln!(
        "first plan: converged {}, {} iterations, prim {:.1e}, dual {:.1e}",
        plan.converged, plan.iterations, plan.prim_err, plan.dual_err
    );
    let (xs, us) = (&plan.xs, &plan.us);
    assert_eq!((xs.len(), us.len()), (HORIZON + 1, HORIZON));
    // The planned base moves forward, not sideways, and stays near its standing height.
    let (dx, dy) = (xs[HORIZON][0] - xs[0][0], xs[HORIZON][1] - xs[0][1]);
    let t = HORIZON as f64 * DT;
    eprintln!("first plan: base displacement ({dx:.4}, {dy:.4}) m over {t} s");
    assert!(dx > 0.3 * COMMAND[0] * t, "dx = {dx}");
    assert!(dy.abs() < 0.2 * dx, "dy = {dy}");
    let h0 = task.standing_height();
    assert!(xs.iter().all(|x| (x[2] / h0 - 1.0).abs() < 0.3));
}

/// Asserts the closed-loop requirements of the module documentation.
fn check_walk(name: &str, rec: &Record, ms: &[Metric], slope: f64) {
    let h0 = metric(ms, "min base height / nominal");
    let h1 = metric(ms, "max base height / nominal");
    assert!(h0 > 0.7 && h1 < 1.3, "{name}: base height ratio in [{h0}, {h1}]");
    // Independently from the record: the base height above the tilted ground.
    let x0 = &rec.xs[0];
    let standing = x0[2];
    for x in &rec.xs {
        let h = x[2] - slope.tan() * x[0];
        assert!((h / standing - 1.0).abs() < 0.3, "{name}: base height {h}");
    }
    let n = rec.xs.len() - 1;
    let v = (rec.xs[n][0] - rec.xs[n / 2][0]) / ((n - n / 2) as f64 * 1e-3);
    assert!((metric(ms, "mean forward velocity (2nd half)") - v).abs() < 1e-9);
    assert!(
        (v - COMMAND[0]).abs() < 0.2 * COMMAND[0],
        "{name}: forward velocity {v}"
    );
    let cone = metric(ms, "max friction-cone violation");
    assert!(cone < 1e-2, "{name}: friction-cone violation {cone} N");
}

#[test]
fn closed_loop_on_flat_ground() {
    let (_, rec, ms) = closed_loop("solo-walk-mpc", 1.5);
    check_walk("solo-walk-mpc", &rec, &ms, 0.0);
}

#[test]
fn closed_loop_on_the_unmodelled_slope() {
    let (_, rec, ms) = closed_loop("solo-walk-mpc-slope", 1.5);
    check_walk("solo-walk-mpc-slope", &rec, &ms, gharial_problems::solo_walk::SLOPE);
}

/// Downhill the swing feet's fly-high cost is measured from the estimated ground (from
/// `z = 0` it grew as `e^{50 · 0.1 x}` with the distance walked, the feet landed ever
/// higher above the ground and were pulled onto it, the forces leaving their cones
/// within 1.5 s).
#[test]
fn closed_loop_downhill() {
    let slope = -gharial_problems::solo_walk::SLOPE;
    let sc = gharial_problems::solo_walk::scenario(slope, COMMAND).unwrap();
    let (_, rec, ms) = run_closed_loop("downhill", sc, 1.5);
    check_walk("downhill", &rec, &ms, slope);
}

/// A closed loop driven cycle by cycle: MPC solve, then the policy on the plant.
struct Drive {
    sc: MpcScenario,
    mpc: gharial::mpc::Mpc<ProxDdp>,
    x: Vec<f64>,
    next: Vec<f64>,
    u: Vec<f64>,
}

impl Drive {
    fn new(threads: usize) -> Self {
        let sc = scenario("solo-walk-mpc").unwrap();
        let opts = sc.example.proxddp.clone().with(|o| o.num_threads = threads);
        let mpc = sc.controller(ProxDdp::new(opts)).unwrap();
        let p = &sc.example.problem;
        let x = p.x0().unwrap().to_vec();
        let u = vec![0.0; p.nu(0)];
        Self {
            next: x.clone(),
            x,
            u,
            sc,
            mpc,
        }
    }

    /// Cycles `cycles`, each followed by its plant steps.
    fn run(&mut self, cycles: std::ops::Range<usize>) {
        let spc = self.sc.steps_per_cycle;
        for c in cycles {
            if c > 0 {
                let id = self.mpc.shift().unwrap();
                (self.sc.on_shift)(c, id, &self.x).unwrap();
            }
            self.mpc.solve(&self.x).unwrap();
            for k in c * spc..(c + 1) * spc {
                self.mpc.control(&self.x, &mut self.u).unwrap();
                self.sc.plant.step(k, &self.x, &self.u, &mut self.next).unwrap();
                self.x.copy_from_slice(&self.next);
            }
        }
    }
}

/// Allocations of `cycles` cycles after two warm-up cycles.
fn cycle_allocations(cycles: usize) -> usize {
    let mut d = Drive::new(1);
    d.run(0..2);
    let count = counting_alloc::local_allocations_during(|| d.run(2..2 + cycles));
    assert!(d.x.iter().all(|v| v.is_finite()));
    count
}

#[test]
fn cycles_with_the_plant_do_not_allocate() {
    assert_eq!(cycle_allocations(60), 0);
}

/// The count the scenario must sustain, 10^4 cycles (minutes in release):
/// `cargo test --release -p gharial-problems --test solo_walk -- --ignored`.
#[test]
#[ignore]
fn ten_thousand_cycles_do_not_allocate() {
    assert_eq!(cycle_allocations(10_000), 0);
}

/// The parallel Riccati (two legs) gives the serial closed loop, contact phases changing
/// along it, to 1e-9 relative.
#[test]
fn the_parallel_riccati_gives_the_serial_closed_loop() {
    let (mut serial, mut parallel) = (Drive::new(1), Drive::new(2));
    serial.run(0..30);
    parallel.run(0..30);
    let scale = serial.x.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    let diff = serial
        .x
        .iter()
        .zip(&parallel.x)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff <= 1e-9 * scale, "{diff:e}");
    let sol = (serial.mpc.solution(), parallel.mpc.solution());
    let du = sol
        .0
        .us
        .iter()
        .flatten()
        .zip(sol.1.us.iter().flatten())
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        du <= 1e-9 * sol.0.us.iter().flatten().fold(1.0_f64, |m, v| m.max(v.abs())),
        "{du:e}"
    );
}

#[test]
fn bad_input_is_an_error() {
    use gharial_problems::solo_walk::scenario as walk;
    for slope in [f64::NAN, 0.6, -1.0] {
        let e = walk(slope, COMMAND).unwrap_err().to_string();
        assert!(e.contains("slope"), "{e}");
    }
    let e = walk(0.0, [f64::INFINITY, 0.0]).unwrap_err().to_string();
    assert!(e.contains("command"), "{e}");
    let no_swing = Gait {
        double_support: 4,
        single_support: 0,
    };
    let e = WalkTask::new(no_swing, COMMAND).unwrap_err().to_string();
    assert!(e.contains("Gait"), "{e}");
    let task = WalkTask::new(Gait::default(), COMMAND).unwrap();
    let e = task.set_stage_target(40, 0.0).unwrap_err().to_string();
    assert!(e.contains("stage object 40"), "{e}");
    assert!(task.set_stage_target(39, 0.5).is_ok());
}

/// A push changes the base's linear velocity in the record by exactly the push at its
/// step and leaves the states before it unchanged; a payload changes the plant's motion;
/// the UR5 has no floating base to push.
#[test]
fn pushes_and_payloads_reach_the_plant() {
    use gharial_problems::mpc::{Mismatch, ScenarioSettings, scenario_with};
    let settings = |payload: f64| {
        let mut s = ScenarioSettings::default();
        s.mismatch = Mismatch::payload(payload);
        s
    };
    let run = |payload: f64, push: Option<[f64; 3]>| {
        let mut sc = scenario_with("solo-walk-mpc", &settings(payload)).unwrap();
        if let Some(dv) = push {
            sc.push_base(0.03, dv).unwrap();
        }
        let mut mpc = sc.controller(ProxDdp::new(sc.example.proxddp.clone())).unwrap();
        sc.run(&mut mpc, 0.05).unwrap()
    };
    let plain = run(0.0, None);
    let dv = [0.05, -0.3, 0.02];
    let pushed = run(0.0, Some(dv));
    let k = 30;
    assert_eq!(plain.xs[..k], pushed.xs[..k]);
    let nv = (plain.xs[k].len() - 1) / 2;
    let base_v = plain.xs[k].len() - nv;
    for i in 0..3 {
        let jump = pushed.xs[k][base_v + i] - plain.xs[k][base_v + i];
        assert!((jump - dv[i]).abs() < 1e-12, "{i}: {jump}");
    }
    let loaded = run(0.5, None);
    assert_eq!(plain.xs[0], loaded.xs[0]);
    let dz = (loaded.xs[50][2] - plain.xs[50][2]).abs();
    assert!(dz > 1e-4, "a 0.5 kg payload moved the base by {dz} m in 50 ms");
    let mut ur5 = scenario_with("ur5-circle-mpc", &settings(1.0)).unwrap();
    let e = ur5.push_base(0.1, dv).unwrap_err().to_string();
    assert!(e.contains("no floating base"), "{e}");
}
