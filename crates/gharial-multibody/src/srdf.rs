//! SRDF loader: reference configurations (`group_state`) and rotor parameters.

use crate::configuration::neutral;
use crate::error::{Error, Result};
use crate::joint::JointType;
use crate::model::Model;
use roxmltree::Node;

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

impl Model {
    /// Reads an SRDF file: see [`Model::load_srdf_str`].
    pub fn load_srdf_file(&mut self, path: impl AsRef<std::path::Path>) -> Result<()> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        self.load_srdf(&text, &path.display().to_string())
    }

    /// Reads an SRDF: every `<group_state>` becomes a named reference configuration (the
    /// neutral configuration with the listed joints set; joints unknown to the model are
    /// skipped, as Pinocchio does), and `<rotor_params><joint name mass gear_ratio/>`
    /// entries set the rotor inertia, gear ratio and armature (`mass · gear_ratio²`).
    pub fn load_srdf_str(&mut self, xml: &str) -> Result<()> {
        self.load_srdf(xml, "SRDF")
    }

    fn load_srdf(&mut self, xml: &str, file: &str) -> Result<()> {
        let doc = roxmltree::Document::parse(xml).map_err(|e| Error::Xml {
            file: file.into(),
            message: e.to_string(),
        })?;
        let robot = doc.root_element();
        if robot.tag_name().name() != "robot" {
            return Err(err(file, &robot, "the root element must be <robot>"));
        }
        let mut configs = Vec::new();
        let mut rotor: Vec<(usize, f64, f64)> = Vec::new();
        for node in robot.children().filter(|n| n.is_element()) {
            match node.tag_name().name() {
                "group_state" => {
                    let name = attr(file, &node, "name")?;
                    let mut q = neutral(self);
                    for j in node
                        .children()
                        .filter(|n| n.is_element() && n.tag_name().name() == "joint")
                    {
                        let jname = attr(file, &j, "name")?;
                        let Ok(id) = self.joint_id(jname) else { continue };
                        let jm = self.joints[id];
                        let text = attr(file, &j, "value")?;
                        let vals: Option<Vec<f64>> = text
                            .split_whitespace()
                            .map(|s| s.parse::<f64>().ok().filter(|v| v.is_finite()))
                            .collect();
                        let vals = vals
                            .ok_or_else(|| err(file, &j, format!("value `{text}` is not a list of finite numbers")))?;
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
                    configs.push((name.to_string(), q));
                }
                "rotor_params" => {
                    for j in node
                        .children()
                        .filter(|n| n.is_element() && n.tag_name().name() == "joint")
                    {
                        let jname = attr(file, &j, "name")?;
                        let id = self
                            .joint_id(jname)
                            .map_err(|_| err(file, &j, "joint not in the model"))?;
                        rotor.push((id, number(file, &j, "mass")?, number(file, &j, "gear_ratio")?));
                    }
                }
                _ => {}
            }
        }
        for (name, q) in configs {
            match self.reference_configurations.iter_mut().find(|(n, _)| *n == name) {
                Some(slot) => slot.1 = q,
                None => self.reference_configurations.push((name, q)),
            }
        }
        for (id, mass, ratio) in rotor {
            let jm = self.joints[id];
            for k in jm.idx_v..jm.idx_v + jm.nv {
                self.rotor_inertia[k] = mass;
                self.rotor_gear_ratio[k] = ratio;
                self.armature[k] = mass * ratio * ratio;
            }
        }
        Ok(())
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
