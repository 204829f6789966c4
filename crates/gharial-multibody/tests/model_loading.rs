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
    // A contact that the robot cannot realize gives a clear error, not NaN.
    let c = vec![ContactModel::from_frame(&m, ContactType::Contact6D, 3, ReferenceFrame::Local).unwrap()];
    let mut cd = ContactData::new(&m, &c).unwrap();
    assert!(matches!(
        constraint_dynamics(&m, &mut d, &c, &mut cd, &[0.0], &[0.0], &[0.0]),
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
