//! # usray-geometry
//!
//! Differentiable geometry for the usray ultrasound ray tracer: generic small
//! vectors and rays ([`Vec3`], [`Ray`]), rigid-plus-scale transforms
//! ([`Transform`]), analytic shapes ([`shapes`]: sphere, cylinder along `y`, tube
//! with a wall thickness, slab, half-space) and closed triangle meshes (OBJ
//! loading, a procedural heart-valve mesh), gathered in a [`Geometry`] that answers
//! the tracer's two questions: *what does this ray hit first?*
//! ([`Geometry::intersect`]) and *which medium is this point in?*
//! ([`Geometry::innermost_containing`], [`MediumStack`]).
//!
//! Hit **finding** runs on values (`f64` roots for analytic shapes; for meshes an
//! `f32` [`obvhs`] BVH with `f64` triangle tests) and carries no gradient; hit
//! **quantities** — distance `t`, point, outward normal — are then recomputed in
//! any scalar `T: Real` (`f64`, a forward [`usray_ad::Dual`], a tape variable)
//! from the differentiable parameters, so a time of flight `t/c` carries
//! `∂t/∂radius`, `∂t/∂centre`, `∂t/∂translation`, …
//!
//! Units: metres everywhere; angles in radians. Frames follow `CONTRACT.md` §1
//! (`x` lateral, `y` elevation, `z` depth); transforms are named by what they map
//! (`world_from_object`).
//!
//! ## Example
//! A ray down the `z` axis hits a cylinder of radius 5 mm centred at depth 15 mm
//! at `t = 15 mm − r`, so `∂t/∂r = −1`:
//! ```
//! use usray_ad::{Dual, Real};
//! use usray_geometry::{shapes::cylinder::Cylinder, Geometry, Ray, Vec3};
//!
//! type D = Dual<1>;
//! let radius = D::variable(0.005, 0); // seed ∂/∂radius
//! let mut geo = Geometry::<D>::new();
//! let id = geo
//!     .add(Cylinder::new(Vec3::from_f64s([0.0, 0.0, 0.015]), radius))
//!     .unwrap();
//! let ray = Ray::<D>::from_f64s([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
//! let hit = geo.intersect(&ray, 1e-9, 1.0).expect("the ray hits the cylinder");
//! assert_eq!(hit.object, id);
//! assert!((hit.t.value() - 0.010).abs() < 1e-15);
//! assert!((hit.t.eps[0] - (-1.0)).abs() < 1e-12); // ∂t/∂r
//! let n = hit.normal.value(); // outward, facing the probe
//! assert!(n[0].abs() < 1e-15 && (n[2] + 1.0).abs() < 1e-12);
//! assert!(hit.entering(&ray.dir));
//!
//! // The same query in plain f64:
//! let mut g64 = Geometry::<f64>::new();
//! g64.add(Cylinder::new(Vec3::new(0.0, 0.0, 0.015), 0.005)).unwrap();
//! let h = g64.intersect(&Ray::from_f64s([0.0; 3], [0.0, 0.0, 1.0]), 1e-9, 1.0).unwrap();
//! assert!((h.t - 0.010).abs() < 1e-15);
//! ```
//!
//! ## Conventions the transport relies on
//! - [`Hit::normal`] is the unit outward normal of the hit object's **solid**; the
//!   ray enters iff `dir · normal < 0` ([`Hit::entering`]). For a tube
//!   ([`shapes::hollow_cylinder`]) the solid is the wall, so at the inner surface
//!   the normal points towards the axis.
//! - [`Ray::dir`] is a unit vector, so `t` is a distance in metres.
//! - Nested media: see [`Geometry`] (a per-ray [`MediumStack`]; entering pushes,
//!   exiting removes; where objects overlap, later objects nest inside earlier
//!   ones; [`Geometry::stack_at`] starts a ray).
//! - `t_min` (metres) excludes the surface a ray starts on (`1e-9` m is ample: hit
//!   points are recomputed in `f64`); tangent rays are misses.
//! - Hit identity is decided on values only ([`Geometry::find`] → [`HitId`]);
//!   [`Geometry::hit_from`] recomputes the quantities for a `T` ray. A replay in a
//!   dual or tape type with the same values therefore takes the same branches;
//!   a visibility change (a ray starting or ceasing to hit) carries no derivative.
//! - Mesh BVHs are built from the transform's *value* and shared by `Arc`;
//!   [`MeshInstance::with_transform`] reuses one for a `Dual`/tape copy of the
//!   same scene instead of rebuilding it.
//!
//! ## Shapes
//! | shape | solid region | surfaces |
//! |---|---|---|
//! | [`shapes::sphere::Sphere`] | `‖p − c‖ < r` | 0 |
//! | [`shapes::cylinder::Cylinder`] | `(x−cx)² + (z−cz)² < r²`, infinite along `y` | 0 |
//! | [`shapes::hollow_cylinder::HollowCylinder`] | `r − t < ρ < r` (the wall) | 0 outer, 1 inner |
//! | [`shapes::slab::Slab`] | `z_top < z < z_bottom` | 0 top, 1 bottom |
//! | [`shapes::half_space::HalfSpace`] | `(p − q)·n < 0` | 0 |
//! | [`MeshInstance`] | inside a closed, outward-wound [`TriangleMesh`] | 0 (`primitive` = triangle) |
//!
//! Meshes: [`obj::load_obj`] (via `tobj`, triangles only, errors name the file),
//! [`TriangleMesh::write_obj`], [`TriangleMesh::icosphere`], the procedural
//! heart valve [`valve::valve_leaflets`] (shipped as
//! `scenes/meshes/valve_{open,half,closed}.obj`; its vertices as differentiable
//! functions of the closure state, [`valve::valve_leaflet_positions`], attach to
//! a mesh with [`MeshInstance::with_vertices`] for `∂t/∂openness`), invariant checkers
//! [`TriangleMesh::assert_well_formed`] and [`MeshBvh::assert_well_formed`].
//! For throughput comparisons, [`MeshBvh::traverse_f32`] is the bare `obvhs`
//! traversal; `cargo run --release -p usray-geometry --example bench_traversal`
//! prints rays/s for each layer.

mod error;
mod geometry;
pub mod obj;
mod ray;
pub mod shapes;
mod transform;
pub mod valve;
mod vec3;

pub use error::{GeometryError, MeshError};
pub use geometry::{Geometry, Hit, HitId, MediumStack, Shape, MEDIUM_STACK_DEPTH};
pub use ray::Ray;
pub use shapes::mesh::{MeshBvh, MeshHit, MeshInstance, TriangleMesh};
pub use transform::{Mat3, Transform};
pub use vec3::Vec3;
