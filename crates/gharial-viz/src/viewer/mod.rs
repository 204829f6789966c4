//! The 3D trajectory viewer: one self-contained HTML page (scene, script and styles
//! inline; no network access needed to open it) that plays a trajectory on a canvas,
//! with play / pause, a time slider, a speed choice and an orbiting camera (drag to turn,
//! wheel to zoom). `#t=1.5` in the page's address shows that time paused, `#play` plays.
//!
//! A [`Scene`] holds bodies (a shape and one pose per frame), fixed markers (targets,
//! obstacles) and arrows per frame (contact forces). [`Scene::add_robot`] places the
//! visual geometry of a multibody model along a configuration trajectory by forward
//! kinematics: boxes, cylinders and spheres as written in the URDF, meshes (STL, OBJ,
//! COLLADA) when their
//! files resolve ([`MeshSearch`]), and capsules between the joint frames for what does
//! not.

mod meshes;

use gharial_multibody::spatial::{Mat3, Se3, Vec3};
use gharial_multibody::{Data, Geometry, JointType, Model, forward_kinematics_placements};
use serde_json::{Value, json};

pub use meshes::MeshSearch;

use crate::{Error, Result};

/// A rigid placement in the world: rotation and translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation matrix, row by row.
    pub rotation: [[f64; 3]; 3],
    /// Translation.
    pub translation: [f64; 3],
}

impl Pose {
    /// The pure translation to `p`.
    pub fn at(p: [f64; 3]) -> Self {
        Self {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: p,
        }
    }

    /// The pose of a capsule from `a` to `b` (centred between them, z along `b - a`),
    /// and its length.
    pub fn between(a: [f64; 3], b: [f64; 3]) -> (Self, f64) {
        let (a, b) = (Vec3::from(a), Vec3::from(b));
        (segment_pose(&a, &b), (b - a).norm())
    }

    /// The rotation by `angle` about the axis `x`, `y` or `z` (0, 1, 2), at `p`.
    pub fn rotated(axis: usize, angle: f64, p: [f64; 3]) -> Self {
        let (c, s) = (angle.cos(), angle.sin());
        let rotation = match axis {
            0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
            1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
            _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        };
        Self {
            rotation,
            translation: p,
        }
    }

    fn from_se3(m: &Se3) -> Self {
        let r = &m.rotation;
        Self {
            rotation: [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]),
            translation: [m.translation.x, m.translation.y, m.translation.z],
        }
    }

    fn flat(&self) -> [f64; 12] {
        let r = &self.rotation;
        let t = &self.translation;
        [
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2], t[0], t[1], t[2],
        ]
    }
}

/// A shape in its local frame (centred; cylinders and capsules along z).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Box with full side lengths.
    Box {
        /// Side lengths.
        size: [f64; 3],
    },
    /// Cylinder along z.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Length.
        length: f64,
    },
    /// Sphere.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// Cylinder along z with hemispherical ends (`length` between the centres of the ends).
    Capsule {
        /// Radius.
        radius: f64,
        /// Length of the cylindrical part.
        length: f64,
    },
    /// Triangle mesh.
    Mesh {
        /// Vertices.
        vertices: Vec<[f64; 3]>,
        /// Triangles, as vertex indices.
        triangles: Vec<[u32; 3]>,
    },
}

impl Shape {
    fn json(&self) -> Value {
        match self {
            Shape::Box { size } => json!({"kind": "box", "size": size}),
            Shape::Cylinder { radius, length } => json!({"kind": "cylinder", "radius": radius, "length": length}),
            Shape::Sphere { radius } => json!({"kind": "sphere", "radius": radius}),
            Shape::Capsule { radius, length } => json!({"kind": "capsule", "radius": radius, "length": length}),
            Shape::Mesh { vertices, triangles } => json!({
                "kind": "mesh",
                "vertices": vertices.iter().flatten().map(|v| round(*v)).collect::<Vec<_>>(),
                "triangles": triangles.iter().flatten().collect::<Vec<_>>(),
            }),
        }
    }

    fn numbers(&self) -> Vec<f64> {
        match self {
            Shape::Box { size } => size.to_vec(),
            Shape::Cylinder { radius, length } | Shape::Capsule { radius, length } => vec![*radius, *length],
            Shape::Sphere { radius } => vec![*radius],
            Shape::Mesh { vertices, .. } => vertices.iter().flatten().copied().collect(),
        }
    }
}

