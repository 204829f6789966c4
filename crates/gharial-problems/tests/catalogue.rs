//! The catalogue API: every name builds a consistent example; unknown names are errors
//! that list the valid ones.

use std::collections::HashSet;

#[test]
fn every_catalogue_entry_builds_a_consistent_example() {
    let names: HashSet<_> = gharial_problems::catalogue().iter().map(|p| p.name).collect();
    assert_eq!(names.len(), gharial_problems::catalogue().len(), "names are unique");
    for info in gharial_problems::catalogue() {
        let ex = gharial_problems::build(info.name).unwrap();
        assert_eq!(ex.name, info.name);
        assert!(!info.summary.is_empty() && !ex.description.is_empty());
        let p = &ex.problem;
        p.check_trajectory(&ex.xs0, &ex.us0).unwrap();
        ex.proxddp.validate().unwrap();
        assert!(ex.dt.is_none_or(|dt| dt > 0.0));
        // The guess starts at x0 and, except where documented (clqr, the swing-ups and the
        // Solo-12 jump with an infeasible state guess), is the rollout of us0.
        assert_eq!(p.x0().unwrap(), ex.xs0[0].as_slice(), "{}", info.name);
        // ur10-ballistic: the flight nodes hold the released mug at rest (cold start);
        // solo-com-circle: x0 at every node (the rollout of u_qs leaves the unstable
        // standing equilibrium); car-escape and quadrotor-maze: states through six or seven
        // poses (ALTRO's infeasible start).
        let not_rollouts = [
            "clqr",
            "pendulum",
            "cartpole",
            "solo-jump",
            "ur10-ballistic",
            "solo-com-circle",
            "car-escape",
            "quadrotor-maze",
        ];
        if !not_rollouts.contains(&info.name) {
            let xs = gharial_problems::rollout(p, &ex.us0).unwrap();
            assert_eq!(xs, ex.xs0, "{}", info.name);
        }
    }
}

#[test]
fn horizons_and_steps_are_as_documented() {
    for (name, n, dt) in [
        ("lqr", 20, None),
        ("clqr", 100, None),
        ("pendulum", 200, Some(0.01)),
        ("cartpole", 500, Some(0.01)),
        ("acrobot", 200, Some(0.005)),
        ("se2-car", 40, Some(0.05)),
        ("quadrotor", 60, Some(0.033)),
        ("peers-lqr", 100, None),
        ("solo-com-circle", 250, Some(0.02)),
        ("block-move", 20, Some(0.1)),
        ("car-parallel-park", 100, Some(0.03)),
        ("car-3-obstacles", 100, Some(0.05)),
        ("car-escape", 100, Some(0.03)),
        ("arm-obstacles", 80, Some(0.025)),
        ("car-parallel-park-min-time", 100, Some(0.03)),
        ("altro-pendulum", 30, Some(0.15)),
        ("altro-pendulum-min-time", 30, Some(0.15)),
        ("altro-acrobot", 100, Some(0.05)),
        ("altro-cartpole", 100, Some(0.05)),
        ("quadrotor-line", 100, Some(0.05)),
        ("quadrotor-maze", 100, Some(0.05)),
        ("ecddp-cartpole", 200, Some(0.01)),
        ("ecddp-ur5", 200, Some(0.01)),
    ] {
        let ex = gharial_problems::build(name).unwrap();
        assert_eq!(ex.problem.horizon(), n, "{name}");
        assert_eq!(ex.dt, dt, "{name}");
    }
}

#[test]
fn unknown_names_are_errors_listing_the_valid_ones() {
    let err = gharial_problems::build("pendulm").unwrap_err().to_string();
    assert!(err.contains("unknown problem `pendulm`"), "{err}");
    for info in gharial_problems::catalogue() {
        assert!(err.contains(info.name), "{err}");
    }
}
