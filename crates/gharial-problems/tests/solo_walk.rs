//! The Solo-12 trot in closed loop (`solo-walk-mpc`, `solo-walk-mpc-slope`): the gait
//! schedule, the first OCP, short closed loops on flat and sloped ground (the base stays
//! up, the base follows the command, the stance forces stay in their friction cones), and
//! no allocation per MPC cycle with the plant stepping in between.

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
    let mut sc = scenario(name).unwrap();
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

#[test]
fn cycles_with_the_plant_do_not_allocate() {
    let mut sc = scenario("solo-walk-mpc").unwrap();
    let mut mpc = sc.controller(ProxDdp::new(sc.example.proxddp.clone())).unwrap();
    let p = &sc.example.problem;
    let mut x = p.x0().unwrap().to_vec();
    let mut next = x.clone();
    let mut u = vec![0.0; p.nu(0)];
    let spc = sc.steps_per_cycle;
    let mut run = |sc: &mut MpcScenario, cycles: std::ops::Range<usize>| {
        for c in cycles {
            if c > 0 {
                let id = mpc.shift().unwrap();
                (sc.on_shift)(c, id).unwrap();
            }
            mpc.solve(&x).unwrap();
            for k in c * spc..(c + 1) * spc {
                mpc.control(&x, &mut u).unwrap();
                sc.plant.step(k, &x, &u, &mut next).unwrap();
                x.copy_from_slice(&next);
            }
        }
    };
    run(&mut sc, 0..2);
    let count = counting_alloc::local_allocations_during(|| run(&mut sc, 2..62));
    assert_eq!(count, 0);
    assert!(x.iter().all(|v| v.is_finite()));
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
