//! Triangle meshes: [`TriangleMesh`] (object-frame data), [`MeshBvh`] (an `f32`
//! `obvhs` CWBVH over world-space triangles, no gradients) and [`MeshInstance`]
//! (a mesh placed by a differentiable `world_from_object` transform).
//!
//! Hit *finding* traverses the `f32` BVH (bounding boxes padded so that `f32`
//! rounding never culls a true hit) and tests candidate triangles in `f64`
//! against the world-space vertices (Möller & Trumbore, "Fast, minimum storage
//! ray-triangle intersection", J. Graphics Tools 2(1), 1997). Hit *quantities* are
//! then recomputed in `T` by the same formula on the triangle's object-frame
//! vertices mapped by the `T` transform, so `t`, the point and the normal carry
//! derivatives with respect to translation, rotation and scale.

use std::sync::Arc;
use std::time::Duration;

use glam::Vec3A;
use obvhs::{aabb::Aabb, cwbvh::CwBvh, ray::RayHit, BvhBuildParams};
use usray_ad::Real;

use crate::{MeshError, Ray, Transform, Vec3};

/// An indexed triangle mesh in its object frame (metres).
///
/// Triangles are wound counter-clockwise seen from outside: the geometric normal
/// `(v1 − v0) × (v2 − v0)` points **out of** the solid. A closed mesh (every edge
/// shared by exactly two triangles, traversed in opposite directions) bounds a
/// solid, which is what ray parity ([`MeshInstance::contains`]) and the
/// enter/exit convention need. [`TriangleMesh::orient_outward`] fixes a closed
/// mesh wound the other way.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct TriangleMesh {
    /// Vertex positions, metres, object frame.
    pub positions: Vec<[f64; 3]>,
    /// Vertex indices of each triangle (counter-clockwise seen from outside).
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleMesh {
    /// A mesh from positions and triangles, checked: at least one triangle, every
    /// index in range, every coordinate finite.
    pub fn new(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        let m = Self {
            positions,
            triangles,
        };
        m.check("<memory>")?;
        Ok(m)
    }

    /// The checks of [`TriangleMesh::new`], naming `source` in errors.
    pub fn check(&self, source: &str) -> Result<(), MeshError> {
        if self.triangles.is_empty() {
            return Err(MeshError::NoTriangles {
                file: source.to_string(),
            });
        }
        for (i, p) in self.positions.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(MeshError::NonFiniteVertex {
                    file: source.to_string(),
                    vertex: i,
                });
            }
        }
        let n = self.positions.len();
        for (i, t) in self.triangles.iter().enumerate() {
            if t.iter().any(|&k| k as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    file: source.to_string(),
                    triangle: i,
                    vertices: n,
                });
            }
        }
        Ok(())
    }

    /// The three object-frame corners of triangle `i`.
    #[inline]
    pub fn corners(&self, i: usize) -> [[f64; 3]; 3] {
        let t = self.triangles[i];
        [
            self.positions[t[0] as usize],
            self.positions[t[1] as usize],
            self.positions[t[2] as usize],
        ]
    }

    /// Area of triangle `i`, m².
    pub fn triangle_area(&self, i: usize) -> f64 {
        let [a, b, c] = self.corners(i).map(Vec3::<f64>::from);
        0.5 * (b - a).cross(c - a).length()
    }

    /// Signed enclosed volume, m³ (divergence theorem: `Σ v0·(v1 × v2)/6`);
    /// positive for a closed mesh wound outward.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|i| {
                let [a, b, c] = self.corners(i).map(Vec3::<f64>::from);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Total surface area, m².
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|i| self.triangle_area(i))
            .sum()
    }

    /// Reverse the winding of every triangle (flips all normals).
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// If the mesh encloses a negative signed volume, flip it so normals point
    /// outward. Returns true when it flipped.
    pub fn orient_outward(&mut self) -> bool {
        if self.signed_volume() < 0.0 {
            self.flip();
            true
        } else {
            false
        }
    }

    /// True when every edge is used by exactly two triangles in opposite directions
    /// (a closed, consistently oriented 2-manifold-with-possible-pinches).
    pub fn is_closed(&self) -> bool {
        use std::collections::HashMap;
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        directed
            .iter()
            .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
    }

    /// Axis-aligned bounds `(min, max)` of the vertices, metres.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// An icosphere: the regular icosahedron subdivided `subdivisions` times, every
    /// vertex projected onto the sphere of radius `radius_m` centred at the
    /// origin (an inscribed polyhedron, wound outward; `20·4^subdivisions`
    /// triangles).
    ///
    /// ```
    /// let m = usray_geometry::TriangleMesh::icosphere(1.0, 2);
    /// assert_eq!(m.triangles.len(), 320);
    /// m.assert_well_formed();
    /// ```
    pub fn icosphere(radius_m: f64, subdivisions: u32) -> Self {
        use std::collections::HashMap;
        let g = (1.0 + 5.0_f64.sqrt()) / 2.0;
        let mut pos: Vec<[f64; 3]> = vec![
            [-1.0, g, 0.0],
            [1.0, g, 0.0],
            [-1.0, -g, 0.0],
            [1.0, -g, 0.0],
            [0.0, -1.0, g],
            [0.0, 1.0, g],
            [0.0, -1.0, -g],
            [0.0, 1.0, -g],
            [g, 0.0, -1.0],
            [g, 0.0, 1.0],
            [-g, 0.0, -1.0],
            [-g, 0.0, 1.0],
        ];
        let mut tris: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        let unit = |p: [f64; 3]| {
            let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            [p[0] / l, p[1] / l, p[2] / l]
        };
        for p in &mut pos {
            *p = unit(*p);
        }
        for _ in 0..subdivisions {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut next = Vec::with_capacity(tris.len() * 4);
            let mut midpoint = |a: u32, b: u32, pos: &mut Vec<[f64; 3]>| {
                let key = (a.min(b), a.max(b));
                *mid.entry(key).or_insert_with(|| {
                    let (pa, pb) = (pos[a as usize], pos[b as usize]);
                    pos.push(unit([pa[0] + pb[0], pa[1] + pb[1], pa[2] + pb[2]]));
                    (pos.len() - 1) as u32
                })
            };
            for t in &tris {
                let ab = midpoint(t[0], t[1], &mut pos);
                let bc = midpoint(t[1], t[2], &mut pos);
                let ca = midpoint(t[2], t[0], &mut pos);
                next.push([t[0], ab, ca]);
                next.push([t[1], bc, ab]);
                next.push([t[2], ca, bc]);
                next.push([ab, bc, ca]);
            }
            tris = next;
        }
        let mut m = Self {
            positions: pos
                .into_iter()
                .map(|p| [p[0] * radius_m, p[1] * radius_m, p[2] * radius_m])
                .collect(),
            triangles: tris,
        };
        m.orient_outward();
        m
    }

    /// Append another mesh (indices are offset).
    pub fn append(&mut self, other: &TriangleMesh) {
        let off = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|k| k + off)));
    }

    /// Invariant checker (in the spirit of parry's `assert_*` helpers), for tests:
    /// panics with a description unless the mesh is valid ([`TriangleMesh::check`]),
    /// has no degenerate triangle, is closed and consistently oriented
    /// ([`TriangleMesh::is_closed`]) and encloses a positive volume (outward
    /// winding).
    pub fn assert_well_formed(&self) {
        if let Err(e) = self.check("<assert_well_formed>") {
            panic!("mesh invalid: {e}");
        }
        for i in 0..self.triangles.len() {
            assert!(
                self.triangle_area(i) > 0.0,
                "mesh triangle {i} is degenerate (zero area)"
            );
        }
        assert!(
            self.is_closed(),
            "mesh is not closed/consistently oriented (some edge not shared by exactly two opposite triangles)"
        );
        let v = self.signed_volume();
        assert!(
            v > 0.0,
            "mesh encloses non-positive signed volume {v} (inward winding?)"
        );
    }
}

