//! Loading a scene's mesh objects (Wavefront OBJ: `v` and `f` records).

use crate::scene::{Object, Scene, SceneError};
use std::sync::Arc;
use usray_geometry::TriangleMesh;

/// Read the OBJ file of a mesh object (path relative to the scene file), fan-
/// triangulate polygons, and orient the triangles outward. Errors name the file
/// and the object's `path` key.
pub fn load_mesh(scene: &Scene, o: &Object) -> Result<Arc<TriangleMesh>, SceneError> {
    let key = format!("objects.{}.path", o.name);
    let err = |m: String| SceneError::new(&scene.source, key.clone(), m);
    let rel = o
        .path
        .as_deref()
        .ok_or_else(|| err("required for shape mesh".into()))?;
    let full = scene.base_dir.join(rel);
    let text = std::fs::read_to_string(&full)
        .map_err(|e| err(format!("cannot read mesh file {}: {e}", full.display())))?;
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let v: Vec<f64> = it.take(3).filter_map(|s| s.parse().ok()).collect();
                if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
                    return Err(err(format!(
                        "{}:{}: expected `v x y z` with finite numbers",
                        full.display(),
                        ln + 1
                    )));
                }
                positions.push([v[0], v[1], v[2]]);
            }
            Some("f") => {
                let mut idx = Vec::new();
                for s in it {
                    let first = s.split('/').next().unwrap_or("");
                    let i: i64 = first.parse().map_err(|_| {
                        err(format!(
                            "{}:{}: bad face index {s:?}",
                            full.display(),
                            ln + 1
                        ))
                    })?;
                    let n = positions.len() as i64;
                    let i = if i < 0 { n + i } else { i - 1 };
                    if i < 0 || i >= n {
                        return Err(err(format!(
                            "{}:{}: face index out of range",
                            full.display(),
                            ln + 1
                        )));
                    }
                    idx.push(i as u32);
                }
                for k in 1..idx.len().saturating_sub(1) {
                    triangles.push([idx[0], idx[k], idx[k + 1]]);
                }
            }
            _ => {}
        }
    }
    let mut mesh = TriangleMesh::new(positions, triangles)
        .map_err(|e| err(format!("{}: {e}", full.display())))?;
    mesh.orient_outward();
    Ok(Arc::new(mesh))
}