/// Coordinates written with 6 decimals (micrometres): smaller pages, same pictures.
fn round(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// A moving body: its shape, colour and pose at every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name (the URDF link, say).
    pub name: String,
    /// Shape.
    pub shape: Shape,
    /// Colour, RGB in `[0, 1]`.
    pub color: [f64; 3],
    /// Pose at each frame.
    pub poses: Vec<Pose>,
}

/// A fixed object: a target or an obstacle.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Shape.
    pub shape: Shape,
    /// Colour, RGB in `[0, 1]`.
    pub color: [f64; 3],
    /// Opacity in `(0, 1]`.
    pub alpha: f64,
    /// Pose.
    pub pose: Pose,
}

/// An arrow (a contact force, say) from a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrow {
    /// Start point.
    pub from: [f64; 3],
    /// Vector, in metres on the picture.
    pub vector: [f64; 3],
}

/// What the viewer plays.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    /// Title of the page.
    pub title: String,
    /// Time between frames, seconds.
    pub dt: f64,
    /// Moving bodies.
    pub bodies: Vec<Body>,
    /// Fixed markers.
    pub markers: Vec<Marker>,
    /// Arrows of each frame (empty: none).
    pub arrows: Vec<Vec<Arrow>>,
}

/// What [`Scene::add_robot`] drew from the model's visual geometry.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RobotReport {
    /// Visual elements drawn (primitives and loaded meshes).
    pub visuals: usize,
    /// Mesh files that did not resolve or load (with the reason); capsules between the
    /// joint frames stand in for them.
    pub missing: Vec<String>,
    /// Capsules added between joint frames.
    pub capsules: usize,
}

const ROBOT_COLOR: [f64; 3] = [0.62, 0.66, 0.74];
const SKELETON_COLOR: [f64; 3] = [0.95, 0.55, 0.15];
const TARGET_COLOR: [f64; 3] = [0.1, 0.75, 0.2];
const OBSTACLE_COLOR: [f64; 3] = [0.8, 0.2, 0.2];

impl Scene {
    /// An empty scene with `dt` seconds between frames.
    pub fn new(title: impl Into<String>, dt: f64) -> Self {
        Self {
            title: title.into(),
            dt,
            ..Self::default()
        }
    }

    /// Adds the visual geometry of `model` along the configurations `qs` (one frame
    /// each), resolving mesh files through `meshes`.
    ///
    /// # Errors
    /// No configuration, a configuration of the wrong size or not on the model's
    /// configuration space, or a number of frames other than the scene's other bodies
    /// have.
    pub fn add_robot(&mut self, model: &Model, qs: &[Vec<f64>], meshes: &MeshSearch) -> Result<RobotReport> {
        if qs.is_empty() {
            return Err(Error::Invalid("viewer: no configurations to show".into()));
        }
        if let Some(b) = self.bodies.first()
            && b.poses.len() != qs.len()
        {
            return Err(Error::Invalid(format!(
                "viewer: {} configurations for a scene of {} frames",
                qs.len(),
                b.poses.len()
            )));
        }
        let mut data = Data::new(model);
        let mut joints: Vec<Vec<Se3>> = Vec::with_capacity(qs.len());
        for (t, q) in qs.iter().enumerate() {
            forward_kinematics_placements(model, &mut data, q)
                .map_err(|e| Error::Invalid(format!("viewer: configuration {t}: {e}")))?;
            joints.push((0..model.njoints()).map(|i| *data.joint_placement(i)).collect());
        }
        let mut report = RobotReport::default();
        for v in &model.visuals {
            let shape = match &v.geometry {
                Geometry::Box { size } => Shape::Box {
                    size: [size.x, size.y, size.z],
                },
                Geometry::Cylinder { radius, length } => Shape::Cylinder {
                    radius: *radius,
                    length: *length,
                },
                Geometry::Sphere { radius } => Shape::Sphere { radius: *radius },
                Geometry::Mesh { filename, scale } => match meshes.load(filename, [scale.x, scale.y, scale.z]) {
                    Ok(m) => m,
                    Err(why) => {
                        report.missing.push(format!("{filename}: {why}"));
                        continue;
                    }
                },
            };
            report.visuals += 1;
            self.bodies.push(Body {
                name: v.link.clone(),
                shape,
                color: ROBOT_COLOR,
                poses: joints
                    .iter()
                    .map(|o| Pose::from_se3(&o[v.parent_joint].compose(&v.placement)))
                    .collect(),
            });
        }
        if report.visuals == 0 || !report.missing.is_empty() {
            report.capsules = self.add_skeleton(model, &joints);
        }
        Ok(report)
    }