/// Möller–Trumbore (1997): for the ray `o + t d` and triangle `(v0, v1, v2)`,
/// returns `(t, u, v)` with the hit at `(1 − u − v) v0 + u v1 + v v2`, or `None`
/// when the ray is parallel to the triangle's plane or the triangle is degenerate
/// (`det = 0` exactly: never divides by zero). No inside test is applied.
#[inline]
pub fn moller_trumbore<T: Real>(
    o: Vec3<T>,
    d: Vec3<T>,
    v0: Vec3<T>,
    v1: Vec3<T>,
    v2: Vec3<T>,
) -> Option<(T, T, T)> {
    moller_trumbore_edges(o, d, v0, v1 - v0, v2 - v0)
}

/// [`moller_trumbore`] with the edges `e1 = v1 − v0`, `e2 = v2 − v0` given
/// (bit-identical results when they are computed the same way).
#[inline(always)]
pub fn moller_trumbore_edges<T: Real>(
    o: Vec3<T>,
    d: Vec3<T>,
    v0: Vec3<T>,
    e1: Vec3<T>,
    e2: Vec3<T>,
) -> Option<(T, T, T)> {
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.value() == 0.0 || !det.value().is_finite() {
        return None;
    }
    let inv = det.recip();
    let s = o - v0;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    let t = e2.dot(q) * inv;
    Some((t, u, v))
}

