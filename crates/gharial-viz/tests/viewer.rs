//! The viewer's scene from real solutions: the UR5's skeleton ends where the solution puts
//! its tool, meshes found on the search path replace the skeleton, and the page embeds a
//! scene that reads back; bad scenes are errors.

use std::path::PathBuf;

use gharial::solvers::proxddp::ProxDdp;
use gharial::solvers::{InitialGuess, Solver};
use gharial_multibody::{Model, RootJoint};
use gharial_problems::robots::{DOUBLE_PENDULUM_URDF, UR5_URDF};
use gharial_viz::Error;
use gharial_viz::viewer::{Body, MeshSearch, Pose, Scene, Shape, page};

fn solve(name: &str) -> (Vec<Vec<f64>>, f64) {
    let ex = gharial_problems::build(name).unwrap();
    let mut s = ProxDdp::new(ex.proxddp.clone());
    s.setup(&ex.problem).unwrap();
    let sol = s.solve(&ex.problem, InitialGuess::primal(&ex.xs0, &ex.us0)).unwrap();
    assert!(sol.status.converged());
    (sol.xs.clone(), ex.dt.unwrap())
}

/// The far end of a capsule (its `+z` end).
fn capsule_end(pose: &Pose, length: f64) -> [f64; 3] {
    let r = &pose.rotation;
    [0, 1, 2].map(|i| pose.translation[i] + 0.5 * length * r[i][2])
}

#[test]
fn the_ur5_skeleton_ends_at_the_reached_target() {
    let (xs, dt) = solve("ur5");
    let model = Model::from_urdf_str(UR5_URDF, RootJoint::Fixed).unwrap();
    let qs: Vec<Vec<f64>> = xs.iter().map(|x| x[..model.nq()].to_vec()).collect();
    let mut scene = Scene::new("ur5", dt);
    let report = scene.add_robot(&model, &qs, &MeshSearch::default()).unwrap();
    // Its meshes are COLLADA files that no search path holds here: all stand-ins.
    assert_eq!((report.visuals, report.missing.len()), (0, 7), "{report:?}");
    assert!(report.capsules >= 6);
    assert!(scene.bodies.iter().all(|b| b.poses.len() == xs.len()));
    // The capsule to tool0 ends at the target (0.3, 0.5, 0.5) that the solve reached.
    let target = [0.3, 0.5, 0.5];
    let closest = scene
        .bodies
        .iter()
        .filter_map(|b| match b.shape {
            Shape::Capsule { length, .. } => Some(capsule_end(b.poses.last().unwrap(), length)),
            _ => None,
        })
        .map(|p| (0..3).map(|i| (p[i] - target[i]).powi(2)).sum::<f64>().sqrt())
        .fold(f64::INFINITY, f64::min);
    assert!(closest < 1e-2, "no capsule ends at the target: {closest}");
}

/// A binary STL of one triangle.
fn triangle_stl(size: f32) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&[0u8; 12]);
    for v in [[0.0, 0.0, 0.0], [size, 0.0, 0.0], [0.0, 0.0, -size]] {
        for c in v {
            b.extend_from_slice(&f32::to_le_bytes(c));
        }
    }
    b.extend_from_slice(&[0u8; 2]);
    b
}

#[test]
fn meshes_on_the_search_path_replace_the_skeleton() {
    let root = std::env::temp_dir().join(format!("gharial-viewer-meshes-{}", std::process::id()));
    let dir: PathBuf = root.join("example-robot-data/robots/double_pendulum_description/meshes");
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["base_link", "link1", "link2"] {
        std::fs::write(dir.join(format!("{name}.stl")), triangle_stl(0.1)).unwrap();
    }
    let model = Model::from_urdf_str(DOUBLE_PENDULUM_URDF, RootJoint::Fixed).unwrap();
    let qs = vec![vec![0.0, 0.0], vec![0.5, -0.3]];
    let mut scene = Scene::new("double pendulum", 0.01);
    let report = scene
        .add_robot(&model, &qs, &MeshSearch::new(vec![root.clone()]))
        .unwrap();
    assert_eq!((report.visuals, report.capsules), (3, 0), "{report:?}");
    assert!(report.missing.is_empty());
    // Each mesh moves with its link: the base stays, link 2 turns with both joints.
    let moved = |b: &Body| b.poses[0] != b.poses[1];
    let by_name = |n: &str| scene.bodies.iter().find(|b| b.name == n).unwrap();
    assert!(!moved(by_name("base_link")) && moved(by_name("link1")) && moved(by_name("link2")));
    let Shape::Mesh { vertices, triangles } = &by_name("link1").shape else {
        panic!("not a mesh")
    };
    assert_eq!((vertices.len(), triangles.len()), (3, 1));
    assert!((vertices[1][0] - 0.1).abs() < 1e-7);
    std::fs::remove_dir_all(&root).ok();
}

#[test]
fn the_page_embeds_the_scene_and_bad_scenes_are_errors() {
    let mut scene = Scene::new("a </script> title & more", 0.1);
    scene.bodies.push(Body {
        name: "b".into(),
        shape: Shape::Box { size: [0.1, 0.2, 0.3] },
        color: [0.5; 3],
        poses: vec![Pose::at([0.0, 0.0, 0.0]), Pose::at([1.0, 0.0, 0.0])],
    });
    scene.add_target([1.0, 1.0, 1.0], 0.05);
    let html = page(&scene).unwrap();
    assert!(!html.contains("http://") && !html.contains("https://") && !html.contains(" src="));
    assert!(html.contains("a &lt;/script&gt; title &amp; more"));
    let start = html.find(r#"<script id="scene" type="application/json">"#).unwrap();
    let json = &html[start..];
    let json = &json[json.find('>').unwrap() + 1..json.find("</script>").unwrap()];
    let doc: serde_json::Value = serde_json::from_str(json).unwrap();
    assert_eq!(doc["frames"], 2);
    assert_eq!(doc["bodies"][0]["poses"][1][9], 1.0);
    assert_eq!(doc["markers"][0]["pose"][11], 1.0);

    let mut bad = scene.clone();
    bad.dt = 0.0;
    assert!(matches!(page(&bad), Err(Error::Invalid(_))));
    let mut bad = scene.clone();
    bad.bodies[0].poses.pop();
    bad.bodies.push(scene.bodies[0].clone());
    assert!(page(&bad).unwrap_err().to_string().contains("poses"));
    let mut bad = scene.clone();
    bad.bodies[0].poses[1].translation[2] = f64::NAN;
    assert!(page(&bad).unwrap_err().to_string().contains("non-finite"));
    let mut bad = scene.clone();
    bad.arrows = vec![vec![]];
    assert!(page(&bad).unwrap_err().to_string().contains("arrows"));
    // A configuration off the model (wrong size) is an error naming the node.
    let model = Model::from_urdf_str(UR5_URDF, RootJoint::Fixed).unwrap();
    let e = Scene::new("x", 0.1)
        .add_robot(&model, &[vec![0.0; 6], vec![0.0; 5]], &MeshSearch::default())
        .unwrap_err();
    assert!(e.to_string().contains("configuration 1"), "{e}");
    // No configuration at all (an empty trajectory) is an error, not an index panic.
    let e = Scene::new("x", 0.1)
        .add_robot(&model, &[], &MeshSearch::default())
        .unwrap_err();
    assert!(e.to_string().contains("no configurations"), "{e}");
}
