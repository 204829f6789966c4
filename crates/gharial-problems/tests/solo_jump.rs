//! The Solo-12 jump (ProxDDP paper §VII-D): ProxDDP converges; the solution takes off,
//! flies and lands on the constrained feet heights with positive ground forces; the
//! figure data have their columns, and their contact forces satisfy the multibody
//! dynamics recomputed independently; the variants and bad parameters.

use faer::Mat;
use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solution, Solver, Status};
use gharial_multibody::{
    ContactData, ContactModel, ContactType, ReferenceFrame, compute_joint_jacobians, constraint_dynamics,
    frame_jacobian, rnea,
};
use gharial_problems::solo_jump::{FEET, JumpParams, JumpSetup, Phase, proxddp_options};

/// The optimal cost of the default jump by ALIGATOR 0.19.1's ProxDDP on the same problem
/// (same model, costs, guess and settings, built with its own API) at tol 1e-8.
const ALIGATOR_COST: f64 = 0.290_180_395_36;

fn solve(params: &JumpParams) -> (JumpSetup, Solution) {
    let setup = JumpSetup::new(params).unwrap();
    let (xs, us) = setup.initial_guess();
    let mut solver = ProxDdp::new(proxddp_options());
    solver.setup(&setup.problem).unwrap();
    let sol = solver.solve(&setup.problem, InitialGuess::primal(&xs, &us)).unwrap();
    (setup, sol.clone())
}

/// A CSV text as its header and rows of optional numbers (empty fields are `None`).
fn parse_csv(text: &str) -> (Vec<String>, Vec<Vec<Option<f64>>>) {
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|f| (!f.is_empty()).then(|| f.parse::<f64>().unwrap()))
                .collect()
        })
        .collect();
    (header, rows)
}

fn column(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name}"))
}

#[test]
fn the_paper_jump_converges_to_the_peer_optimum() {
    let (setup, sol) = solve(&JumpParams::default());
    let tol = proxddp_options().tol;
    eprintln!(
        "solo-jump: {:?} in {} iterations ({} AL), prim {:.1e}, dual {:.1e}, cost {:.12}",
        sol.status, sol.iterations, sol.al_iterations, sol.prim_err, sol.dual_err, sol.cost
    );
    assert_eq!(sol.status, Status::Converged);
    assert!(sol.iterations <= 80, "{} iterations (57 measured)", sol.iterations);
    assert!(sol.prim_err <= tol && sol.dual_err <= tol);
    assert!((sol.cost - ALIGATOR_COST).abs() < 1e-8, "cost {}", sol.cost);
    assert_eq!(setup.problem.horizon(), 60);
}

#[test]
fn the_solution_jumps_and_lands() {
    let params = JumpParams::default();
    let (setup, sol) = solve(&params);
    let standing = setup.standing_height();
    let mut apex = f64::MIN;
    for (t, x) in sol.xs.iter().enumerate() {
        let z = setup.feet_heights(x).unwrap();
        match params.phase(t) {
            // The contact velocity is damped in one step: the feet stay on the ground.
            Phase::Stance | Phase::Landing => assert!(z.iter().all(|z| z.abs() < 1e-3), "node {t}: {z:?}"),
            // Lift-off at node 20 already (the velocity of the push).
            Phase::Flight => {
                assert!(z.iter().all(|&z| z > 2e-3), "node {t}: feet {z:?}");
                apex = apex.max(x[2]);
            }
        }
    }
    let landing = setup.feet_heights(&sol.xs[params.landing]).unwrap();
    assert!(landing.iter().all(|z| z.abs() <= 1e-6), "{landing:?}");
    assert!(apex > standing + 0.2, "apex {apex}, standing {standing}");
    // Ground forces push (the contacts are bilateral: nothing but the optimum makes them so).
    let dynamics = setup.contact_dynamics();
    let mut d = dynamics.create_contact_data();
    for t in (0..params.horizon).filter(|&t| params.phase(t).in_contact()) {
        let lambda = dynamics.contact_forces(&sol.xs[t], &sol.us[t], &mut d).unwrap();
        for k in 0..FEET.len() {
            assert!(
                lambda[3 * k + 2] > 1.0,
                "stage {t} {}: {:?}",
                FEET[k],
                &lambda[3 * k..3 * k + 3]
            );
        }
    }
}

