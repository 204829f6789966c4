//! Building contact sets by frame name, with Baumgarte gains and reference placements.

use crate::multibody_error;
use gharial::{Error, Result};
use gharial_multibody::{ContactModel, ContactType, Model, ReferenceFrame, forward_kinematics_placements};

/// How each contact of a set is modelled: point (3D) or frame (6D), the frame its rows
/// and forces are expressed in, and the Baumgarte gains of the acceleration-level
/// constraint `Jc a + γ = −Kp c(q) − Kd ċ` (ProxDDP paper, (55)); the gains are the same
/// on every axis of a contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactSpec {
    /// 3D point or 6D frame contact.
    pub kind: ContactType,
    /// `Local` or `LocalWorldAligned`.
    pub reference_frame: ReferenceFrame,
    /// Position gain `Kp` (≥ 0).
    pub kp: f64,
    /// Velocity gain `Kd` (≥ 0).
    pub kd: f64,
}

impl ContactSpec {
    /// Point contacts (3 rows each) in `reference_frame`, no Baumgarte terms.
    pub fn point(reference_frame: ReferenceFrame) -> Self {
        Self {
            kind: ContactType::Contact3D,
            reference_frame,
            kp: 0.0,
            kd: 0.0,
        }
    }

    /// Frame contacts (6 rows each) in `reference_frame`, no Baumgarte terms.
    pub fn frame(reference_frame: ReferenceFrame) -> Self {
        Self {
            kind: ContactType::Contact6D,
            ..Self::point(reference_frame)
        }
    }

    /// The same with Baumgarte gains `kp`, `kd`.
    pub fn with_gains(self, kp: f64, kd: f64) -> Self {
        Self { kp, kd, ..self }
    }
}

/// One contact per named frame, as `spec` says. The position terms (`kp`) are measured
/// against the world origin until [`set_contact_references`] sets the references.
///
/// # Errors
/// An unknown frame name, a `World` reference frame, or gains that are negative or not
/// finite.
pub fn contacts_at_frames(model: &Model, frames: &[&str], spec: ContactSpec) -> Result<Vec<ContactModel>> {
    check_gains(&spec)?;
    frames
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let what = || format!("contact {k} (frame `{name}`) of model `{}`", model.name);
            let id = model.frame_id(name).map_err(|e| multibody_error(&what(), e))?;
            let mut c = ContactModel::from_frame(model, spec.kind, id, spec.reference_frame)
                .map_err(|e| multibody_error(&what(), e))?;
            c.kp = spec.kp;
            c.kd = spec.kd;
            Ok(c)
        })
        .collect()
}

fn check_gains(spec: &ContactSpec) -> Result<()> {
    for (name, g) in [("kp", spec.kp), ("kd", spec.kd)] {
        if !(g.is_finite() && g >= 0.0) {
            return Err(Error::option(
                format!("ContactSpec::{name}"),
                format!("Baumgarte gain must be finite and non-negative, got {g}"),
            ));
        }
    }
    Ok(())
}

/// Sets the reference placement of every contact (what the `kp` term pulls towards) to
/// its world placement at configuration `q`, e.g. where a foot touches the ground.
///
/// # Errors
/// If `q` has the wrong size or a non-finite entry, or a contact's joint is not a joint
/// of the model.
pub fn set_contact_references(model: &Model, contacts: &mut [ContactModel], q: &[f64]) -> Result<()> {
    let mut data = model.create_data();
    forward_kinematics_placements(model, &mut data, q).map_err(|e| multibody_error("set_contact_references", e))?;
    for (k, c) in contacts.iter_mut().enumerate() {
        if c.joint == 0 || c.joint >= model.njoints() {
            return Err(Error::InvalidModel(format!(
                "set_contact_references: contact {k} is attached to joint {}, not a moving joint of model `{}`",
                c.joint, model.name
            )));
        }
        c.reference = data.joint_placement(c.joint).compose(&c.placement);
    }
    Ok(())
}
