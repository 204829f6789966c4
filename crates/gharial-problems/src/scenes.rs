//! What the trajectory viewer shows of a catalogue problem: the robot whose
//! configuration `q` leads the problem's state `x = (q, v)`, and fixed markers (targets,
//! obstacles).

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
        assert_eq!(seen, 12);
    }
}