#[test]
fn the_figures_have_their_columns_and_the_forces_of_the_dynamics() {
    let params = JumpParams::default();
    let (setup, sol) = solve(&params);
    let fig = setup.figures(&sol).unwrap();

    let (header, rows) = parse_csv(&fig.convergence);
    assert_eq!(
        header,
        ["iter", "prim_err", "dual_err", "mu", "al_iter", "alpha", "cost"]
    );
    assert_eq!(rows.len(), sol.history.len());
    for (row, rec) in rows.iter().zip(&sol.history) {
        let r: Vec<f64> = row.iter().map(|v| v.unwrap()).collect();
        assert_eq!(
            r,
            [
                rec.iter as f64,
                rec.prim_err,
                rec.dual_err,
                rec.mu,
                rec.al_iter as f64,
                rec.alpha,
                rec.cost
            ]
        );
    }

    let (header, rows) = parse_csv(&fig.trajectory);
    let model = setup.space().model().clone();
    assert_eq!(header.len(), 3 + 3 + 4 + 12 + 12 + 12);
    assert_eq!(&header[..6], ["node", "time", "phase", "base_x", "base_y", "base_z"]);
    assert_eq!(header[6], "z_FL_FOOT");
    assert_eq!(header[10], "u_FL_HAA");
    assert_eq!(header[22], "u_max_FL_HAA");
    assert_eq!(header[45], "f_HR_FOOT_z");
    assert_eq!(rows.len(), params.horizon + 1);
    assert!(rows.iter().all(|r| r.len() == header.len()));
    let (nq, nv) = (model.nq(), model.nv());
    let u0 = column(&header, "u_FL_HAA");
    let umax0 = column(&header, "u_max_FL_HAA");
    let f0 = column(&header, "f_FL_FOOT_x");
    let mut data = model.create_data();
    let feet: Vec<usize> = FEET.iter().map(|f| model.frame_id(f).unwrap()).collect();
    let mut jac = Mat::<f64>::zeros(6, nv);
    let mut worst_all = 0.0_f64;
    for (t, row) in rows.iter().enumerate() {
        let x = &sol.xs[t];
        assert_eq!(row[0], Some(t as f64));
        assert!((row[1].unwrap() - 0.02 * t as f64).abs() < 1e-12);
        assert_eq!(row[2], Some(params.phase(t).index() as f64));
        assert_eq!(&row[3..6], &[Some(x[0]), Some(x[1]), Some(x[2])]);
        let z = setup.feet_heights(x).unwrap();
        assert_eq!(&row[6..10], z.iter().map(|&z| Some(z)).collect::<Vec<_>>().as_slice());
        if t == params.horizon {
            assert!(row[u0..].iter().all(Option::is_none), "node N has no control");
            continue;
        }
        let u: Vec<f64> = row[u0..u0 + 12].iter().map(|v| v.unwrap()).collect();
        assert_eq!(u, sol.us[t]);
        assert!(row[umax0..umax0 + 12].iter().all(|&m| m == Some(1000.0)));
        let f: Vec<f64> = row[f0..f0 + 12].iter().map(|v| v.unwrap()).collect();
        if !params.phase(t).in_contact() {
            assert!(f.iter().all(|&f| f == 0.0));
            continue;
        }
        // (56a) at the solution, from the multibody crate alone: the acceleration of the
        // semi-implicit Euler step, a = (v_{t+1} − v_t) / dt, and the forces of the table
        // balance RNEA: M a + b − Jcᵀ λ = [0; u].
        let (q, v) = x.split_at(nq);
        let a: Vec<f64> = (0..nv).map(|i| (sol.xs[t + 1][nq + i] - v[i]) / params.dt).collect();
        let mut residual = rnea(&model, &mut data, q, v, &a).unwrap().to_vec();
        compute_joint_jacobians(&model, &mut data, q).unwrap();
        for (k, &frame) in feet.iter().enumerate() {
            frame_jacobian(&model, &data, frame, ReferenceFrame::LocalWorldAligned, jac.as_mut()).unwrap();
            for j in 0..nv {
                residual[j] -= (0..3).map(|r| jac[(r, j)] * f[3 * k + r]).sum::<f64>();
            }
        }
        for j in 6..nv {
            residual[j] -= u[j - 6];
        }
        let worst = residual.iter().fold(0.0_f64, |m, r| m.max(r.abs()));
        assert!(worst < 1e-6, "stage {t}: generalized force residual {worst:e}");
        worst_all = worst_all.max(worst);
    }
    eprintln!("solo-jump figures: largest residual of (56a) with the table's forces {worst_all:.1e}");
    // The forces of the table are those of the multibody contact dynamics at (x_t, u_t).
    let mut contacts: Vec<ContactModel> = feet
        .iter()
        .map(|&f| {
            let mut c =
                ContactModel::from_frame(&model, ContactType::Contact3D, f, ReferenceFrame::LocalWorldAligned).unwrap();
            c.kd = params.kd;
            c
        })
        .collect();
    contacts.iter_mut().for_each(|c| c.kp = params.kp);
    let mut cdata = ContactData::new(&model, &contacts).unwrap();
    for t in [0, 10, 19, 45, 50, 59] {
        let (q, v) = sol.xs[t].split_at(nq);
        let tau: Vec<f64> = [0.0; 6].iter().chain(&sol.us[t]).copied().collect();
        constraint_dynamics(&model, &mut data, &contacts, &mut cdata, q, v, &tau).unwrap();
        let row = &rows[t];
        for (i, &l) in cdata.lambda().iter().enumerate() {
            let f = row[f0 + i].unwrap();
            assert!(
                (f - l).abs() <= 1e-9 * l.abs().max(1.0),
                "stage {t} row {i}: {f} vs {l}"
            );
        }
    }
}

