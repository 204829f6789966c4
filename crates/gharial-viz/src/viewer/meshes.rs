//! Mesh files of URDF visuals: finding them (`package://` and relative paths) and reading
//! STL (binary and ASCII) and Wavefront OBJ, simplified to a size a canvas draws fast.

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
        roots.extend(example_robot_data());
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
            other => Err(format!("`.{other}` meshes are not read (STL and OBJ are)")),
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
            "from example_robot_data.path import EXAMPLE_ROBOT_DATA_MODEL_DIR as d; print(d)",
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
