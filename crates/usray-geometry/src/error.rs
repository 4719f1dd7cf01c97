//! Errors of this crate ([`MeshError`], [`GeometryError`]).

use thiserror::Error;

/// Errors while loading, writing or building a mesh. Every variant that concerns
/// a file names it.
#[derive(Debug, Error)]
pub enum MeshError {
    /// The file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The OBJ parser rejected the file.
    #[error("{file}: not a valid OBJ file: {reason}")]
    Parse {
        /// The file.
        file: String,
        /// What the parser reported.
        reason: String,
    },
    /// The file holds no triangle (no faces at all, or only points/lines).
    #[error("{file}: no triangles found")]
    NoTriangles {
        /// The file (or `<memory>`).
        file: String,
    },
    /// A face with more than three vertices (this loader does not triangulate).
    #[error("{file}: face {face} of model '{model}' has {vertices} vertices; only triangles are accepted (triangulate the mesh first)")]
    NonTriangleFace {
        /// The file.
        file: String,
        /// Model (OBJ object/group) name.
        model: String,
        /// Face index within the model.
        face: usize,
        /// Number of vertices of that face.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("{file}: vertex {vertex} has a non-finite (NaN or infinite) coordinate")]
    NonFiniteVertex {
        /// The file.
        file: String,
        /// Vertex index (0-based, within the merged mesh).
        vertex: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("{file}: triangle {triangle} refers to a vertex index >= the vertex count {vertices}")]
    IndexOutOfRange {
        /// The file.
        file: String,
        /// Triangle index.
        triangle: usize,
        /// Number of vertices.
        vertices: usize,
    },
    /// Differentiable vertices given to `MeshInstance::with_vertices` do not match
    /// the mesh the BVH was built from.
    #[error("differentiable vertices do not match the mesh: expected {expected} vertices with the mesh's values, got {got}")]
    VerticesMismatch {
        /// Vertex count of the mesh.
        expected: usize,
        /// Vertex count given.
        got: usize,
    },
    /// The object transform is non-finite or has a zero scale factor.
    #[error("mesh transform is not finite or has a zero scale factor")]
    BadTransform,
}

/// Errors when adding an object to a [`crate::Geometry`].
#[derive(Debug, Error)]
pub enum GeometryError {
    /// A parameter is non-finite or out of range (radius ≤ 0, thickness not in
    /// `(0, radius)`, slab top not above bottom, zero normal).
    #[error("invalid {shape}: {reason}")]
    InvalidShape {
        /// Which shape.
        shape: &'static str,
        /// What was wrong.
        reason: &'static str,
    },
    /// A mesh problem.
    #[error(transparent)]
    Mesh(#[from] MeshError),
}