/// An `f32` compressed-wide BVH (`obvhs::cwbvh`) over a mesh's world-space
/// triangles, with an `f64` copy of the world vertices for exact primitive tests.
///
/// Built from the *value* of the transform: it carries no derivatives. Degenerate
/// (zero-area) triangles are left out, so they are never hit.
///
/// # The BVH frame
/// `obvhs`'s CWBVH node test clamps the entry distance to at least `1e-4`
/// (`cwbvh::node::EPSILON`, in whatever units the coordinates are), which in
/// metres would cull every node within 0.1 mm of the ray origin — thin valve
/// leaflets and creases would leak. The BVH is therefore built in a normalised
/// frame, `q = (p_world − center)·scale` with the mesh's bounding-box diagonal
/// mapped to [`BVH_FRAME_EXTENT`] units, and every traversal ray starts
/// [`BVH_ORIGIN_SHIFT`] units *behind* its true origin; candidate triangles are
/// then tested in `f64` world coordinates from the true origin, so nothing in
/// front of the origin is ever culled.
#[derive(Clone)]
pub struct MeshBvh {
    bvh: CwBvh,
    /// BVH primitive → mesh triangle index.
    prim_triangle: Vec<u32>,
    /// Per BVH primitive: world-space `f64` corners.
    prim_world: Vec<[[f64; 3]; 3]>,
    /// Per BVH primitive: BVH-frame `f32` triangle (bare traversal benchmark).
    prim_f32: Vec<obvhs::triangle::Triangle>,
    /// Per BVH slot: world-space `f64` `[v0, v1 − v0, v2 − v0]` and the mesh
    /// triangle index (the `f64` test without the `primitive_indices`
    /// indirection).
    slot64: Vec<([[f64; 3]; 3], u32)>,
    /// Diagonal of the world bounds, metres.
    extent: f64,
    /// World point mapped to the BVH-frame origin, metres.
    center: [f64; 3],
    /// BVH-frame units per metre.
    scale: f64,
}

/// Bounding-box diagonal of a mesh in BVH-frame units (see [`MeshBvh`]).
pub const BVH_FRAME_EXTENT: f64 = 1000.0;

/// How far behind its origin a traversal ray starts, in BVH-frame units (100× the
/// `obvhs` node-entry floor of `1e-4`; 1e-5 of the mesh size).
pub const BVH_ORIGIN_SHIFT: f64 = 1e-2;

impl core::fmt::Debug for MeshBvh {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("MeshBvh")
            .field("primitives", &self.prim_triangle.len())
            .field("nodes", &self.bvh.nodes.len())
            .finish()
    }
}

/// A closest hit found on values: distance (metres) and mesh triangle index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshHit {
    /// Ray parameter, metres (f64 primitive test).
    pub t: f64,
    /// Index of the triangle in the mesh.
    pub triangle: u32,
}

