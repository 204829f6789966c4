//! What the trajectory viewer shows of a catalogue problem: the robot whose
//! configuration `q` leads the problem's state `x = (q, v)`, and fixed markers (targets,
//! obstacles).

use gharial::Result;
use gharial_multibody::RootJoint;

use crate::quadrotor::{CYLINDER_RADIUS, CYLINDERS};
use crate::robots::{DOUBLE_PENDULUM_URDF, HECTOR_URDF, SOLO_URDF, UR5_URDF};

/// A vertical cylinder (an obstacle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerticalCylinder {
    /// Centre of its axis in the horizontal plane.
    pub centre: [f64; 2],
    /// Radius.
    pub radius: f64,
    /// Bottom and top heights.
    pub z: (f64, f64),
}

/// The robot and the markers of a problem's scene.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotScene {
    /// The robot's URDF.
    pub urdf: &'static str,
    /// Its root joint.
    pub root: RootJoint,
    /// Points to reach.
    pub targets: Vec<[f64; 3]>,
    /// Obstacles.
    pub cylinders: Vec<VerticalCylinder>,
    /// Frames whose paths the plots draw (the end effector, the base, the feet).
    pub frames: Vec<&'static str>,
}

fn scene(urdf: &'static str, root: RootJoint, frames: &[&'static str], targets: Vec<[f64; 3]>) -> RobotScene {
    RobotScene {
        urdf,
        root,
        targets,
        cylinders: Vec::new(),
        frames: frames.to_vec(),
    }
}

const SOLO_FRAMES: [&str; 5] = ["base_link", "FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"];

/// The scene of the catalogue problem `name`, for the problems whose state leads with a
/// robot's configuration (`None` for the others).
pub fn robot_scene(name: &str) -> Option<RobotScene> {
    Some(match name {
        "ur5" | "ur5-box" => scene(UR5_URDF, RootJoint::Fixed, &["tool0"], vec![[0.3, 0.5, 0.5]]),
        "ecddp-ur5" => scene(
            UR5_URDF,
            RootJoint::Fixed,
            &["tool0"],
            crate::ecddp::UR5_TARGETS.to_vec(),
        ),
        // The spheres' centres as markers (the viewer draws no spheres).
        "arm-obstacles" => scene(
            UR5_URDF,
            RootJoint::Fixed,
            &["tool0"],
            crate::altro_table::ARM_CENTRES.to_vec(),
        ),
        "ur5-circle" | "ur5-circle-joint-bound" | "ur5-circle-half-space" => {
            scene(UR5_URDF, RootJoint::Fixed, &["tool0"], vec![])
        }
        "double-pendulum" | "double-pendulum-box" | "double-pendulum-box-term" => {
            scene(DOUBLE_PENDULUM_URDF, RootJoint::Fixed, &["link2"], vec![])
        }
        "quadrotor" => scene(
            HECTOR_URDF,
            RootJoint::FreeFlyer,
            &["base_link"],
            vec![[0.9, 0.8, 1.0], [1.4, -0.6, 1.0]],
        ),
        "quadrotor-slalom" => RobotScene {
            cylinders: CYLINDERS
                .iter()
                .map(|&centre| VerticalCylinder {
                    centre,
                    radius: CYLINDER_RADIUS,
                    z: (0.0, 2.0),
                })
                .collect(),
            ..scene(
                HECTOR_URDF,
                RootJoint::FreeFlyer,
                &["base_link"],
                vec![[-0.3, 2.5, 1.0]],
            )
        },
        "solo-jump" | "solo-com-circle" => scene(SOLO_URDF, RootJoint::FreeFlyer, &SOLO_FRAMES, vec![]),
        _ => return None,
    })
}

/// The contact forces along a solution of a legged problem.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactForces {
    /// The feet (frames), in the order of the forces.
    pub feet: Vec<&'static str>,
    /// Per stage `t < N`, per foot: the force of the ground on the robot (N, world axes;
    /// zero for a foot in the air).
    pub forces: Vec<Vec<[f64; 3]>>,
    /// Friction coefficient of the problem's cones, if it has some.
    pub mu: Option<f64>,
}

