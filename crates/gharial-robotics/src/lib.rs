//! Robots as gharial optimal control problems.
//!
//! This crate joins the solver core [`gharial`] and the rigid-body dynamics of
//! [`gharial_multibody`] (neither knows the other):
//!
//! - [`spaces`]: the configuration space of any multibody model and its phase space
//!   `x = (q, v)` as core manifolds.

pub mod spaces;

pub use spaces::{MultibodyConfiguration, MultibodyPhaseSpace};