    /// Capsules from each joint's frame to its children's and to the operational frames
    /// it carries; returns their number.
    fn add_skeleton(&mut self, model: &Model, joints: &[Vec<Se3>]) -> usize {
        let parents = model.parents();
        // Segments as (joint, point in its frame, joint, point in its frame); none from
        // the world to a floating base.
        let floating = |i: usize| model.joints()[i].kind == JointType::FreeFlyer;
        let mut segments: Vec<(usize, Vec3, usize, Vec3)> = (1..model.njoints())
            .filter(|&i| !(parents[i] == 0 && floating(i)))
            .map(|i| (parents[i], Vec3::zeros(), i, Vec3::zeros()))
            .collect();
        for f in model.frames() {
            let leaf = !parents.contains(&f.parent_joint);
            if leaf && f.placement.translation.norm() > 1e-3 && f.parent_joint > 0 {
                segments.push((f.parent_joint, Vec3::zeros(), f.parent_joint, f.placement.translation));
            }
        }
        let lengths: Vec<f64> = segments
            .iter()
            .map(|&(p, a, c, b)| {
                let o = &joints[0];
                (o[c].act_point(&b) - o[p].act_point(&a)).norm()
            })
            .collect();
        let longest = lengths.iter().copied().fold(0.0, f64::max);
        let radius = (0.08 * longest).clamp(0.01, 0.05);
        let mut added = 0;
        // A floating base, and a body that ends no segment: the box of its inertia.
        for i in 1..model.njoints() {
            let carries = segments
                .iter()
                .zip(&lengths)
                .any(|(&(p, _, c, _), &len)| len >= 1e-6 && (p == i || c == i));
            if carries && !floating(i) {
                continue;
            }
            if let Some((shape, local)) = inertia_box(&model.inertias()[i]) {
                self.bodies.push(Body {
                    name: format!("body of joint {i}"),
                    shape,
                    color: SKELETON_COLOR,
                    poses: joints.iter().map(|o| Pose::from_se3(&o[i].compose(&local))).collect(),
                });
                added += 1;
            }
        }
        for (&(p, a, c, b), &len) in segments.iter().zip(&lengths) {
            if len < 1e-6 {
                continue;
            }
            let poses = joints
                .iter()
                .map(|o| segment_pose(&o[p].act_point(&a), &o[c].act_point(&b)))
                .collect();
            self.bodies.push(Body {
                name: format!("segment {p}-{c}"),
                shape: Shape::Capsule { radius, length: len },
                color: SKELETON_COLOR,
                poses,
            });
            added += 1;
        }
        added
    }

    /// Adds a moving body of `shape` with one pose per frame (coloured like a robot).
    pub fn add_body(&mut self, name: impl Into<String>, shape: Shape, poses: Vec<Pose>) {
        self.bodies.push(Body {
            name: name.into(),
            shape,
            color: ROBOT_COLOR,
            poses,
        });
    }

    /// Adds a target: a translucent green sphere at `p`.
    pub fn add_target(&mut self, p: [f64; 3], radius: f64) {
        self.markers.push(Marker {
            shape: Shape::Sphere { radius },
            color: TARGET_COLOR,
            alpha: 0.6,
            pose: Pose::at(p),
        });
    }

    /// Adds an obstacle of `shape` at `pose`: translucent red.
    pub fn add_obstacle(&mut self, shape: Shape, pose: Pose) {
        self.markers.push(Marker {
            shape,
            color: OBSTACLE_COLOR,
            alpha: 0.45,
            pose,
        });
    }

    /// The number of frames (that of the bodies; 1 without bodies).
    pub fn frames(&self) -> usize {
        self.bodies.first().map_or(1, |b| b.poses.len())
    }

