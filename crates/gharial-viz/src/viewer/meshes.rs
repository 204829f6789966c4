//! Mesh files of URDF visuals: finding them (`package://` and relative paths) and reading
//! STL (binary and ASCII), Wavefront OBJ and COLLADA (the triangles and polygons of the
//! geometries its visual scene instantiates), simplified to a size a canvas draws fast.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::Shape;

/// Meshes with more triangles than this are simplified by vertex clustering.
const MAX_TRIANGLES: usize = 2500;

/// Where mesh files are looked for. A `package://pkg/rest` URI resolves to `root/pkg/rest`
/// or, for a root that is the package itself (its directory is named `pkg`), to
/// `root/rest`; `file://` URIs and absolute paths are used as they are; other relative
/// paths are tried under every root.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshSearch {
    /// Directories searched, in order.
    pub roots: Vec<PathBuf>,
}

impl MeshSearch {
    /// A search through `roots`.
    pub fn new(roots: Vec<PathBuf>) -> Self {
        Self { roots }
    }

    /// The search path of the environment: `GHARIAL_MESH_PATH` (directories separated by
    /// `:`), then `ROS_PACKAGE_PATH` (the ROS convention), then the robots directory of
    /// the `example-robot-data` Python package when `python3` can import it.
    pub fn from_env() -> Self {
        let mut roots = Vec::new();
        for var in ["GHARIAL_MESH_PATH", "ROS_PACKAGE_PATH"] {
            if let Some(v) = std::env::var_os(var) {
                roots.extend(std::env::split_paths(&v).filter(|p| !p.as_os_str().is_empty()));
            }
        }
        // Its robots directory, for `package://<robot>_description/...`, and the package
        // directory above it, for `package://example-robot-data/robots/...`.
        if let Some(dir) = example_robot_data() {
            roots.extend(dir.parent().map(Path::to_path_buf));
            roots.push(dir);
        }
        Self { roots }
    }

    /// The file that `uri` names, if it exists.
    pub fn resolve(&self, uri: &str) -> Option<PathBuf> {
        if let Some(rest) = uri.strip_prefix("package://") {
            let (pkg, path) = rest.split_once('/')?;
            return self.roots.iter().find_map(|r| {
                let inside = r.join(pkg).join(path);
                let is_pkg = r.file_name().is_some_and(|n| n == pkg);
                if inside.is_file() {
                    Some(inside)
                } else if is_pkg && r.join(path).is_file() {
                    Some(r.join(path))
                } else {
                    None
                }
            });
        }
        let path = Path::new(uri.strip_prefix("file://").unwrap_or(uri));
        if path.is_absolute() {
            return path.is_file().then(|| path.to_path_buf());
        }
        self.roots.iter().map(|r| r.join(path)).find(|p| p.is_file())
    }

    /// The mesh that `uri` names, scaled per axis, as a [`Shape::Mesh`]; why not, as text.
    pub fn load(&self, uri: &str, scale: [f64; 3]) -> Result<Shape, String> {
        let path = self
            .resolve(uri)
            .ok_or_else(|| "not found on the mesh search path (GHARIAL_MESH_PATH, ROS_PACKAGE_PATH)".to_string())?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let (mut vertices, triangles) = match ext.as_str() {
            "stl" => read_stl(&bytes),
            "obj" => read_obj(&String::from_utf8_lossy(&bytes)),
            "dae" => read_dae(&String::from_utf8_lossy(&bytes)),
            other => Err(format!("`.{other}` meshes are not read (STL, OBJ and COLLADA are)")),
        }
        .map_err(|e| format!("{}: {e}", path.display()))?;
        for v in &mut vertices {
            for i in 0..3 {
                v[i] *= scale[i];
            }
        }
        if triangles.is_empty() {
            return Err(format!("{}: no triangles", path.display()));
        }
        let (vertices, triangles) = simplify(vertices, triangles);
        Ok(Shape::Mesh { vertices, triangles })
    }
}

type Triangles = (Vec<[f64; 3]>, Vec<[u32; 3]>);

/// The robots directory of the `example-robot-data` Python package, if installed.
fn example_robot_data() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import os; from example_robot_data import getModelPath as m; \
             print(os.path.realpath(m('ur_description/urdf/ur5_robot.urdf')))",
        ])
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    let dir = PathBuf::from(String::from_utf8(out.stdout).ok()?.trim());
    (out.status.success() && dir.is_dir()).then_some(dir)
}

