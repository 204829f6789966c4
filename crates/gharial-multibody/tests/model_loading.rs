//! URDF/SRDF loading: malformed inputs give errors naming the element, SRDF rotor
//! parameters give the armature, input validation of the algorithms.

use gharial_multibody::*;
use std::path::Path;

fn robots() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/robots")
}

const TWO_LINKS: &str = r#"<robot name="r">
  <link name="base"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="arm"><inertial><origin xyz="0 0 0.5"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><geometry><mesh filename="package://pkg/arm.stl" scale="1 1 2"/></geometry></visual></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="2"/></joint>
</robot>"#;

fn element_error(xml: &str) -> (String, String) {
    match Model::from_urdf_str(xml, RootJoint::Fixed) {
        Err(Error::Element { element, message, .. }) => (element, message),
        other => panic!("expected an element error, got {other:?}"),
    }
}

#[test]
fn valid_urdf_loads_with_visuals() {
    let m = Model::from_urdf_str(TWO_LINKS, RootJoint::Fixed).unwrap();
    assert_eq!((m.nq(), m.nv(), m.njoints(), m.nframes()), (1, 1, 2, 4));
    assert_eq!(m.joints()[1].kind, JointType::Revolute(Axis::Y));
    assert_eq!(m.velocity_limit, vec![2.0]);
    assert!(matches!(&m.visuals[0].geometry, Geometry::Mesh { filename, .. } if filename == "package://pkg/arm.stl"));
    let ur5 = Model::from_urdf_file(robots().join("ur5_robot.urdf"), RootJoint::Fixed).unwrap();
    assert!(
        ur5.visuals
            .iter()
            .any(|v| matches!(&v.geometry, Geometry::Mesh { filename, .. } if filename.starts_with("package://")))
    );
}

