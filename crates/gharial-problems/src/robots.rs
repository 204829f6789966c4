//! The robot descriptions the catalogue builds its problems from (copies under
//! `gharial-multibody/tests/data/robots`, with their licences there), each included once.

/// Universal Robots UR5.
pub const UR5_URDF: &str = include_str!("../../gharial-multibody/tests/data/robots/ur5_robot.urdf");
/// The UR5's SRDF (reference configurations).
pub const UR5_SRDF: &str = include_str!("../../gharial-multibody/tests/data/robots/ur5.srdf");
/// Universal Robots UR10.
pub const UR10_URDF: &str = include_str!("../../gharial-multibody/tests/data/robots/ur10_robot.urdf");
/// The double pendulum of example-robot-data.
pub const DOUBLE_PENDULUM_URDF: &str = include_str!("../../gharial-multibody/tests/data/robots/double_pendulum.urdf");
/// The Hector quadrotor's base.
pub const HECTOR_URDF: &str = include_str!("../../gharial-multibody/tests/data/robots/quadrotor_base.urdf");
/// Solo-12.
pub const SOLO_URDF: &str = include_str!("../../gharial-multibody/tests/data/robots/solo12.urdf");
/// Solo-12's SRDF (reference configurations).
pub const SOLO_SRDF: &str = include_str!("../../gharial-multibody/tests/data/robots/solo.srdf");
/// Unitree G1 (29 joints).
pub const G1_URDF: &str = include_str!("../../gharial-multibody/tests/data/robots/g1_29dof_rev_1_0.urdf");