/// Binary or ASCII STL.
fn read_stl(bytes: &[u8]) -> Result<Triangles, String> {
    let binary_len = bytes
        .get(80..84)
        .map(|c| 84 + 50 * u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize);
    if binary_len == Some(bytes.len()) {
        let count = (bytes.len() - 84) / 50;
        let mut vertices = Vec::with_capacity(3 * count);
        for k in 0..count {
            let rec = &bytes[84 + 50 * k..84 + 50 * (k + 1)];
            for j in 0..3 {
                let at = |i: usize| {
                    let o = 12 + 12 * j + 4 * i;
                    f64::from(f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]))
                };
                vertices.push([at(0), at(1), at(2)]);
            }
        }
        let triangles = (0..count as u32).map(|k| [3 * k, 3 * k + 1, 3 * k + 2]).collect();
        return Ok((vertices, triangles));
    }
    let text = String::from_utf8_lossy(bytes);
    if !text.trim_start().starts_with("solid") {
        return Err("neither binary nor ASCII STL".into());
    }
    let mut vertices = Vec::new();
    for line in text.lines() {
        let mut w = line.split_whitespace();
        if w.next() == Some("vertex") {
            let v: Vec<f64> = w.filter_map(|s| s.parse().ok()).collect();
            let [x, y, z] = v[..] else {
                return Err(format!("bad vertex line `{}`", line.trim()));
            };
            vertices.push([x, y, z]);
        }
    }
    if vertices.len() % 3 != 0 {
        return Err("vertex count not a multiple of 3".into());
    }
    let triangles = (0..(vertices.len() / 3) as u32)
        .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
        .collect();
    Ok((vertices, triangles))
}

