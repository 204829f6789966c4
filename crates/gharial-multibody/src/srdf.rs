//! SRDF loader: reference configurations (`group_state`) and rotor parameters, read as
//! Pinocchio's `loadReferenceConfigurations` and `loadRotorParameters` do: joints the
//! model does not have are skipped, so the SRDF of a whole robot can be read into a
//! reduced model (one arm of a humanoid).

use crate::configuration::neutral;
use crate::error::{Error, Result};
use crate::joint::JointType;
use crate::model::Model;
use roxmltree::Node;
use std::collections::HashMap;

/// What [`Model::load_srdf_str_with`] reads from an SRDF.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdfOptions {
    /// Read the `<group_state>`s into [`Model::reference_configurations`].
    pub reference_configurations: bool,
    /// Read the `<rotor_params>` into the rotor inertia, gear ratio and armature.
    pub rotor_parameters: bool,
}

impl Default for SrdfOptions {
    /// Both.
    fn default() -> Self {
        Self {
            reference_configurations: true,
            rotor_parameters: true,
        }
    }
}

fn err(file: &str, node: &Node, message: impl Into<String>) -> Error {
    let name = node
        .attribute("name")
        .map(|n| format!(" name=\"{n}\""))
        .unwrap_or_default();
    Error::Element {
        file: file.into(),
        element: node.tag_name().name().into(),
        name,
        message: message.into(),
    }
}

fn attr<'a>(file: &str, node: &Node<'a, 'a>, key: &str) -> Result<&'a str> {
    node.attribute(key)
        .ok_or_else(|| err(file, node, format!("missing attribute `{key}`")))
}

fn number(file: &str, node: &Node, key: &str) -> Result<f64> {
    let s = attr(file, node, key)?;
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| err(file, node, format!("attribute `{key}`: `{s}` is not a finite number")))
}

/// The `<joint>` children of `node`.
fn joint_children<'a, 'i>(node: &Node<'a, 'i>) -> impl Iterator<Item = Node<'a, 'i>> {
    node.children()
        .filter(|n| n.is_element() && n.tag_name().name() == "joint")
}

/// Largest number of entries (group states × nq) that one SRDF may add as reference
/// configurations: each `<group_state>` element of a few bytes costs nq numbers, so
/// that a large file of empty group states on a large model could otherwise ask for
/// gigabytes. 2²⁶ entries are 512 MiB.
const MAX_REFERENCE_ENTRIES: usize = 1 << 26;

/// Rotor parameters of one joint: (joint id, rotor inertia, gear ratio).
type Rotor = (usize, f64, f64);

impl Model {
    /// Reads an SRDF file: see [`Model::load_srdf_str`].
    pub fn load_srdf_file(&mut self, path: impl AsRef<std::path::Path>) -> Result<()> {
        self.load_srdf_file_with(path, &SrdfOptions::default())
    }

