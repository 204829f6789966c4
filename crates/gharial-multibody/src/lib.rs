//! Rigid-body dynamics for gharial, as exact as Pinocchio, with analytical derivatives.
//!
//! A [`Model`] (kinematic tree, inertias, frames, limits) is built from a URDF
//! ([`Model::from_urdf_file`]) or by hand; every algorithm writes into a [`Data`]
//! created once by [`Model::create_data`] and allocates nothing afterwards.
//!
//! Conventions are Pinocchio's: spatial vectors are `[linear, angular]`, free-flyer
//! quaternions are `[x, y, z, w]`, q-derivatives are taken along tangent perturbations
//! `q ⊕ δ`. Kinematics, CRBA, ABA and the derivatives work in the world frame (`WORLD`);
//! the RNEA works in the joint frames.
//!
//! ```no_run
//! use gharial_multibody::{Model, RootJoint, rnea, neutral};
//! let model = Model::from_urdf_file("ur5_robot.urdf", RootJoint::Fixed).unwrap();
//! let mut data = model.create_data();
//! let q = neutral(&model);
//! let zeros = vec![0.0; model.nv()];
//! let tau = rnea(&model, &mut data, &q, &zeros, &zeros).unwrap();
//! assert_eq!(tau.len(), model.nv());
//! ```

mod configuration;
mod contact;
mod data;
mod derivatives;
mod dynamics;
mod error;
mod joint;
mod kinematics;
mod lie;
mod linalg;
mod model;
pub mod spatial;
mod srdf;
mod urdf;

pub use configuration::{
    ddifference, difference, dintegrate, integrate, neutral, normalize, random_configuration,
    random_configuration_within_limits,
};
pub use contact::{
    ContactData, ContactModel, ContactType, compute_constraint_dynamics_derivatives, constraint_dynamics,
};
pub use data::Data;
pub use derivatives::{
    compute_aba_derivatives, compute_aba_derivatives_reusing_aba, compute_forward_kinematics_derivatives,
    compute_rnea_derivatives, frame_acceleration_derivatives, frame_velocity_derivatives,
};
pub use dynamics::{
    aba, center_of_mass, compute_minverse, crba, generalized_gravity, jacobian_center_of_mass, nonlinear_effects, rnea,
};
pub use error::{Error, Result};
pub use joint::{Axis, JointModel, JointType};
pub use kinematics::{
    compute_joint_jacobians, compute_joint_jacobians_reusing_placements, forward_kinematics,
    forward_kinematics_placements, frame_acceleration, frame_classical_acceleration, frame_jacobian, frame_velocity,
    joint_acceleration, joint_jacobian, joint_velocity, update_frame_placements,
};
pub use lie::{exp3, exp6, jexp3, jexp6_blocks, jlog3, jlog6_blocks, log3, log6};
pub use model::{
    ArgumentPosition, Frame, FrameType, Geometry, JointLimits, MimicJoint, Model, ReferenceFrame, RootJoint, Visual,
};
pub use srdf::SrdfOptions;
pub use urdf::{MimicPolicy, UrdfOptions};