/// Wavefront OBJ: `v` lines and `f` lines (polygons fanned into triangles; `a/b/c` and
/// negative indices accepted).
fn read_obj(text: &str) -> Result<Triangles, String> {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => {
                let v: Vec<f64> = w.take(3).filter_map(|s| s.parse().ok()).collect();
                let [x, y, z] = v[..] else {
                    return Err(format!("line {}: bad vertex", n + 1));
                };
                vertices.push([x, y, z]);
            }
            Some("f") => {
                let idx: Result<Vec<u32>, String> = w
                    .map(|s| {
                        let i: i64 = s
                            .split('/')
                            .next()
                            .unwrap_or("")
                            .parse()
                            .map_err(|_| format!("line {}: bad face", n + 1))?;
                        let i = if i < 0 { vertices.len() as i64 + i } else { i - 1 };
                        u32::try_from(i)
                            .ok()
                            .filter(|&i| (i as usize) < vertices.len())
                            .ok_or_else(|| format!("line {}: face index out of range", n + 1))
                    })
                    .collect();
                let idx = idx?;
                for k in 1..idx.len().saturating_sub(1) {
                    triangles.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok((vertices, triangles))
}

/// A 4 x 4 transform, row-major.
type Transform = [[f64; 4]; 4];

const IDENTITY: Transform = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

fn compose(a: &Transform, b: &Transform) -> Transform {
    let mut c = [[0.0; 4]; 4];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

fn numbers(text: &str) -> Vec<f64> {
    text.split_whitespace().filter_map(|s| s.parse().ok()).collect()
}

/// The transform of a COLLADA `<node>`: its `matrix`, `translate`, `rotate` (axis,
/// degrees) and `scale` children, in order.
fn node_transform(node: roxmltree::Node<'_, '_>) -> Transform {
    let mut m = IDENTITY;
    for child in node.children().filter(roxmltree::Node::is_element) {
        let v = numbers(child.text().unwrap_or(""));
        let t = match (child.tag_name().name(), v.len()) {
            ("matrix", 16) => [0, 1, 2, 3].map(|i| [v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]]),
            ("translate", 3) => {
                let mut t = IDENTITY;
                (0..3).for_each(|i| t[i][3] = v[i]);
                t
            }
            ("scale", 3) => {
                let mut t = IDENTITY;
                (0..3).for_each(|i| t[i][i] = v[i]);
                t
            }
            ("rotate", 4) => {
                let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-12);
                let (x, y, z) = (v[0] / n, v[1] / n, v[2] / n);
                let (s, c) = v[3].to_radians().sin_cos();
                let k = 1.0 - c;
                [
                    [c + x * x * k, x * y * k - z * s, x * z * k + y * s, 0.0],
                    [y * x * k + z * s, c + y * y * k, y * z * k - x * s, 0.0],
                    [z * x * k - y * s, z * y * k + x * s, c + z * z * k, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                ]
            }
            _ => continue,
        };
        m = compose(&m, &t);
    }
    m
}

type Node<'a, 'i> = roxmltree::Node<'a, 'i>;

/// The element of `doc` whose `id` is `id` (a leading `#` ignored).
fn by_id<'a, 'i>(doc: &'a roxmltree::Document<'i>, id: &str) -> Option<Node<'a, 'i>> {
    doc.descendants()
        .find(|n| n.attribute("id") == Some(id.trim_start_matches('#')))
}

/// The whitespace-separated integers of an element's text (empty without the element).
fn integers<T: std::str::FromStr>(node: Option<Node<'_, '_>>) -> Vec<T> {
    let text = node.and_then(|n| n.text()).unwrap_or("");
    text.split_whitespace().filter_map(|s| s.parse().ok()).collect()
}

/// The geometries that the visual scene instantiates, with the world transforms of
/// their nodes; without a visual scene, every geometry as it is.
fn scene_instances<'a, 'i>(doc: &'a roxmltree::Document<'i>) -> Vec<(Node<'a, 'i>, Transform)> {
    fn walk(node: Node<'_, '_>, parent: Transform, out: &mut Vec<(String, Transform)>) {
        let m = compose(&parent, &node_transform(node));
        for child in node.children().filter(Node::is_element) {
            match child.tag_name().name() {
                "instance_geometry" => out.push((child.attribute("url").unwrap_or("").to_string(), m)),
                "node" => walk(child, m, out),
                _ => {}
            }
        }
    }
    let Some(scene) = doc.descendants().find(|n| n.has_tag_name("visual_scene")) else {
        let geometries = doc.descendants().filter(|n| n.has_tag_name("geometry"));
        return geometries.map(|g| (g, IDENTITY)).collect();
    };
    let mut urls = Vec::new();
    for node in scene.children().filter(|n| n.has_tag_name("node")) {
        walk(node, IDENTITY, &mut urls);
    }
    urls.into_iter()
        .filter_map(|(url, m)| Some((by_id(doc, &url)?, m)))
        .collect()
}

/// Appends one `<triangles>` or `<polylist>` element: its positions through `m` (scaled
/// by `unit`, turned to z up when `y_up`) and its polygons fanned into triangles.
fn read_primitive(
    doc: &roxmltree::Document<'_>,
    prims: Node<'_, '_>,
    (m, unit, y_up): (&Transform, f64, bool),
    (vertices, triangles): &mut Triangles,
) -> Result<(), String> {
    let inputs: Vec<_> = prims.children().filter(|n| n.has_tag_name("input")).collect();
    let offset_of = |i: &Node<'_, '_>| i.attribute("offset").and_then(|o| o.parse::<usize>().ok());
    let stride = inputs.iter().filter_map(offset_of).max().unwrap_or(0) + 1;
    let vertex_input = inputs
        .iter()
        .find(|i| i.attribute("semantic") == Some("VERTEX"))
        .ok_or("a primitive without VERTEX input")?;
    let offset = offset_of(vertex_input).unwrap_or(0);
    let positions_id = by_id(doc, vertex_input.attribute("source").unwrap_or(""))
        .and_then(|v| v.children().find(|i| i.attribute("semantic") == Some("POSITION")))
        .and_then(|i| i.attribute("source"))
        .ok_or("VERTEX input without POSITION")?;
    let floats = by_id(doc, positions_id)
        .and_then(|s| s.descendants().find(|n| n.has_tag_name("float_array")))
        .map(|a| numbers(a.text().unwrap_or("")))
        .ok_or("POSITION source without float_array")?;
    let base = vertices.len() as u32;
    for p in floats.chunks_exact(3) {
        let w = [0, 1, 2].map(|i| unit * (m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3]));
        vertices.push(if y_up { [w[0], -w[2], w[1]] } else { w });
    }
    let idx: Vec<u32> = integers(prims.children().find(|n| n.has_tag_name("p")));
    let corners: Vec<u32> = idx.iter().skip(offset).step_by(stride).copied().collect();
    if corners.iter().any(|&i| i as usize >= floats.len() / 3) {
        return Err("a vertex index out of range".into());
    }
    let sizes: Vec<usize> = match prims.children().find(|n| n.has_tag_name("vcount")) {
        Some(v) => integers(Some(v)),
        None => vec![3; corners.len() / 3],
    };
    let mut at = 0;
    for n in sizes {
        let poly = corners.get(at..at + n).ok_or("fewer indices than the polygon sizes")?;
        for k in 1..n.saturating_sub(1) {
            triangles.push([base + poly[0], base + poly[k], base + poly[k + 1]]);
        }
        at += n;
    }
    Ok(())
}

/// COLLADA: the triangles and polygons (fanned) of every geometry that the visual scene
/// instantiates, with the nodes' transforms, in metres, z up. Without a visual scene,
/// every geometry as it is.
fn read_dae(text: &str) -> Result<Triangles, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| format!("not XML: {e}"))?;
    let first = |tag: &str| doc.descendants().find(|n| n.has_tag_name(tag));
    let unit = first("unit")
        .and_then(|n| n.attribute("meter"))
        .and_then(|m| m.parse::<f64>().ok())
        .unwrap_or(1.0);
    let y_up = first("up_axis").is_some_and(|n| n.text() == Some("Y_UP"));
    let mut mesh = (Vec::new(), Vec::new());
    for (geometry, m) in scene_instances(&doc) {
        let prims = geometry.descendants();
        for p in prims.filter(|n| n.has_tag_name("triangles") || n.has_tag_name("polylist")) {
            read_primitive(&doc, p, (&m, unit, y_up), &mut mesh)?;
        }
    }
    Ok(mesh)
}

