//! Wavefront OBJ reading ([`load_obj`], via the `tobj` crate) and writing
//! ([`TriangleMesh::write_obj`]).
//!
//! Only triangles are accepted (no triangulation is done here: a polygon face is
//! an error naming the face, so a mesh is never silently re-triangulated); points,
//! lines, normals, texture coordinates and materials are ignored. All models
//! (`o`/`g` groups) of a file are merged into one [`TriangleMesh`]. Coordinates are
//! read as metres, in the object frame; place the mesh with a `world_from_object`
//! [`crate::Transform`] ([`load_obj_instance`]).

use std::io::{BufReader, Write};
use std::path::Path;
use std::sync::Arc;

use usray_ad::Real;

use crate::{MeshError, MeshInstance, Transform, TriangleMesh};

/// Largest OBJ file read, bytes (256 MiB: some millions of triangles, far
/// more than a scene's anatomy needs).
pub const MAX_OBJ_BYTES: u64 = 256 << 20;

/// Parse OBJ text; `source` names the file in errors.
pub fn parse_obj(text: &str, source: &str) -> Result<TriangleMesh, MeshError> {
    let opts = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = BufReader::new(text.as_bytes());
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &opts, |_| {
        Err(tobj::LoadError::GenericFailure) // materials are ignored
    })
    .map_err(|e| MeshError::Parse {
        file: source.to_string(),
        reason: e.to_string(),
    })?;
    let mut mesh = TriangleMesh::default();
    for model in &models {
        let m = &model.mesh;
        if let Some((face, &arity)) = m.face_arities.iter().enumerate().find(|(_, &a)| a != 3) {
            return Err(MeshError::NonTriangleFace {
                file: source.to_string(),
                model: model.name.clone(),
                face,
                vertices: arity as usize,
            });
        }
        if m.indices.len() % 3 != 0 {
            return Err(MeshError::Parse {
                file: source.to_string(),
                reason: format!("model '{}': index count is not a multiple of 3", model.name),
            });
        }
        let positions: Vec<[f64; 3]> = m
            .positions
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let triangles: Vec<[u32; 3]> = m
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        mesh.append(&TriangleMesh {
            positions,
            triangles,
        });
    }
    mesh.check(source)?;
    Ok(mesh)
}

/// Load an OBJ file of triangles (see the module documentation). Errors name
/// the file: missing/unreadable file, parse failure, no triangles, a non-finite
/// vertex, a non-triangle face, an index out of range.
///
/// ```
/// let dir = std::env::temp_dir().join("usray_geometry_doc_obj");
/// std::fs::create_dir_all(&dir).unwrap();
/// let p = dir.join("tri.obj");
/// std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
/// let m = usray_geometry::obj::load_obj(&p).unwrap();
/// assert_eq!(m.triangles, vec![[0, 1, 2]]);
/// let err = usray_geometry::obj::load_obj(dir.join("missing.obj")).unwrap_err();
/// assert!(err.to_string().contains("missing.obj"));
/// ```
pub fn load_obj(path: impl AsRef<Path>) -> Result<TriangleMesh, MeshError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let size = std::fs::metadata(path)
        .map_err(|source| MeshError::Io {
            file: name.clone(),
            source,
        })?
        .len();
    if size > MAX_OBJ_BYTES {
        return Err(MeshError::Parse {
            file: name,
            reason: format!(
                "{size} bytes is past the limit of {MAX_OBJ_BYTES} (usray_geometry::obj::MAX_OBJ_BYTES)"
            ),
        });
    }
    let text = std::fs::read_to_string(path).map_err(|source| MeshError::Io {
        file: name.clone(),
        source,
    })?;
    parse_obj(&text, &name)
}

/// Load an OBJ file and place it with `world_from_object` (builds the BVH).
pub fn load_obj_instance<T: Real>(
    path: impl AsRef<Path>,
    world_from_object: Transform<T>,
) -> Result<MeshInstance<T>, MeshError> {
    let mesh = load_obj(path)?;
    MeshInstance::new(Arc::new(mesh), world_from_object)
}

impl TriangleMesh {
    /// The mesh as OBJ text (`v` lines in Rust's shortest round-trip notation, so
    /// `f64` positions are read back exactly; 1-based `f` lines).
    pub fn to_obj_string(&self, comment: &str) -> String {
        let mut s = String::new();
        for line in comment.lines() {
            s.push_str("# ");
            s.push_str(line);
            s.push('\n');
        }
        for p in &self.positions {
            s.push_str(&format!("v {:e} {:e} {:e}\n", p[0], p[1], p[2]));
        }
        for t in &self.triangles {
            s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
        }
        s
    }

    /// Write the mesh as OBJ, atomically (a temporary file in the same directory,
    /// then a rename). `comment` goes in `#` lines at the top.
    pub fn write_obj(&self, path: impl AsRef<Path>, comment: &str) -> Result<(), MeshError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let io = |source| MeshError::Io {
            file: name.clone(),
            source,
        };
        let tmp = path.with_extension("obj.tmp");
        {
            let mut f = std::fs::File::create(&tmp).map_err(io)?;
            f.write_all(self.to_obj_string(comment).as_bytes())
                .map_err(io)?;
            f.sync_all().map_err(io)?;
        }
        std::fs::rename(&tmp, path).map_err(io)
    }
}