impl MeshBvh {
    /// Build over `mesh` placed by `world_from_object` (values). Errors when no
    /// triangle has a non-zero world-space area.
    pub fn build(
        mesh: &TriangleMesh,
        world_from_object: &Transform<f64>,
    ) -> Result<Self, MeshError> {
        mesh.check("<MeshBvh::build>")?;
        let world: Vec<[f64; 3]> = mesh
            .positions
            .iter()
            .map(|p| world_from_object.transform_point(Vec3::from(*p)).value())
            .collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in &world {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent =
            ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt();
        let center = [
            0.5 * (lo[0] + hi[0]),
            0.5 * (lo[1] + hi[1]),
            0.5 * (lo[2] + hi[2]),
        ];
        let scale = if extent > 0.0 && extent.is_finite() {
            BVH_FRAME_EXTENT / extent
        } else {
            1.0
        };
        // BVH-frame coordinates are at most ~BVH_FRAME_EXTENT/2: f32 rounding is
        // ~3e-5 units; pad every box by 1e-3 units (1e-6 of the mesh size).
        let pad = (1e-6 * BVH_FRAME_EXTENT) as f32;

        let mut prim_triangle = Vec::new();
        let mut prim_world = Vec::new();
        let mut prim_f32 = Vec::new();
        let mut aabbs = Vec::new();
        for (i, t) in mesh.triangles.iter().enumerate() {
            let c = t.map(|k| world[k as usize]);
            let [a, b, cc] = c.map(Vec3::<f64>::from);
            let area2 = (b - a).cross(cc - a).length();
            if area2.is_nan() || area2 <= 0.0 || !area2.is_finite() {
                continue; // degenerate: never hit
            }
            let q = c.map(|p| {
                [
                    (p[0] - center[0]) * scale,
                    (p[1] - center[1]) * scale,
                    (p[2] - center[2]) * scale,
                ]
            });
            let v = q.map(|p| Vec3A::new(p[0] as f32, p[1] as f32, p[2] as f32));
            let mut bb = Aabb::from_points(&v);
            bb.min -= Vec3A::splat(pad);
            bb.max += Vec3A::splat(pad);
            aabbs.push(bb);
            prim_triangle.push(i as u32);
            prim_world.push(c);
            prim_f32.push(obvhs::triangle::Triangle {
                v0: v[0],
                v1: v[1],
                v2: v[2],
            });
        }
        if aabbs.is_empty() {
            return Err(MeshError::NoTriangles {
                file: "<MeshBvh::build: every triangle is degenerate>".to_string(),
            });
        }
        let bvh = obvhs::cwbvh::builder::build_cwbvh(
            &aabbs,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        // The f64 test data in traversal order: `obvhs` hands the callback a slot
        // index, and this saves the `primitive_indices` indirection and the edge
        // subtractions per candidate.
        let slot64 = bvh
            .primitive_indices
            .iter()
            .map(|&p| {
                let [a, b, c] = prim_world[p as usize];
                let sub = |x: [f64; 3], y: [f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
                ([a, sub(b, a), sub(c, a)], prim_triangle[p as usize])
            })
            .collect();
        Ok(Self {
            bvh,
            prim_triangle,
            prim_world,
            prim_f32,
            slot64,
            extent,
            center,
            scale,
        })
    }

    /// Number of (non-degenerate) triangles in the BVH.
    pub fn len(&self) -> usize {
        self.prim_triangle.len()
    }

    /// True when the BVH holds no triangle (never, for a built BVH).
    pub fn is_empty(&self) -> bool {
        self.prim_triangle.is_empty()
    }

    /// Diagonal of the world-space bounds, metres.
    pub fn extent(&self) -> f64 {
        self.extent
    }

    /// The traversal ray in the BVH frame, started [`BVH_ORIGIN_SHIFT`] behind
    /// the true origin, or `None` when it is not finite in `f32` (`obvhs` asserts
    /// finite rays in debug builds). A world distance `t` along the ray is
    /// `t·scale + BVH_ORIGIN_SHIFT` along the traversal ray (`dir` unit).
    fn f32_ray(&self, origin: [f64; 3], dir: [f64; 3], t_max: f64) -> Option<obvhs::ray::Ray> {
        let q = |k: usize| (origin[k] - self.center[k]) * self.scale - dir[k] * BVH_ORIGIN_SHIFT;
        let o = Vec3A::new(q(0) as f32, q(1) as f32, q(2) as f32);
        let d = Vec3A::new(dir[0] as f32, dir[1] as f32, dir[2] as f32);
        if !(o.is_finite() && d.is_finite()) || t_max.is_nan() {
            return None;
        }
        let tmax = self.to_traversal_t(t_max);
        Some(obvhs::ray::Ray::new(o, d, 0.0, tmax))
    }

    /// World distance → traversal-ray distance, rounded up a little so `f32`
    /// culling never drops a marginally nearer `f64` hit.
    #[inline]
    fn to_traversal_t(&self, t: f64) -> f32 {
        let ts = t * self.scale + BVH_ORIGIN_SHIFT;
        if ts >= f32::MAX as f64 {
            f32::INFINITY
        } else {
            (ts as f32) * (1.0 + 8.0 * f32::EPSILON) + 1e-6
        }
    }

    /// The `f64` test of BVH slot `id` (same arithmetic as [`moller_trumbore`]
    /// on the world corners): `(t, mesh triangle)` of a hit on the triangle.
    #[inline(always)]
    fn slot_t(&self, id: usize, o: Vec3<f64>, d: Vec3<f64>) -> Option<(f64, u32)> {
        let ([a, e1, e2], tri) = self.slot64[id];
        let (a, e1, e2) = (Vec3::from(a), Vec3::from(e1), Vec3::from(e2));
        let (t, u, v) = moller_trumbore_edges(o, d, a, e1, e2)?;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t.is_finite()).then_some((t, tri))
    }

    /// The closest triangle hit with `t` in `[t_min, t_max]` (metres): BVH
    /// traversal in `f32`, every candidate triangle tested in `f64` against the
    /// world-space vertices (edges precomputed in `f64`, stored in traversal
    /// order; bit-identical to [`moller_trumbore`] on the corners).
    ///
    /// An `f32` pre-test of the candidates (conservative Möller–Trumbore in the
    /// BVH frame with forward error bounds, `f64` only for the survivors) was
    /// measured and removed: on the valve scene a tracer ray meets only ≈ 3.5
    /// candidates, and the bounded `f32` test cost about as many instructions as
    /// the `f64` test it saved (`callgrind`: +2.6 % for `closest_hit`); see
    /// `docs/performance.md`.
    pub fn closest_hit(
        &self,
        origin: [f64; 3],
        dir: [f64; 3],
        t_min: f64,
        t_max: f64,
    ) -> Option<MeshHit> {
        let ray = self.f32_ray(origin, dir, t_max)?;
        let (o, d) = (Vec3::from(origin), Vec3::from(dir));
        let mut best: Option<MeshHit> = None;
        let mut rh = RayHit::none();
        self.bvh
            .ray_traverse(ray, &mut rh, |_r, id| match self.slot_t(id, o, d) {
                Some((t, triangle)) if t >= t_min && t <= t_max && best.is_none_or(|b| t < b.t) => {
                    best = Some(MeshHit { t, triangle });
                    self.to_traversal_t(t)
                }
                _ => f32::INFINITY,
            });
        best
    }

    /// Number of triangle crossings with `t > t_min` along a ray (f64 tests).
    pub fn count_crossings(&self, origin: [f64; 3], dir: [f64; 3], t_min: f64) -> usize {
        let Some(ray) = self.f32_ray(origin, dir, f64::INFINITY) else {
            return 0;
        };
        let (o, d) = (Vec3::from(origin), Vec3::from(dir));
        let mut n = 0;
        self.bvh.ray_traverse_anyhit(ray, |_r, id| {
            if let Some((t, _)) = self.slot_t(id, o, d) {
                if t > t_min {
                    n += 1;
                }
            }
        });
        n
    }

    /// **Bare `obvhs` traversal** for benchmarks: `f32` ray (world frame, metres,
    /// unit `dir`), mapped to the BVH frame in `f32`, `f32` Möller–Trumbore of
    /// `obvhs::triangle::Triangle::intersect`, no `f64` refinement and no
    /// derivative work. Returns `(t, mesh triangle index)` of the closest hit with
    /// `t_min ≤ t ≤ t_max` (metres, `f32` accuracy). Compare whole-tracer rays/s
    /// against this on the same rays and `t` ranges.
    pub fn traverse_f32(
        &self,
        origin: [f32; 3],
        dir: [f32; 3],
        t_min: f32,
        t_max: f32,
    ) -> Option<(f32, u32)> {
        if !(origin.iter().chain(dir.iter()).all(|c| c.is_finite())) || t_max.is_nan() {
            return None;
        }
        let (scale, shift) = (self.scale as f32, BVH_ORIGIN_SHIFT as f32);
        let c = self.center.map(|x| x as f32);
        let o = Vec3A::new(
            (origin[0] - c[0]) * scale - dir[0] * shift,
            (origin[1] - c[1]) * scale - dir[1] * shift,
            (origin[2] - c[2]) * scale - dir[2] * shift,
        );
        let ray = obvhs::ray::Ray::new(
            o,
            Vec3A::from(dir),
            t_min.max(0.0) * scale + shift,
            t_max * scale + shift,
        );
        let mut rh = RayHit::none();
        if self.bvh.ray_traverse(ray, &mut rh, |r, id| {
            self.prim_f32[self.bvh.primitive_indices[id] as usize].intersect(r)
        }) {
            let prim = self.bvh.primitive_indices[rh.primitive_id as usize] as usize;
            Some(((rh.t - shift) / scale, self.prim_triangle[prim]))
        } else {
            None
        }
    }

    /// Invariant checker for tests: the `obvhs` structural validation (every node
    /// and primitive reachable, child boxes inside parents, depth within the
    /// traversal stack) plus this wrapper's tables being consistent. Panics on
    /// failure.
    pub fn assert_well_formed(&self) {
        let aabbs: Vec<Aabb> = self.prim_f32.iter().map(|t| t.aabb()).collect();
        let _ = self.bvh.validate(&aabbs, false);
        let n = self.prim_triangle.len();
        assert_eq!(self.prim_world.len(), n, "MeshBvh tables differ in length");
        assert_eq!(self.prim_f32.len(), n, "MeshBvh tables differ in length");
        assert_eq!(self.bvh.primitive_indices.len(), n, "BVH primitive count");
        assert_eq!(self.slot64.len(), n, "MeshBvh tables differ in length");
        for (slot, &p) in self.bvh.primitive_indices.iter().enumerate() {
            let ([a, _, _], tri) = self.slot64[slot];
            assert!(
                (p as usize) < n && a == self.prim_world[p as usize][0],
                "BVH slot {slot}: f64 table out of order"
            );
            assert_eq!(
                tri, self.prim_triangle[p as usize],
                "BVH slot {slot}: triangle"
            );
        }
        let mut seen = vec![false; n];
        for &p in &self.bvh.primitive_indices {
            assert!((p as usize) < n, "BVH primitive index {p} out of range");
            assert!(!seen[p as usize], "BVH primitive {p} referenced twice");
            seen[p as usize] = true;
        }
        for (i, c) in self.prim_world.iter().enumerate() {
            assert!(
                c.iter().flatten().all(|x| x.is_finite()),
                "BVH primitive {i} has a non-finite vertex"
            );
        }
    }
}

/// A triangle mesh placed in the world by a differentiable transform.
///
/// The BVH is built once from the transform's value and shared (`Arc`) between
/// clones and between scalar types (see [`MeshInstance::with_transform`]).
#[derive(Clone, Debug)]
pub struct MeshInstance<T> {
    /// The mesh in its object frame.
    pub mesh: Arc<TriangleMesh>,
    /// Object frame → world frame (differentiable).
    pub world_from_object: Transform<T>,
    /// BVH over the world-space triangles at the transform's value.
    pub bvh: Arc<MeshBvh>,
    /// Optional differentiable object-frame vertex positions (same order and
    /// values as `mesh.positions`), for meshes whose shape is a parameter (e.g.
    /// [`crate::valve::valve_leaflet_positions`]); see
    /// [`MeshInstance::with_vertices`].
    pub vertices: Option<Arc<Vec<Vec3<T>>>>,
}

impl<T: Real> MeshInstance<T> {
    /// Place `mesh` with `world_from_object`; builds the BVH.
    pub fn new(
        mesh: Arc<TriangleMesh>,
        world_from_object: Transform<T>,
    ) -> Result<Self, MeshError> {
        if !world_from_object.is_valid() {
            return Err(MeshError::BadTransform);
        }
        let bvh = Arc::new(MeshBvh::build(&mesh, &world_from_object.to_f64())?);
        Ok(Self {
            mesh,
            world_from_object,
            bvh,
            vertices: None,
        })
    }

    /// Attach differentiable object-frame vertex positions: hit quantities are
    /// then recomputed from these (mapped by the `T` transform), so `t` carries
    /// derivatives with respect to whatever the vertices depend on. Their values
    /// must equal `mesh.positions` (same order), since the BVH was built from
    /// those; a mismatch (or a different count) is an error.
    pub fn with_vertices(mut self, vertices: Vec<Vec3<T>>) -> Result<Self, MeshError> {
        let same = vertices.len() == self.mesh.positions.len()
            && vertices
                .iter()
                .zip(&self.mesh.positions)
                .all(|(v, p)| v.value() == *p);
        if !same {
            return Err(MeshError::VerticesMismatch {
                expected: self.mesh.positions.len(),
                got: vertices.len(),
            });
        }
        self.vertices = Some(Arc::new(vertices));
        Ok(self)
    }

    /// The same mesh and BVH with a transform in another scalar type. The new
    /// transform must have the **same value** as the one the BVH was built from
    /// (e.g. the dual version of the same scene); this is not checked beyond a
    /// debug assertion. Differentiable vertices are not carried over (attach
    /// them again with [`MeshInstance::with_vertices`]).
    pub fn with_transform<U: Real>(&self, world_from_object: Transform<U>) -> MeshInstance<U> {
        debug_assert_eq!(world_from_object.to_f64(), self.world_from_object.to_f64());
        MeshInstance {
            mesh: self.mesh.clone(),
            world_from_object,
            bvh: self.bvh.clone(),
            vertices: None,
        }
    }

    /// Values only (shares mesh and BVH).
    pub fn to_f64(&self) -> MeshInstance<f64> {
        self.with_transform(self.world_from_object.to_f64())
    }

    /// Closest hit on values (see [`MeshBvh::closest_hit`]).
    pub fn find(&self, ray: &Ray<f64>, t_min: f64, t_max: f64) -> Option<MeshHit> {
        self.bvh
            .closest_hit(ray.origin.value(), ray.dir.value(), t_min, t_max)
    }

    /// World-space corners of a triangle in `T` (through the `T` transform).
    #[inline]
    pub fn world_corners(&self, triangle: u32) -> [Vec3<T>; 3] {
        match &self.vertices {
            Some(v) => self.mesh.triangles[triangle as usize]
                .map(|k| self.world_from_object.transform_point(v[k as usize])),
            None => self
                .mesh
                .corners(triangle as usize)
                .map(|p| self.world_from_object.transform_point(Vec3::from_f64s(p))),
        }
    }

    /// `t` (metres) and unit outward normal of the hit of `ray` with `triangle`,
    /// recomputed in `T` by Möller–Trumbore on the transformed vertices. `None`
    /// only if the triangle is degenerate or parallel to the ray in `T`'s values.
    pub fn hit_quantities(&self, ray: &Ray<T>, triangle: u32) -> Option<(T, Vec3<T>)> {
        let [a, b, c] = self.world_corners(triangle);
        let (t, _, _) = moller_trumbore(ray.origin, ray.dir, a, b, c)?;
        let mut n = (b - a).cross(c - a).normalize();
        if self.world_from_object.flips_orientation() {
            n = -n;
        }
        Some((t, n))
    }

    /// Point inside the closed mesh (values), by ray parity: the majority vote of
    /// three fixed, irrational-ish directions (an edge or vertex hit along one
    /// direction cannot flip the answer).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        const DIRS: [[f64; 3]; 3] = [
            [0.571_2, 0.312_9, 0.758_8],
            [-0.423_1, 0.691_7, -0.585_3],
            [0.271_3, -0.833_9, 0.480_1],
        ];
        let votes = DIRS
            .iter()
            .filter(|d| {
                let d = Vec3::from(**d).normalize().value();
                self.bvh.count_crossings(p, d, 0.0) % 2 == 1
            })
            .count();
        votes >= 2
    }
}
