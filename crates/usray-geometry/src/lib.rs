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
//!   ray enters iff `dir · normal < 0`.
//! - Nested media: see [`Geometry`] (a per-ray [`MediumStack`]; entering pushes,
//!   exiting removes; later objects nest inside earlier ones).
//! - `t_min` (metres) excludes the surface a ray starts on; tangent rays miss.

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