#[test]
fn malformed_urdf_names_the_element() {
    assert!(matches!(
        Model::from_urdf_str("<robot><link name=", RootJoint::Fixed),
        Err(Error::Xml { .. })
    ));
    let (e, msg) = element_error(&TWO_LINKS.replace(r#"<mass value="2"/>"#, r#"<mass value="heavy"/>"#));
    assert_eq!(e, "mass");
    assert!(msg.contains("heavy"), "{msg}");
    let (e, msg) = element_error(&TWO_LINKS.replace(r#"<parent link="base"/>"#, r#"<parent link="nowhere"/>"#));
    assert_eq!(e, "joint");
    assert!(msg.contains("nowhere"), "{msg}");
    let (e, _) = element_error(&TWO_LINKS.replace(r#"type="revolute""#, r#"type="screw""#));
    assert_eq!(e, "joint");
    let (e, _) = element_error(&TWO_LINKS.replace(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="0 1"/>"#));
    assert_eq!(e, "axis");
    let (e, msg) = element_error(&TWO_LINKS.replace(r#"<child link="arm"/>"#, ""));
    assert!(msg.contains("child"), "{msg}");
    assert_eq!(e, "joint");
    let (e, msg) =
        element_error(&TWO_LINKS.replace(r#"<link name="arm">"#, r#"<link name="arm2"></link><link name="arm">"#));
    assert_eq!(e, "robot");
    assert!(msg.contains("root"), "{msg}");
    let (e, _) = element_error(&TWO_LINKS.replace(r#"effort="10" "#, ""));
    assert_eq!(e, "limit");
    // Limits that no joint can have: lower above upper, a negative effort or velocity.
    for (from, to, what) in [
        (r#"effort="10" "#, r#"effort="-10" "#, "effort"),
        (r#"velocity="2""#, r#"velocity="-2""#, "velocity"),
    ] {
        let (e, msg) = element_error(&TWO_LINKS.replace(from, to));
        assert_eq!(e, "limit");
        assert!(msg.contains(what) && msg.contains("negative"), "{msg}");
    }
    let swapped = TWO_LINKS.replace(r#"lower="-1" upper="1""#, r#"lower="1" upper="-1""#);
    let (e, msg) = element_error(&swapped);
    assert!(e == "limit" && msg.contains("exceeds"), "{e}: {msg}");
    let (e, _) = element_error("<model/>");
    assert_eq!(e, "model");
    assert!(matches!(
        Model::from_urdf_file(robots().join("missing.urdf"), RootJoint::Fixed),
        Err(Error::Io { .. })
    ));
}

#[test]
fn srdf_rotor_parameters_set_the_armature() {
    let mut m = Model::from_urdf_str(TWO_LINKS, RootJoint::Fixed).unwrap();
    let mut plain = m.clone();
    m.load_srdf_str(r#"<robot name="r"><rotor_params><joint name="j" mass="0.001" gear_ratio="10"/></rotor_params>
        <group_state name="up" group="all"><joint name="j" value="0.5"/><joint name="unknown" value="1"/></group_state></robot>"#)
        .unwrap();
    assert!((m.armature[0] - 0.1).abs() < 1e-15);
    assert_eq!(m.rotor_gear_ratio, vec![10.0]);
    assert_eq!(m.reference_configuration("up").unwrap(), &[0.5]);
    // tau(armature) − tau(no armature) = armature · a, and M gains armature on the diagonal.
    let (q, v, a) = ([0.3], [0.2], [1.5]);
    let mut d = m.create_data();
    let t1 = rnea(&m, &mut d, &q, &v, &a).unwrap()[0];
    let t0 = rnea(&plain, &mut plain.create_data(), &q, &v, &a).unwrap()[0];
    assert!((t1 - t0 - 0.1 * 1.5).abs() < 1e-12);
    let m1 = crba(&m, &mut d, &q).unwrap()[(0, 0)];
    let m0 = crba(&plain, &mut plain.create_data(), &q).unwrap()[(0, 0)];
    assert!((m1 - m0 - 0.1).abs() < 1e-12);
    let err =
        m.load_srdf_str(r#"<robot><rotor_params><joint name="j" mass="x" gear_ratio="1"/></rotor_params></robot>"#);
    assert!(
        matches!(err, Err(Error::Element { ref element, .. }) if element == "joint"),
        "{err:?}"
    );
    plain.armature[0] = 0.0;
    let solo_srdf = robots().join("solo.srdf");
    let mut solo = Model::from_urdf_file(robots().join("solo12.urdf"), RootJoint::FreeFlyer).unwrap();
    solo.load_srdf_file(solo_srdf).unwrap();
    assert_eq!(solo.reference_configuration("standing").unwrap()[2], 0.235);
    // Solo's SRDF on the UR5: none of its joints is there.
    let mut ur5 = Model::from_urdf_file(robots().join("ur5_robot.urdf"), RootJoint::Fixed).unwrap();
    let e = ur5.load_srdf_file(robots().join("solo.srdf")).err().unwrap();
    assert!(e.to_string().contains("another robot"), "{e}");
    assert!(ur5.reference_configurations.is_empty());
}

#[test]
fn algorithms_validate_their_inputs() {
    let m = Model::from_urdf_str(TWO_LINKS, RootJoint::Fixed).unwrap();
    let mut d = m.create_data();
    assert!(matches!(
        rnea(&m, &mut d, &[0.0, 1.0], &[0.0], &[0.0]),
        Err(Error::Dimension { .. })
    ));
    assert!(matches!(
        aba(&m, &mut d, &[0.0], &[f64::NAN], &[0.0]),
        Err(Error::NotFinite { .. })
    ));
    let other = Model::from_urdf_file(robots().join("ur5_robot.urdf"), RootJoint::Fixed).unwrap();
    let mut wrong = other.create_data();
    assert!(matches!(crba(&m, &mut wrong, &[0.0]), Err(Error::Invalid(_))));
    assert!(frame_velocity(&m, &d, 99, ReferenceFrame::Local).is_err());
    assert!(joint_velocity(&d, 99, ReferenceFrame::Local).is_err());
    assert!(ContactModel::from_frame(&m, ContactType::Contact3D, 0, ReferenceFrame::Local).is_err());
    assert!(ContactModel::from_frame(&m, ContactType::Contact3D, 3, ReferenceFrame::World).is_err());
    // More constraint rows than degrees of freedom: refused when the contact data is made.
    let c = vec![ContactModel::from_frame(&m, ContactType::Contact6D, 3, ReferenceFrame::Local).unwrap()];
    assert!(matches!(ContactData::new(&m, &c), Err(Error::Invalid(ref s)) if s.contains("6 constraint rows")));
    // Two contacts on one rigid body (the same point twice, or two points of a link)
    // have dependent rows: refused when the contact data is made.
    let tool = other.frame_id("tool0").unwrap();
    let c = vec![ContactModel::from_frame(&other, ContactType::Contact3D, tool, ReferenceFrame::Local).unwrap(); 2];
    let e = ContactData::new(&other, &c).err().unwrap();
    assert!(e.to_string().contains("contacts 0 and 1 both move with joint"), "{e}");
    let mut off = c.clone();
    off[1].placement.translation[0] += 0.05;
    assert!(ContactData::new(&other, &off).is_err());
    // A contact the robot cannot realize (a point of the first link, which turns about
    // one axis: Jc has rank 1) gives a clear error, not NaN.
    let mut c = vec![c[0].clone()];
    c[0].joint = 1;
    c[0].placement.translation[0] = 0.1;
    let mut cd = ContactData::new(&other, &c).unwrap();
    let mut d = other.create_data();
    let (q, z) = (vec![0.3; 6], vec![0.0; 6]);
    assert!(matches!(
        constraint_dynamics(&other, &mut d, &c, &mut cd, &q, &z, &z),
        Err(Error::NotPositiveDefinite { .. })
    ));
}

#[test]
fn data_of_another_tree_is_rejected() {
    // Same numbers of joints, dofs and frames, different trees: a chain and a fork.
    let build = |fork: bool| {
        let mut m = Model::new("tree");
        let z = spatial::Se3::identity();
        let kind = JointType::Revolute(Axis::Z);
        let lim = || JointLimits::unbounded(&kind);
        let j1 = m.add_joint(0, kind, z, "j1", lim()).unwrap();
        let j2 = m.add_joint(j1, kind, z, "j2", lim()).unwrap();
        m.add_joint(if fork { j1 } else { j2 }, kind, z, "j3", lim()).unwrap();
        for j in 1..4 {
            let y = spatial::Inertia::from_com(1.0, spatial::Vec3::new(0.1, 0.0, 0.0), spatial::Mat3::identity());
            m.set_inertia(j, y).unwrap();
        }
        m
    };
    let (chain, fork) = (build(false), build(true));
    let mut d = chain.create_data();
    assert!(crba(&chain, &mut d, &[0.1, 0.2, 0.3]).is_ok());
    assert!(matches!(crba(&fork, &mut d, &[0.1, 0.2, 0.3]), Err(Error::Invalid(_))));
}

/// A URDF chain of `n` links joined by joints of `kind` (revolute joints alternate their
/// axes), built as a string.
fn chain_urdf(n: usize, kind: &str) -> String {
    let mut s = String::from("<robot name=\"chain\">\n");
    let inertial = r#"<inertial><origin xyz="0 0 0.05"/><mass value="0.1"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>"#;
    for k in 0..n {
        s += &format!("<link name=\"l{k}\">{inertial}</link>\n");
        if k > 0 {
            let axis = ["1 0 0", "0 1 0", "0 0 1"][k % 3];
            s += &format!(
                "<joint name=\"j{k}\" type=\"{kind}\"><parent link=\"l{}\"/><child link=\"l{k}\"/><origin xyz=\"0 0 0.1\"/><axis xyz=\"{axis}\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>\n",
                k - 1
            );
        }
    }
    s + "</robot>\n"
}

/// A 20,000-joint chain (7 MB of URDF) used to abort on quadratic memory: it is now
/// refused with `ModelTooLarge` naming the first joint beyond the limit, and a chain at
/// the limit loads and runs.
#[test]
fn deep_chains_are_limited_not_aborted() {
    let xml = chain_urdf(20_001, "revolute");
    assert!(xml.len() > 6_000_000);
    match Model::from_urdf_str(&xml, RootJoint::Fixed) {
        Err(Error::ModelTooLarge { joint, nv, max }) => {
            assert_eq!((nv, max), (Model::MAX_NV + 1, Model::MAX_NV));
            assert_eq!(joint, format!("j{}", Model::MAX_NV + 1));
        }
        other => panic!("expected ModelTooLarge, got {other:?}"),
    }
    // A free-flyer root counts its 6 dofs.
    let at_limit = chain_urdf(Model::MAX_NV - 6 + 1, "revolute");
    let m = Model::from_urdf_str(&at_limit, RootJoint::FreeFlyer).unwrap();
    assert_eq!(m.nv(), Model::MAX_NV);
    assert!(matches!(
        Model::from_urdf_str(&chain_urdf(Model::MAX_NV - 6 + 2, "revolute"), RootJoint::FreeFlyer),
        Err(Error::ModelTooLarge { .. })
    ));
    // The deepest model runs: the ABA's accelerations reproduce tau through the RNEA.
    let mut d = m.create_data();
    let nv = m.nv();
    let mut q = neutral(&m);
    for k in 7..m.nq() {
        q[k] = 0.3 * ((k as f64) * 0.7).sin();
    }
    let v: Vec<f64> = (0..nv).map(|k| 0.1 * ((k as f64) * 0.3).cos()).collect();
    let tau: Vec<f64> = (0..nv).map(|k| 0.01 * ((k as f64) * 1.1).sin()).collect();
    let ddq = aba(&m, &mut d, &q, &v, &tau).unwrap().to_vec();
    // Relative to the torques of the 200 m tall chain's weight (about 1e5 N·m).
    let scale = nonlinear_effects(&m, &mut d, &q, &v)
        .unwrap()
        .iter()
        .fold(0.0f64, |s, x| s.max(x.abs()));
    let back = rnea(&m, &mut d, &q, &v, &ddq).unwrap();
    let err = back.iter().zip(&tau).fold(0.0f64, |e, (a, b)| e.max((a - b).abs()));
    assert!(
        scale > 1e4 && err < 1e-11 * scale,
        "rnea(aba(tau)) − tau = {err:e}, scale {scale:e}"
    );
    // Building by hand is refused the same way, leaving the model unchanged.
    let mut m = Model::new("hand");
    let kind = JointType::Revolute(Axis::Z);
    let mut parent = 0;
    for k in 0..Model::MAX_NV {
        parent = m
            .add_joint(
                parent,
                kind,
                spatial::Se3::identity(),
                &format!("j{k}"),
                JointLimits::unbounded(&kind),
            )
            .unwrap();
    }
    let r = m.add_joint(
        parent,
        kind,
        spatial::Se3::identity(),
        "extra",
        JointLimits::unbounded(&kind),
    );
    assert!(
        matches!(r, Err(Error::ModelTooLarge { ref joint, .. }) if joint == "extra"),
        "{r:?}"
    );
    assert_eq!((m.nv(), m.njoints()), (Model::MAX_NV, Model::MAX_NV + 1));
}

/// Depth without degrees of freedom is not limited: 20,000 links welded in a chain load
/// (one body, 40,000 frames), with no recursion on the depth.
#[test]
fn deep_fixed_chains_load() {
    let m = Model::from_urdf_str(&chain_urdf(20_000, "fixed"), RootJoint::FreeFlyer).unwrap();
    assert_eq!((m.nv(), m.njoints(), m.nframes()), (6, 2, 2 + 2 * 20_000 - 1));
    assert!((m.total_mass() - 2000.0).abs() < 1e-9);
    let mut d = m.create_data();
    forward_kinematics(&m, &mut d, &neutral(&m), &[0.0; 6], &[0.0; 6]).unwrap();
    update_frame_placements(&m, &mut d).unwrap();
    let tip = m.frame_id("l19999").unwrap();
    assert!((d.frame_placement(tip).translation.z - 1999.9).abs() < 1e-6);
}

fn unit_inertia(mass: f64) -> spatial::Inertia {
    spatial::Inertia::from_com(
        mass,
        spatial::Vec3::new(0.1, 0.0, 0.0),
        spatial::Mat3::identity() * 0.01,
    )
}

fn invalid_inertia(r: Result<()>, what: &str) {
    assert!(
        matches!(&r, Err(Error::InvalidInertia { what: w, message }) if w.contains(what) && !message.is_empty()),
        "{r:?}"
    );
}

#[test]
fn invalid_inertias_are_refused_where_they_enter() {
    let mut m = Model::from_urdf_str(TWO_LINKS, RootJoint::Fixed).unwrap();
    let before = m.inertias()[1];
    let mut nan = unit_inertia(1.0);
    nan.rotational[(1, 1)] = f64::NAN;
    invalid_inertia(m.set_inertia(1, nan), "joint `j`");
    invalid_inertia(m.set_inertia(1, unit_inertia(-1.0)), "joint `j`");
    // Positive mass, but a negative principal moment about the centre of mass.
    let indefinite = spatial::Inertia::from_com(
        1.0,
        spatial::Vec3::zeros(),
        spatial::Mat3::from_diagonal(&spatial::Vec3::new(1.0, 1.0, -0.1)),
    );
    invalid_inertia(m.set_inertia(1, indefinite), "joint `j`");
    let mut asym = unit_inertia(1.0);
    asym.rotational[(0, 1)] += 0.5;
    invalid_inertia(m.set_inertia(1, asym), "joint `j`");
    let mut massless_offset = spatial::Inertia::zero();
    massless_offset.first_moment.x = 0.3;
    invalid_inertia(m.set_inertia(1, massless_offset), "joint `j`");
    let place = spatial::Se3::identity();
    invalid_inertia(m.append_body_to_joint(1, &indefinite, &place), "joint `j`");
    // Overflow of the transformed inertia.
    let far = spatial::Se3::new(spatial::Mat3::identity(), spatial::Vec3::new(1e200, 0.0, 0.0));
    invalid_inertia(m.append_body_to_joint(1, &unit_inertia(1e200), &far), "joint `j`");
    assert_eq!(m.inertias()[1], before, "a refused inertia changed the model");
    // Valid: the all-zero dummy body, a point mass, round-off below the tolerance.
    m.set_inertia(1, spatial::Inertia::zero()).unwrap();
    m.set_inertia(
        1,
        spatial::Inertia::from_com(2.0, spatial::Vec3::new(0.0, 0.0, 1.0), spatial::Mat3::zeros()),
    )
    .unwrap();
    let nearly = spatial::Mat3::from_diagonal(&spatial::Vec3::new(1.0, 1.0, -1e-9));
    m.set_inertia(1, spatial::Inertia::from_com(1.0, spatial::Vec3::zeros(), nearly))
        .unwrap();
    m.append_body_to_joint(1, &unit_inertia(1.0), &place).unwrap();
    // The URDF loader names the link.
    let bad = TWO_LINKS.replace(r#"ixx="0.1" ixy="0""#, r#"ixx="0.1" ixy="2""#);
    match Model::from_urdf_str(&bad, RootJoint::Fixed) {
        Err(Error::Element {
            element, name, message, ..
        }) => {
            assert_eq!((element.as_str(), name.as_str()), ("link", " name=\"arm\""));
            assert!(message.contains("positive semidefinite"), "{message}");
        }
        other => panic!("expected an error naming the link, got {other:?}"),
    }
    let negative = TWO_LINKS.replace(r#"<mass value="2"/>"#, r#"<mass value="-2"/>"#);
    assert!(matches!(
        Model::from_urdf_str(&negative, RootJoint::Fixed),
        Err(Error::Element { ref name, ref message, .. }) if name.contains("arm") && message.contains("negative mass")
    ));
    // Links without <inertial> (zero inertia) stay legal.
    let dummy = TWO_LINKS.replace(
        r#"<link name="base"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>"#,
        r#"<link name="base"/>"#,
    );
    assert!(Model::from_urdf_str(&dummy, RootJoint::Fixed).is_ok());
}

const MIMIC: &str = r#"<robot name="gripper">
  <link name="base"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="left"><inertial><mass value="0.1"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>
  <link name="right"><inertial><mass value="0.1"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>
  <joint name="finger_l" type="prismatic"><parent link="base"/><child link="left"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="10" velocity="1"/></joint>
  <joint name="finger_r" type="prismatic"><parent link="base"/><child link="right"/><axis xyz="0 -1 0"/><limit lower="0" upper="0.04" effort="10" velocity="1"/>
    <mimic joint="finger_l" multiplier="2" offset="-0.01"/></joint>
</robot>"#;

#[test]
fn mimic_joints_are_recorded_or_refused() {
    // Default: an independent joint (Pinocchio's mimic=false), the relation recorded.
    let m = Model::from_urdf_str(MIMIC, RootJoint::Fixed).unwrap();
    assert_eq!(m.nv(), 2);
    let (l, r) = (m.joint_id("finger_l").unwrap(), m.joint_id("finger_r").unwrap());
    assert_eq!(
        m.mimic_joints(),
        &[MimicJoint {
            joint: r,
            mimicked: l,
            multiplier: 2.0,
            offset: -0.01
        }]
    );
    let opts = UrdfOptions {
        mimic: MimicPolicy::Refuse,
    };
    match Model::from_urdf_str_with(MIMIC, RootJoint::Fixed, &opts) {
        Err(Error::Element {
            element, name, message, ..
        }) => {
            assert_eq!((element.as_str(), name.as_str()), ("joint", " name=\"finger_r\""));
            assert!(message.contains("mimic") && message.contains("finger_l"), "{message}");
        }
        other => panic!("expected a refusal, got {other:?}"),
    }
    // Without mimic joints Refuse loads.
    assert!(Model::from_urdf_str_with(TWO_LINKS, RootJoint::Fixed, &opts).is_ok());
    let defaults = MIMIC.replace(r#" multiplier="2" offset="-0.01""#, "");
    let m = Model::from_urdf_str(&defaults, RootJoint::Fixed).unwrap();
    assert_eq!((m.mimic_joints()[0].multiplier, m.mimic_joints()[0].offset), (1.0, 0.0));
    // Invalid mimic elements.
    for (bad, needle) in [
        (
            MIMIC.replace(r#"joint="finger_l" multiplier"#, r#"joint="ghost" multiplier"#),
            "ghost",
        ),
        (MIMIC.replace(r#"multiplier="2""#, r#"multiplier="inf""#), "multiplier"),
        (MIMIC.replace(r#"offset="-0.01""#, r#"offset="x""#), "offset"),
        (
            MIMIC.replace(r#"joint="finger_l" multiplier"#, r#"joint="finger_r" multiplier"#),
            "itself",
        ),
        (MIMIC.replace(r#"<mimic joint="finger_l""#, r#"<mimic"#), "joint"),
    ] {
        let e = Model::from_urdf_str(&bad, RootJoint::Fixed).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
    }
}

/// solo12's URDF without its hind legs (links and joints whose names start with HL_ or
/// HR_): a reduced model, as one arm of a humanoid.
fn solo_front_legs() -> String {
    let text = std::fs::read_to_string(robots().join("solo12.urdf")).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let mut cut: Vec<std::ops::Range<usize>> = doc
        .root_element()
        .children()
        .filter(|n| {
            n.is_element()
                && n.attribute("name")
                    .is_some_and(|s| s.starts_with("HL_") || s.starts_with("HR_"))
        })
        .map(|n| n.range())
        .collect();
    cut.reverse();
    let mut out = text.clone();
    for r in cut {
        out.replace_range(r, "");
    }
    out
}

#[test]
fn srdf_of_the_whole_robot_reads_into_a_reduced_model() {
    let full_srdf = std::fs::read_to_string(robots().join("solo.srdf")).unwrap();
    let legs = ["FL", "FR", "HL", "HR"];
    let rotors: String = legs
        .iter()
        .enumerate()
        .flat_map(|(l, leg)| {
            ["HAA", "HFE", "KFE"].iter().enumerate().map(move |(k, j)| {
                format!(
                    r#"<joint name="{leg}_{j}" mass="{}" gear_ratio="9"/>"#,
                    1e-6 * (1 + 3 * l + k) as f64
                )
            })
        })
        .collect();
    let srdf = full_srdf.replace("</robot>", &format!("<rotor_params>{rotors}</rotor_params></robot>"));
    let mut full = Model::from_urdf_file(robots().join("solo12.urdf"), RootJoint::FreeFlyer).unwrap();
    full.load_srdf_str(&srdf).unwrap();
    let mut reduced = Model::from_urdf_str(&solo_front_legs(), RootJoint::FreeFlyer).unwrap();
    assert_eq!((reduced.nq(), reduced.nv()), (13, 12));
    reduced.load_srdf_str(&srdf).unwrap();
    // Every joint of the reduced model has the whole robot's values, joint by joint.
    for name in ["standing", "straight_standing"] {
        let (qf, qr) = (
            full.reference_configuration(name).unwrap(),
            reduced.reference_configuration(name).unwrap(),
        );
        for (id, jm) in reduced.joints().iter().enumerate().skip(1) {
            let jf = full.joints()[full.joint_id(&reduced.joint_names()[id]).unwrap()];
            assert_eq!(
                &qr[jm.idx_q..jm.idx_q + jm.nq],
                &qf[jf.idx_q..jf.idx_q + jf.nq],
                "{name}"
            );
        }
        assert_eq!(qr[2], 0.235);
    }
    let fl_hfe = reduced.joints()[reduced.joint_id("FL_HFE").unwrap()].idx_v;
    assert_eq!(reduced.rotor_inertia[fl_hfe], 2e-6);
    assert!((reduced.armature[fl_hfe] - 2e-6 * 81.0).abs() < 1e-18);
    for (id, jm) in reduced.joints().iter().enumerate().skip(2) {
        let jf = full.joints()[full.joint_id(&reduced.joint_names()[id]).unwrap()];
        assert_eq!(reduced.armature[jm.idx_v], full.armature[jf.idx_v]);
        assert_eq!(reduced.rotor_gear_ratio[jm.idx_v], 9.0);
    }
    // Only what is asked for is read.
    let mut refs_only = Model::from_urdf_str(&solo_front_legs(), RootJoint::FreeFlyer).unwrap();
    let options = SrdfOptions {
        reference_configurations: true,
        rotor_parameters: false,
    };
    refs_only.load_srdf_str_with(&srdf, &options).unwrap();
    assert!(refs_only.armature.iter().all(|&a| a == 0.0));
    assert!(refs_only.rotor_inertia.iter().all(|&a| a == 0.0));
    assert_eq!(refs_only.reference_configurations.len(), 2);
    let mut rotors_only = Model::from_urdf_str(&solo_front_legs(), RootJoint::FreeFlyer).unwrap();
    let options = SrdfOptions {
        reference_configurations: false,
        rotor_parameters: true,
    };
    rotors_only.load_srdf_str_with(&srdf, &options).unwrap();
    assert!(rotors_only.reference_configurations.is_empty());
    assert_eq!(rotors_only.armature, reduced.armature);
}

#[test]
fn srdf_errors_name_the_element_and_leave_the_model_unchanged() {
    let mut m = Model::from_urdf_file(robots().join("solo12.urdf"), RootJoint::FreeFlyer).unwrap();
    m.load_srdf_file(robots().join("solo.srdf")).unwrap();
    let before = m.clone();
    let cases = [
        (
            r#"<group_state name="s"><joint name="root_joint" value="0 0 1"/></group_state>"#,
            "expected 7 values",
        ),
        (
            r#"<group_state name="s"><joint name="root_joint" value="0 0 1 0 0 0 0"/></group_state>"#,
            "zero quaternion",
        ),
        (
            r#"<group_state name="s"><joint name="FL_HAA" value="nan"/></group_state>"#,
            "finite",
        ),
        (
            r#"<rotor_params><joint name="root_joint" mass="1" gear_ratio="1"/></rotor_params>"#,
            "nv = 6",
        ),
        (
            r#"<rotor_params><joint name="FL_HAA" mass="-1" gear_ratio="1"/></rotor_params>"#,
            "negative",
        ),
        (
            r#"<rotor_params><joint name="FL_HAA" mass="1e200" gear_ratio="1e200"/></rotor_params>"#,
            "overflows",
        ),
    ];
    for (body, needle) in cases {
        let xml = format!(
            r#"<robot name="solo"><group_state name="standing"><joint name="FL_HAA" value="1"/></group_state>{body}</robot>"#
        );
        let e = m.load_srdf_str(&xml).unwrap_err();
        assert!(
            matches!(e, Error::Element { .. }) && e.to_string().contains(needle),
            "{e}"
        );
        assert_eq!(m.reference_configurations, before.reference_configurations);
        assert_eq!(m.armature, before.armature);
    }
    // Non-unit quaternions are normalized; joints the model lacks are skipped even when
    // their values would be invalid.
    m.load_srdf_str(
        r#"<robot name="solo"><group_state name="tilted"><joint name="root_joint" value="0 0 0.3 0 0 2 2"/>
        <joint name="left_arm" value="not numbers"/></group_state></robot>"#,
    )
    .unwrap();
    let q = m.reference_configuration("tilted").unwrap();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    assert!((q[5] - h).abs() < 1e-15 && (q[6] - h).abs() < 1e-15, "{q:?}");
    assert_eq!(&q[7..], &neutral(&m)[7..]);
}

/// Joint axes with huge entries are normalized without overflow (1e300 squared used to
/// make the norm infinite and the axis zero).
#[test]
fn huge_joint_axes_are_normalized() {
    let m = Model::from_urdf_str(
        &TWO_LINKS.replace(r#"xyz="0 1 0""#, r#"xyz="1e300 -1e300 0""#),
        RootJoint::Fixed,
    )
    .unwrap();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    match m.joints()[1].kind {
        JointType::Revolute(Axis::Unaligned(a)) => {
            assert!((a - spatial::Vec3::new(h, -h, 0.0)).norm() < 1e-15, "{a:?}")
        }
        other => panic!("{other:?}"),
    }
    let tiny = Model::from_urdf_str(
        &TWO_LINKS.replace(r#"xyz="0 1 0""#, r#"xyz="0 3e-7 4e-7""#),
        RootJoint::Fixed,
    )
    .unwrap();
    assert_eq!(
        tiny.joints()[1].kind.unaligned_axis(),
        Some(spatial::Vec3::new(0.0, 0.6, 0.8))
    );
}

/// The model's public vectors that the algorithms read are checked, not indexed blindly.
#[test]
fn a_model_armature_of_the_wrong_length_is_an_error() {
    let mut m = Model::from_urdf_str(TWO_LINKS, RootJoint::Fixed).unwrap();
    let mut d = m.create_data();
    m.armature.clear();
    let r = rnea(&m, &mut d, &[0.1], &[0.0], &[0.0]);
    assert!(
        matches!(r, Err(Error::Dimension { ref what, expected: 1, got: 0 }) if what.contains("armature")),
        "{r:?}"
    );
}

/// Many group states on a large model: a clear error, not gigabytes.
#[test]
fn too_many_group_states_are_refused() {
    let mut m = Model::from_urdf_str(&chain_urdf(2000, "revolute"), RootJoint::Fixed).unwrap();
    let states: String = (0..40_000).map(|k| format!("<group_state name=\"s{k}\"/>")).collect();
    let r = m.load_srdf_str(&format!("<robot name=\"chain\">{states}</robot>"));
    assert!(
        matches!(r, Err(Error::Element { ref message, .. }) if message.contains("40000 group states")),
        "{r:?}"
    );
    assert!(m.reference_configurations.is_empty());
    let states: String = (0..100).map(|k| format!("<group_state name=\"s{k}\"/>")).collect();
    m.load_srdf_str(&format!("<robot name=\"chain\">{states}</robot>"))
        .unwrap();
    assert_eq!(m.reference_configurations.len(), 100);
}