/// The contact forces of the catalogue problem `name` along `(xs, us)`, recomputed from
/// its contact dynamics (`None` for problems without contacts).
///
/// # Errors
/// A trajectory that does not fit the problem, or a state at which the contact dynamics
/// fail.
pub fn contact_forces(name: &str, xs: &[Vec<f64>], us: &[Vec<f64>]) -> Option<Result<ContactForces>> {
    let feet = crate::solo_walk::FEET.to_vec();
    match name {
        "solo-jump" => Some((|| {
            let setup = crate::solo_jump::JumpSetup::new(&Default::default())?;
            Ok(ContactForces {
                forces: setup.contact_forces(xs, us)?,
                mu: setup.params().friction,
                feet,
            })
        })()),
        "solo-com-circle" => Some((|| {
            let s = crate::solo_com_circle::setup(&crate::solo_com_circle::CircleParams {
                horizon: us.len().max(1),
                ..Default::default()
            })?;
            s.problem.check_trajectory(xs, us)?;
            let mut data = s.dynamics.create_contact_data();
            let mut forces = Vec::with_capacity(us.len());
            for (x, u) in xs.iter().zip(us) {
                let lambda = s.dynamics.contact_forces(x, u, &mut data)?;
                forces.push(
                    (0..feet.len())
                        .map(|k| [lambda[3 * k], lambda[3 * k + 1], lambda[3 * k + 2]])
                        .collect(),
                );
            }
            Ok(ContactForces {
                forces,
                mu: Some(s.mu),
                feet,
            })
        })()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gharial_multibody::{Data, Model, forward_kinematics_placements};

    /// Every scene's robot fits its problem: the state's leading entries are a valid
    /// configuration of the model at every node of the initial guess.
    #[test]
    fn scene_robots_fit_their_problems() {
        let mut seen = 0;
        for info in crate::catalogue() {
            let Some(sc) = robot_scene(info.name) else { continue };
            let model = Model::from_urdf_str(sc.urdf, sc.root).unwrap();
            let ex = crate::build(info.name).unwrap();
            for f in &sc.frames {
                model.frame_id(f).unwrap_or_else(|e| panic!("{}: {e}", info.name));
            }
            let mut data = Data::new(&model);
            assert!(ex.problem.space(0).nx() >= model.nq(), "{}", info.name);
            for x in &ex.xs0 {
                forward_kinematics_placements(&model, &mut data, &x[..model.nq()])
                    .unwrap_or_else(|e| panic!("{}: {e}", info.name));
            }
            seen += 1;
        }
        assert_eq!(seen, 14);
    }
}

#[cfg(test)]
mod force_tests {
    use super::*;

    /// Standing still (the guess of `solo-com-circle`: the quasi-static torques), the
    /// feet carry the robot's weight: the vertical forces sum to m g, the horizontal ones
    /// to zero, and every force is inside its friction cone.
    #[test]
    fn standing_feet_carry_the_weight() {
        let ex = crate::build("solo-com-circle").unwrap();
        let (xs, us) = (&ex.xs0[..3], &ex.us0[..2]);
        let f = contact_forces("solo-com-circle", xs, us).unwrap().unwrap();
        assert_eq!((f.forces.len(), f.feet.len()), (2, 4));
        let model = gharial_multibody::Model::from_urdf_str(crate::robots::SOLO_URDF, RootJoint::FreeFlyer).unwrap();
        let weight = model.inertias().iter().map(|i| i.mass).sum::<f64>() * 9.81;
        let sum: Vec<f64> = (0..3).map(|a| f.forces[0].iter().map(|p| p[a]).sum()).collect();
        assert!((sum[2] - weight).abs() < 1e-6 * weight, "{sum:?} vs {weight}");
        assert!(sum[0].abs() < 1e-6 && sum[1].abs() < 1e-6, "{sum:?}");
        let mu = f.mu.unwrap();
        for p in &f.forces[0] {
            assert!(p[0].hypot(p[1]) <= mu * p[2], "{p:?}");
        }
        assert!(contact_forces("ur5", xs, us).is_none());
        assert!(contact_forces("solo-com-circle", &xs[..1], us).unwrap().is_err());
    }
}