#[test]
fn the_guess_stands_still_until_the_take_off() {
    let setup = JumpSetup::new(&JumpParams::default()).unwrap();
    let (xs, us) = setup.initial_guess();
    assert_eq!((xs.len(), us.len()), (61, 60));
    assert!(xs.iter().all(|x| *x == setup.x0) && us.iter().all(|u| *u == setup.u_stand));
    assert!(setup.feet_heights(&setup.x0).unwrap().iter().all(|z| z.abs() < 1e-12));
    assert!((setup.standing_height() - (0.235 - 0.01205)).abs() < 1e-5);
    // u_qs holds the robot: the contact dynamics at (x0, u_qs) give a = 0 and the
    // quasi-static forces, which carry the weight.
    let dynamics = setup.contact_dynamics();
    let mut d = dynamics.create_contact_data();
    let lambda = dynamics
        .contact_forces(&setup.x0, &setup.u_stand, &mut d)
        .unwrap()
        .to_vec();
    assert!(
        d.acceleration().iter().all(|a| a.abs() < 1e-9),
        "{:?}",
        d.acceleration()
    );
    for (l, r) in lambda.iter().zip(&setup.lambda_stand) {
        assert!((l - r).abs() < 1e-9);
    }
    let weight = setup.space().model().total_mass() * 9.81;
    let normal: f64 = (0..4).map(|k| lambda[3 * k + 2]).sum();
    assert!((normal - weight).abs() < 1e-3 * weight, "{normal} vs {weight}");
}

#[test]
fn friction_cones_and_torque_limits_keep_the_jump() {
    let mu = 0.8;
    let params = JumpParams {
        friction: Some(mu),
        torque_limits: true,
        ..JumpParams::default()
    };
    let (setup, sol) = solve(&params);
    eprintln!(
        "solo-jump with cones and torque limits: {:?} in {} iterations, cost {:.12}",
        sol.status, sol.iterations, sol.cost
    );
    assert_eq!(sol.status, Status::Converged);
    let stage = &setup.problem.stages()[0];
    assert_eq!(stage.constraints().len(), 5, "four cones and the torque box");
    assert_eq!(
        setup.problem.stages()[30].constraints().len(),
        1,
        "the torque box only in flight"
    );
    let dynamics = setup.contact_dynamics();
    let mut d = dynamics.create_contact_data();
    for t in (0..params.horizon).filter(|&t| params.phase(t).in_contact()) {
        let lambda = dynamics.contact_forces(&sol.xs[t], &sol.us[t], &mut d).unwrap();
        for f in lambda.chunks(3) {
            assert!(f[0].hypot(f[1]) <= mu * f[2] + 1e-6, "stage {t}: {f:?}");
        }
    }
    // The cones and the bounds are inactive at the jump without them.
    assert!((sol.cost - ALIGATOR_COST).abs() < 1e-6, "cost {}", sol.cost);
}

#[test]
fn bad_parameters_and_solutions_are_errors() {
    let cases = [
        JumpParams {
            takeoff: 45,
            landing: 45,
            ..JumpParams::default()
        },
        JumpParams {
            landing: 60,
            ..JumpParams::default()
        },
        JumpParams {
            takeoff: 0,
            ..JumpParams::default()
        },
        JumpParams {
            dt: 0.0,
            ..JumpParams::default()
        },
        JumpParams {
            friction: Some(-0.5),
            ..JumpParams::default()
        },
        JumpParams {
            kd: f64::NAN,
            ..JumpParams::default()
        },
        JumpParams {
            control_weight: -1.0,
            ..JumpParams::default()
        },
        // Refused before anything is allocated for it.
        JumpParams {
            horizon: usize::MAX,
            ..JumpParams::default()
        },
    ];
    for p in cases {
        let err = JumpSetup::new(&p).unwrap_err().to_string();
        assert!(err.contains("JumpParams"), "{p:?}: {err}");
    }
    let setup = JumpSetup::new(&JumpParams::default()).unwrap();
    let mut sol = Solution::new(&setup.problem, 0);
    let (xs, us) = setup.initial_guess();
    sol.xs = xs;
    sol.us = us;
    assert!(setup.figures(&sol).is_ok());
    sol.us.pop();
    assert!(setup.figures(&sol).is_err());
    assert!(setup.feet_heights(&[0.0; 3]).is_err());
}