    fn check(&self) -> Result<()> {
        let invalid = |m: String| Err(Error::Invalid(format!("viewer: {m}")));
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return invalid(format!("time step {} is not positive", self.dt));
        }
        let n = self.frames();
        if n == 0 {
            return invalid("no frames".into());
        }
        for b in &self.bodies {
            if b.poses.len() != n {
                return invalid(format!("body `{}` has {} poses for {n} frames", b.name, b.poses.len()));
            }
            let finite = b.poses.iter().all(|p| p.flat().iter().all(|v| v.is_finite()));
            if !finite || !b.shape.numbers().iter().all(|v| v.is_finite()) {
                return invalid(format!("body `{}` has non-finite numbers", b.name));
            }
        }
        if !self.arrows.is_empty() && self.arrows.len() != n {
            return invalid(format!("{} frames of arrows for {n} frames", self.arrows.len()));
        }
        Ok(())
    }

    /// Every point of the bodies' poses and the markers (for the camera and the ground).
    fn points(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let bodies = self.bodies.iter().flat_map(|b| b.poses.iter().map(|p| p.translation));
        bodies.chain(self.markers.iter().map(|m| m.pose.translation))
    }

    /// The scene as the page's JSON.
    fn json(&self) -> Value {
        let (lo, hi) = self
            .points()
            .fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
                ([0, 1, 2].map(|i| lo[i].min(p[i])), [0, 1, 2].map(|i| hi[i].max(p[i])))
            });
        let (lo, hi) = if lo[0] <= hi[0] { (lo, hi) } else { ([0.0; 3], [0.0; 3]) };
        let centre = [0, 1, 2].map(|i| 0.5 * (lo[i] + hi[i]));
        let extent = [0, 1, 2]
            .map(|i| hi[i] - lo[i])
            .iter()
            .copied()
            .fold(0.0, f64::max)
            .max(0.3);
        json!({
            "title": self.title,
            "dt": self.dt,
            "frames": self.frames(),
            "bodies": self.bodies.iter().map(|b| json!({
                "shape": b.shape.json(),
                "color": b.color,
                "poses": b.poses.iter().map(|p| p.flat().map(round)).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "markers": self.markers.iter().map(|m| json!({
                "shape": m.shape.json(), "color": m.color, "alpha": m.alpha, "pose": m.pose.flat(),
            })).collect::<Vec<_>>(),
            "arrows": self.arrows.iter().map(|frame| frame.iter().map(|a| json!({
                "from": a.from, "vector": a.vector,
            })).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "camera": {"target": centre, "distance": 1.4 * extent + 0.3, "yaw": 0.9, "pitch": 0.45},
            "ground": {"z": lo[2].min(0.0), "half": (1.2 * extent).max(0.5)},
        })
    }
}

/// The box with the rotational inertia of `inertia` about its centre of mass (sides
/// `sqrt(6 (I_j + I_k - I_i) / m)` along the principal axes), placed at the centre of
/// mass on those axes; `None` without mass.
fn inertia_box(inertia: &gharial_multibody::spatial::Inertia) -> Option<(Shape, Se3)> {
    let m = inertia.mass;
    if m.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let c = inertia.first_moment / m;
    let about_com = inertia.rotational - m * (Mat3::identity() * c.norm_squared() - c * c.transpose());
    let eig = about_com.symmetric_eigen();
    let l = eig.eigenvalues;
    let side = |i: usize, j: usize, k: usize| (6.0 * (l[j] + l[k] - l[i]) / m).max(1e-6).sqrt();
    let size = [side(0, 1, 2), side(1, 2, 0), side(2, 0, 1)];
    let mut r = eig.eigenvectors;
    if r.determinant() < 0.0 {
        r.column_mut(2).neg_mut();
    }
    Some((
        Shape::Box { size },
        Se3 {
            rotation: r,
            translation: c,
        },
    ))
}

/// The pose of a capsule from `a` to `b`: centred between them, z along `b - a`.
fn segment_pose(a: &Vec3, b: &Vec3) -> Pose {
    let d = b - a;
    let z = d / d.norm().max(1e-12);
    let helper = if z.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    let x = helper.cross(&z).normalize();
    let y = z.cross(&x);
    let r = Mat3::from_columns(&[x, y, z]);
    let c = 0.5 * (a + b);
    Pose {
        rotation: [0, 1, 2].map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]),
        translation: [c.x, c.y, c.z],
    }
}

/// The viewer page of `scene`: one HTML document with everything inline.
///
/// # Errors
/// A non-positive time step, no frames, bodies with pose counts other than the frames,
/// non-finite numbers, or arrows for another number of frames.
pub fn page(scene: &Scene) -> Result<String> {
    scene.check()?;
    // `</` cannot close the script element from inside the JSON.
    let data = scene.json().to_string().replace("</", "<\\/");
    let title = html_escape(&scene.title);
    Ok(include_str!("page.html")
        .replace("__TITLE__", &title)
        .replace("__SCRIPT__", include_str!("viewer.js"))
        .replace("__SCENE__", &data))
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