/// Merges vertices that share a cell of a grid over the bounding box, finer until the
/// mesh has at most [`MAX_TRIANGLES`] triangles (or the finest grid is reached), and
/// drops the triangles that collapse.
fn simplify(vertices: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Triangles {
    if triangles.len() <= MAX_TRIANGLES {
        return (vertices, triangles);
    }
    let (lo, hi) = vertices
        .iter()
        .fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), v| {
            ([0, 1, 2].map(|i| lo[i].min(v[i])), [0, 1, 2].map(|i| hi[i].max(v[i])))
        });
    let extent = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max).max(1e-9);
    let mut best = (vertices.clone(), triangles.clone());
    for cells in [12.0, 16.0, 24.0, 32.0, 48.0] {
        let h = extent / cells;
        let mut cell_of: HashMap<[i64; 3], u32> = HashMap::new();
        let mut merged: Vec<[f64; 3]> = Vec::new();
        let map: Vec<u32> = vertices
            .iter()
            .map(|v| {
                let key = [0, 1, 2].map(|i| ((v[i] - lo[i]) / h).floor() as i64);
                *cell_of.entry(key).or_insert_with(|| {
                    merged.push(*v);
                    (merged.len() - 1) as u32
                })
            })
            .collect();
        let mut seen = std::collections::HashSet::new();
        let tris: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| map[i as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .filter(|t| {
                let mut k = *t;
                k.sort_unstable();
                seen.insert(k)
            })
            .collect();
        if tris.len() > MAX_TRIANGLES {
            break;
        }
        best = (merged, tris);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra_obj() -> &'static str {
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf -4/1/1 -2 -1\nf 2 3 4\n"
    }

    #[test]
    fn obj_and_both_stl_forms_read_the_same_tetrahedron() {
        let (v, t) = read_obj(tetra_obj()).unwrap();
        assert_eq!((v.len(), t.len()), (4, 4));
        assert_eq!(t[2], [0, 2, 3]);
        // The same triangles as ASCII and binary STL.
        let mut ascii = String::from("solid t\n");
        let mut binary = vec![0u8; 80];
        binary.extend_from_slice(&(t.len() as u32).to_le_bytes());
        for tri in &t {
            ascii.push_str("facet normal 0 0 0\nouter loop\n");
            binary.extend_from_slice(&[0u8; 12]);
            for &i in tri {
                let p = v[i as usize];
                ascii.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
                for c in p {
                    binary.extend_from_slice(&(c as f32).to_le_bytes());
                }
            }
            ascii.push_str("endloop\nendfacet\n");
            binary.extend_from_slice(&[0u8; 2]);
        }
        ascii.push_str("endsolid t\n");
        for bytes in [ascii.as_bytes(), binary.as_slice()] {
            let (sv, st) = read_stl(bytes).unwrap();
            assert_eq!(st.len(), 4);
            for (k, tri) in st.iter().enumerate() {
                for j in 0..3 {
                    assert_eq!(sv[tri[j] as usize], v[t[k][j] as usize]);
                }
            }
        }
        assert!(read_stl(b"garbage").is_err());
        assert!(read_obj("v 0 0\n").is_err());
        assert!(read_obj("v 0 0 0\nf 1 2 3\n").is_err());
    }

    /// A COLLADA square (a quad in a polylist) in centimetres, moved by its node, and a
    /// triangle of another geometry, both instantiated by the visual scene.
    #[test]
    fn collada_geometries_with_their_node_transforms() {
        let dae = r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="sq"><mesh>
      <source id="sq-pos"><float_array id="sq-arr" count="12">0 0 0 100 0 0 100 100 0 0 100 0</float_array></source>
      <vertices id="sq-v"><input semantic="POSITION" source="#sq-pos"/></vertices>
      <polylist count="1"><input semantic="VERTEX" source="#sq-v" offset="0"/><input semantic="NORMAL" source="#n" offset="1"/>
        <vcount>4</vcount><p>0 0 1 0 2 0 3 0</p></polylist>
    </mesh></geometry>
    <geometry id="tri"><mesh>
      <source id="tri-pos"><float_array id="tri-arr" count="9">0 0 0 0 0 100 0 100 0</float_array></source>
      <vertices id="tri-v"><input semantic="POSITION" source="#tri-pos"/></vertices>
      <triangles count="1"><input semantic="VERTEX" source="#tri-v" offset="0"/><p>0 1 2</p></triangles>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes><visual_scene id="s">
    <node id="a"><translate>0 0 50</translate><instance_geometry url="#sq"/></node>
    <node id="b"><matrix>1 0 0 200 0 1 0 0 0 0 1 0 0 0 0 1</matrix><instance_geometry url="#tri"/></node>
  </visual_scene></library_visual_scenes>
</COLLADA>"##;
        let (v, t) = read_dae(dae).unwrap();
        assert_eq!((v.len(), t.len()), (7, 3));
        assert_eq!(v[2], [1.0, 1.0, 0.5]);
        assert_eq!(t[..2], [[0, 1, 2], [0, 2, 3]]);
        assert_eq!(v[5], [2.0, 0.0, 1.0]);
        assert_eq!(t[2], [4, 5, 6]);
        assert!(read_dae("<COLLADA/>").unwrap().1.is_empty());
        assert!(read_dae("not xml").is_err());
    }

    #[test]
    fn package_uris_resolve_under_roots_and_large_meshes_are_simplified() {
        let root = std::env::temp_dir().join(format!("gharial-meshes-{}", std::process::id()));
        let dir = root.join("robot_description/meshes");
        std::fs::create_dir_all(&dir).unwrap();
        // A fine grid of a unit square: 2 * 60 * 60 triangles.
        let n = 60;
        let mut obj = String::new();
        for i in 0..=n {
            for j in 0..=n {
                obj.push_str(&format!("v {} {} 0\n", i as f64 / n as f64, j as f64 / n as f64));
            }
        }
        for i in 0..n {
            for j in 0..n {
                let a = i * (n + 1) + j + 1;
                obj.push_str(&format!(
                    "f {} {} {}\nf {} {} {}\n",
                    a,
                    a + 1,
                    a + n + 2,
                    a,
                    a + n + 2,
                    a + n + 1
                ));
            }
        }
        std::fs::write(dir.join("plate.obj"), obj).unwrap();
        let search = MeshSearch::new(vec![root.clone()]);
        let uri = "package://robot_description/meshes/plate.obj";
        assert_eq!(search.resolve(uri), Some(dir.join("plate.obj")));
        // A root that is the package itself.
        let inside = MeshSearch::new(vec![root.join("robot_description")]);
        assert_eq!(inside.resolve(uri), Some(dir.join("plate.obj")));
        assert_eq!(search.resolve("package://other/meshes/plate.obj"), None);
        let Shape::Mesh { vertices, triangles } = search.load(uri, [2.0, 1.0, 1.0]).unwrap() else {
            panic!("not a mesh")
        };
        assert!(
            triangles.len() <= MAX_TRIANGLES && triangles.len() > 500,
            "{}",
            triangles.len()
        );
        let xmax = vertices.iter().map(|v| v[0]).fold(0.0, f64::max);
        assert!((1.9..=2.0).contains(&xmax), "scaled: {xmax}");
        assert!(
            search
                .load("package://robot_description/meshes/none.stl", [1.0; 3])
                .is_err()
        );
        std::fs::write(dir.join("m.dae"), "<COLLADA/>").unwrap();
        let e = search
            .load("package://robot_description/meshes/m.dae", [1.0; 3])
            .unwrap_err();
        assert!(e.contains(".dae"), "{e}");
        std::fs::remove_dir_all(&root).ok();
    }
}
