//! Robots as gharial optimal control problems.
//!
//! This crate joins the solver core [`gharial`] and the rigid-body dynamics of
//! [`gharial_multibody`] (neither knows the other):
//!
//! - [`spaces`]: the configuration space of any multibody model and its phase space
//!   `x = (q, v)` as core manifolds.
//! - [`dynamics`]: free and contact forward dynamics as core ODEs on the phase space.
//! - [`inverse`]: gravity compensation and quasi-static torques for initial guesses.
//! - [`residuals`]: frame, centre-of-mass, gravity, contact-force and friction-cone
//!   residuals, and joint limits as ready-made constraints.

pub mod dynamics;
pub mod inverse;
pub mod residuals;
pub mod spaces;

pub use dynamics::{
    Actuation, ContactDynamicsData, ContactSpec, MultibodyConstraintFwdDynamics, MultibodyFreeFwdDynamics,
    MultibodyWeldFwdDynamics, WeldData, contacts_at_frames, set_contact_references,
};
pub use inverse::{QuasiStatic, gravity_compensation, quasi_static_torque};
pub use spaces::{MultibodyConfiguration, MultibodyPhaseSpace};

/// A multibody error as a core error, prefixed with `context` (the object being built).
pub(crate) fn multibody_error(context: &str, e: gharial_multibody::Error) -> gharial::Error {
    use gharial_multibody::Error as E;
    match e {
        E::Dimension { what, expected, got } => gharial::Error::dim(format!("{context}: {what}"), expected, got),
        E::NotFinite { what, index, .. } => gharial::Error::non_finite(format!("{context}: {what}, entry {index}")),
        E::NotPositiveDefinite { .. } => gharial::Error::singular(format!("{context}: {e}")),
        other => gharial::Error::InvalidModel(format!("{context}: {other}")),
    }
}
