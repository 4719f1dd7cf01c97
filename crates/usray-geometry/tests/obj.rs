//! OBJ loading errors name the file and the problem; writing round-trips.

use usray_geometry::obj::{load_obj, parse_obj};
use usray_geometry::{MeshError, TriangleMesh};

fn tmp(name: &str, text: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("usray_geometry_obj_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn missing_file_names_the_file() {
    let e = load_obj("/nonexistent/dir/heart.obj").unwrap_err();
    assert!(matches!(e, MeshError::Io { .. }));
    let s = e.to_string();
    assert!(s.contains("/nonexistent/dir/heart.obj"), "{s}");
}

#[test]
fn no_triangles_is_an_error() {
    let p = tmp("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    let e = load_obj(&p).unwrap_err();
    assert!(matches!(e, MeshError::NoTriangles { .. }), "{e:?}");
    assert!(e.to_string().contains("points.obj") && e.to_string().contains("no triangles"));
    let e = parse_obj("", "empty.obj").unwrap_err();
    assert!(matches!(e, MeshError::NoTriangles { .. }));
}

#[test]
fn nan_vertex_is_an_error() {
    let p = tmp("nan.obj", "v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n");
    let e = load_obj(&p).unwrap_err();
    assert!(
        matches!(e, MeshError::NonFiniteVertex { vertex: 1, .. }),
        "{e:?}"
    );
    assert!(e.to_string().contains("nan.obj"));
}

#[test]
fn quad_face_is_an_error_naming_the_face() {
    let p = tmp(
        "quad.obj",
        "o thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 2 3 4\n",
    );
    let e = load_obj(&p).unwrap_err();
    match &e {
        MeshError::NonTriangleFace {
            face,
            vertices,
            model,
            ..
        } => {
            assert_eq!((*face, *vertices, model.as_str()), (1, 4, "thing"));
        }
        other => panic!("{other:?}"),
    }
    let s = e.to_string();
    assert!(s.contains("quad.obj") && s.contains("4 vertices"), "{s}");
}

#[test]
fn bad_index_and_garbage_are_parse_errors() {
    for (name, text) in [
        ("oob.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        ("garbage.obj", "v 0 0 zero\nf 1 2 3\n"),
    ] {
        let e = load_obj(tmp(name, text)).unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
    }
}

#[test]
fn write_then_load_round_trips_exactly() {
    let mut m = TriangleMesh::icosphere(0.0123456789, 2);
    m.positions[0][0] += 1e-17; // not representable in short decimal: must survive
    let dir = std::env::temp_dir().join(format!("usray_geometry_rt_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("ico.obj");
    m.write_obj(&p, "test\nsecond line").unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.starts_with("# test\n# second line\n"));
    let back = load_obj(&p).unwrap();
    assert_eq!(back.triangles.len(), m.triangles.len());
    for i in 0..m.triangles.len() {
        assert_eq!(back.corners(i), m.corners(i));
    }
    back.assert_well_formed();
    assert!(!dir.join("ico.obj.tmp").exists());
}

#[test]
#[should_panic(expected = "not closed")]
fn open_mesh_fails_the_invariant_checker() {
    let mut m = TriangleMesh::icosphere(1.0, 1);
    m.triangles.pop();
    m.assert_well_formed();
}

#[test]
#[should_panic(expected = "non-positive signed volume")]
fn inward_mesh_fails_the_invariant_checker() {
    let mut m = TriangleMesh::icosphere(1.0, 1);
    m.flip();
    m.assert_well_formed();
}
