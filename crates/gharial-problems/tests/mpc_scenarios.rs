//! The receding-horizon scenarios: cycles of `ur5-circle-mpc` allocate nothing after the
//! controller is built, the parallel Riccati gives the serial cycles, and the closed
//! loop tracks the circle (and keeps the joint bound) on the plant at 1 ms.

#[path = "../../gharial/tests/support/counting_alloc.rs"]
mod counting_alloc;

use gharial::mpc::Mpc;
use gharial::solvers::Solver;
use gharial::solvers::proxddp::ProxDdp;
use gharial_problems::mpc::{MpcScenario, scenario};

#[global_allocator]
static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;

/// The measured state and the policy's control of a run of cycles.
struct Loop {
    x: Vec<f64>,
    u: Vec<f64>,
    cycle: usize,
}

impl Loop {
    fn new(sc: &MpcScenario) -> Self {
        let p = &sc.example.problem;
        Self {
            x: p.x0().unwrap().to_vec(),
            u: vec![0.0; p.nu(0)],
            cycle: 0,
        }
    }
}

/// `cycles` cycles on the controller's own model (the plan's next state is the next
/// measurement), with the scenario's reference updates; returns the first control and
/// state of every plan if `keep`.
fn cycles<S: Solver>(
    sc: &mut MpcScenario,
    mpc: &mut Mpc<S>,
    lp: &mut Loop,
    cycles: usize,
    keep: bool,
) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(if keep { 2 * cycles } else { 0 });
    let Loop { x, u, cycle } = lp;
    for _ in 0..cycles {
        let c = *cycle;
        *cycle += 1;
        let sol = mpc.solve(x).unwrap();
        assert!(sol.xs[1].iter().all(|v| v.is_finite()), "cycle {c}");
        if keep {
            out.push(sol.us[0].clone());
            out.push(sol.xs[1].clone());
        }
        x.copy_from_slice(&sol.xs[1]);
        let id = mpc.shift().unwrap();
        (sc.on_shift)(c + 1, id, x).unwrap();
        mpc.control(x, u).unwrap();
    }
    out
}

/// Asserts that `n` cycles of each circle scenario allocate nothing.
fn assert_cycles_do_not_allocate(n: usize) {
    for name in [
        "ur5-circle-mpc",
        "ur5-circle-mpc-joint-bound",
        "ur5-circle-mpc-half-space",
    ] {
        let mut sc = scenario(name).unwrap();
        let mut mpc = sc.controller(ProxDdp::new(sc.example.proxddp.clone())).unwrap();
        let mut lp = Loop::new(&sc);
        cycles(&mut sc, &mut mpc, &mut lp, 2, false);
        let count = counting_alloc::local_allocations_during(|| {
            cycles(&mut sc, &mut mpc, &mut lp, n, false);
        });
        assert_eq!(count, 0, "{name}");
    }
}

#[test]
fn circle_mpc_cycles_do_not_allocate() {
    assert_cycles_do_not_allocate(300);
}

/// The scenario's full count, 10^5 cycles of each variant (2.1 min in release on two cores):
/// `cargo test --release -p gharial-problems --test mpc_scenarios -- --ignored`.
#[test]
#[ignore]
fn circle_mpc_1e5_cycles_do_not_allocate() {
    assert_cycles_do_not_allocate(100_000);
}

#[test]
fn circle_mpc_parallel_riccati_gives_the_serial_cycles() {
    let run = |threads: usize| {
        let mut sc = scenario("ur5-circle-mpc-joint-bound").unwrap();
        let opts = sc.example.proxddp.clone().with(|o| o.num_threads = threads);
        let mut mpc = sc.controller(ProxDdp::new(opts)).unwrap();
        let mut lp = Loop::new(&sc);
        cycles(&mut sc, &mut mpc, &mut lp, 60, true)
    };
    let (serial, parallel) = (run(1), run(2));
    let scale = serial.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    let diff = serial
        .iter()
        .flatten()
        .zip(parallel.iter().flatten())
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff <= 1e-9 * scale, "{diff:e} (scale {scale:e})");
}

#[test]
fn circle_mpc_closed_loop_tracks_the_circle() {
    let metric = |sc: &MpcScenario, rec, name: &str| {
        sc.metrics(rec)
            .unwrap()
            .into_iter()
            .find(|m| m.name == name)
            .unwrap()
            .value
    };
    // One turn of the circle (π s at 2 rad/s) on the plant at 1 ms.
    let mut free = scenario("ur5-circle-mpc").unwrap();
    let mut mpc = free.controller(ProxDdp::new(free.example.proxddp.clone())).unwrap();
    let rec = free.run(&mut mpc, std::f64::consts::PI).unwrap();
    assert_eq!(rec.cycles.len(), 63);
    let mean = metric(&free, &rec, "mean tool error");
    assert!(mean < 0.03, "{mean}");
    assert!(
        metric(&free, &rec, "max |q_1|") > 0.3,
        "the unconstrained arm swings its base"
    );
    let mut bound = scenario("ur5-circle-mpc-joint-bound").unwrap();
    let mut mpc = bound.controller(ProxDdp::new(bound.example.proxddp.clone())).unwrap();
    let rec = bound.run(&mut mpc, std::f64::consts::PI).unwrap();
    let q1 = metric(&bound, &rec, "max |q_1|");
    assert!(q1 < 0.05 + 0.01, "{q1}");
    assert!(metric(&bound, &rec, "mean tool error") > 2.0 * mean);
}