    /// Reads the parts of an SRDF file selected by `options`: see
    /// [`Model::load_srdf_str_with`].
    pub fn load_srdf_file_with(&mut self, path: impl AsRef<std::path::Path>, options: &SrdfOptions) -> Result<()> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        self.load_srdf(&text, &path.display().to_string(), options)
    }

    /// Reads the reference configurations and the rotor parameters of an SRDF: see
    /// [`Model::load_srdf_str_with`].
    pub fn load_srdf_str(&mut self, xml: &str) -> Result<()> {
        self.load_srdf(xml, "SRDF", &SrdfOptions::default())
    }

    /// Reads the parts of an SRDF selected by `options`, as Pinocchio does:
    ///
    /// * every `<group_state name>` becomes a named reference configuration: the neutral
    ///   configuration with the listed joints set from their `value` (nq numbers, or
    ///   one angle for an unbounded revolute joint; quaternions and (cos, sin) pairs are
    ///   normalized). Joints the model does not have are skipped, their entries stay
    ///   neutral. A group state defined again (in the file or by an earlier load)
    ///   replaces the earlier definition.
    /// * the first `<rotor_params>` element's `<joint name mass gear_ratio/>` entries set
    ///   the rotor inertia (`mass`), the gear ratio and the armature
    ///   (`mass · gear_ratio²`) of one-degree-of-freedom joints; joints the model does
    ///   not have are skipped. (Pinocchio adds to the armature; setting it makes a
    ///   second load idempotent, and gives the same model after a URDF load.)
    ///
    /// Errors (the model is left unchanged) name the element: malformed XML, a missing
    /// attribute, a non-finite number, a wrong number of values for a joint of the
    /// model (Pinocchio only prints a warning and leaves it neutral), a zero quaternion,
    /// rotor parameters for a joint with more than one degree of freedom, a negative
    /// rotor inertia, more group states than 2²⁶ / nq.
    pub fn load_srdf_str_with(&mut self, xml: &str, options: &SrdfOptions) -> Result<()> {
        self.load_srdf(xml, "SRDF", options)
    }

    fn load_srdf(&mut self, xml: &str, file: &str, options: &SrdfOptions) -> Result<()> {
        let doc = roxmltree::Document::parse(xml).map_err(|e| Error::Xml {
            file: file.into(),
            message: e.to_string(),
        })?;
        let robot = doc.root_element();
        if robot.tag_name().name() != "robot" {
            return Err(err(file, &robot, "the root element must be <robot>"));
        }
        let elements = || robot.children().filter(|n| n.is_element());
        self.check_some_joint_is_known(file, &robot)?;
        let mut configs = Vec::new();
        if options.reference_configurations {
            let count = elements().filter(|n| n.tag_name().name() == "group_state").count();
            if count.saturating_mul(self.nq) > MAX_REFERENCE_ENTRIES {
                return Err(err(
                    file,
                    &robot,
                    format!(
                        "{count} group states of nq = {} numbers each exceed the limit of {MAX_REFERENCE_ENTRIES} numbers",
                        self.nq
                    ),
                ));
            }
            for node in elements().filter(|n| n.tag_name().name() == "group_state") {
                configs.push(self.group_state(file, &node)?);
            }
        }
        let mut rotors = Vec::new();
        let first_rotor_params = elements().find(|n| n.tag_name().name() == "rotor_params");
        if let Some(node) = first_rotor_params.filter(|_| options.rotor_parameters) {
            for j in joint_children(&node) {
                if let Some(r) = self.rotor_params(file, &j)? {
                    rotors.push(r);
                }
            }
        }
        self.set_reference_configurations(configs);
        for (id, mass, ratio) in rotors {
            let k = self.joints[id].idx_v;
            self.rotor_inertia[k] = mass;
            self.rotor_gear_ratio[k] = ratio;
            self.armature[k] = mass * ratio * ratio;
        }
        Ok(())
    }

    /// Joints the model does not have are skipped (a reduced model), but an SRDF none of
    /// whose joints is in the model is another robot's: an error, not a set of neutral
    /// configurations.
    fn check_some_joint_is_known(&self, file: &str, robot: &Node) -> Result<()> {
        let mut names = robot
            .children()
            .filter(|n| matches!(n.tag_name().name(), "group_state" | "rotor_params"))
            .flat_map(|n| joint_children(&n).collect::<Vec<_>>())
            .filter_map(|j| j.attribute("name"))
            .peekable();
        if names.peek().is_none() || names.any(|name| self.joint_id(name).is_ok()) {
            return Ok(());
        }
        Err(err(
            file,
            robot,
            format!(
                "none of the joints of this SRDF is in model `{}` (an SRDF of another robot?)",
                self.name
            ),
        ))
    }

    /// The configuration of one `<group_state>`.
    fn group_state(&self, file: &str, node: &Node) -> Result<(String, Vec<f64>)> {
        let name = attr(file, node, "name")?;
        let mut q = neutral(self);
        for j in joint_children(node) {
            let jname = attr(file, &j, "name")?;
            let Ok(id) = self.joint_id(jname) else { continue };
            let jm = self.joints[id];
            let text = attr(file, &j, "value")?;
            let vals: Option<Vec<f64>> = text
                .split_whitespace()
                .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect();
            let vals = vals.ok_or_else(|| err(file, &j, format!("value `{text}` is not a list of finite numbers")))?;
            let qj = &mut q[jm.idx_q..jm.idx_q + jm.nq];
            if vals.len() == jm.nq {
                qj.copy_from_slice(&vals);
            } else if vals.len() == 1 && matches!(jm.kind, JointType::RevoluteUnbounded(_)) {
                qj[0] = vals[0].cos();
                qj[1] = vals[0].sin();
            } else {
                return Err(err(file, &j, format!("expected {} values, got {}", jm.nq, vals.len())));
            }
        }
        crate::configuration::normalize(self, &mut q).map_err(|e| err(file, node, e.to_string()))?;
        Ok((name.to_string(), q))
    }

    /// The rotor parameters of one `<rotor_params><joint>`, or `None` for a joint the
    /// model does not have.
    fn rotor_params(&self, file: &str, j: &Node) -> Result<Option<Rotor>> {
        let jname = attr(file, j, "name")?;
        let Ok(id) = self.joint_id(jname) else {
            return Ok(None);
        };
        if self.joints[id].nv != 1 {
            return Err(err(
                file,
                j,
                format!(
                    "rotor parameters need a one-dof joint, this one has nv = {}",
                    self.joints[id].nv
                ),
            ));
        }
        let (mass, ratio) = (number(file, j, "mass")?, number(file, j, "gear_ratio")?);
        if mass < 0.0 {
            return Err(err(file, j, format!("negative rotor inertia `mass` = {mass:e}")));
        }
        if !(mass * ratio * ratio).is_finite() {
            return Err(err(file, j, "the armature mass · gear_ratio² overflows"));
        }
        Ok(Some((id, mass, ratio)))
    }

    /// Adds the configurations, a name defined again replacing the earlier one.
    fn set_reference_configurations(&mut self, configs: Vec<(String, Vec<f64>)>) {
        let mut index: HashMap<String, usize> = self
            .reference_configurations
            .iter()
            .enumerate()
            .map(|(k, (n, _))| (n.clone(), k))
            .collect();
        for (name, q) in configs {
            match index.get(&name) {
                Some(&k) => self.reference_configurations[k].1 = q,
                None => {
                    index.insert(name.clone(), self.reference_configurations.len());
                    self.reference_configurations.push((name, q));
                }
            }
        }
    }

    /// Named reference configuration (from an SRDF).
    pub fn reference_configuration(&self, name: &str) -> Result<&[f64]> {
        self.reference_configurations
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, q)| q.as_slice())
            .ok_or_else(|| Error::NotFound {
                what: "reference configuration".into(),
                name: name.into(),
            })
    }
}
