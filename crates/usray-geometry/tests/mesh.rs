//! Triangle meshes: BVH against brute force, a tessellated sphere against the
//! analytic sphere within the computed tessellation error, transform derivatives,
//! point-in-solid by parity, degenerate triangles, the bare-traversal entry point.

use std::sync::Arc;

use usray_ad::Dual;
use usray_geometry::shapes::mesh::moller_trumbore;
use usray_geometry::shapes::sphere::Sphere;
use usray_geometry::valve::{
    valve_leaflet_meshes, valve_leaflet_positions, valve_leaflets, ValveParams,
};
use usray_geometry::{Geometry, MeshBvh, MeshInstance, Ray, Transform, TriangleMesh, Vec3};

/// Deterministic pseudo-random numbers in [0, 1) (SplitMix64).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Distance from `p` to the triangle `abc` (Ericson, *Real-Time Collision
/// Detection*, 2005, §5.1.5, closest point on triangle).
fn point_triangle_distance(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return norm(ap);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return norm(bp);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return norm(sub(
            p,
            [a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]],
        ));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return norm(cp);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return norm(sub(
            p,
            [a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]],
        ));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        let bc = sub(c, b);
        return norm(sub(
            p,
            [b[0] + w * bc[0], b[1] + w * bc[1], b[2] + w * bc[2]],
        ));
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    let q = [
        a[0] + ab[0] * v + ac[0] * w,
        a[1] + ab[1] * v + ac[1] * w,
        a[2] + ab[2] * v + ac[2] * w,
    ];
    norm(sub(p, q))
}

/// Brute-force closest hit over every non-degenerate triangle (f64).
fn brute_force(inst: &MeshInstance<f64>, ray: &Ray<f64>, t_min: f64) -> Option<(f64, u32)> {
    let mut best: Option<(f64, u32)> = None;
    for i in 0..inst.mesh.triangles.len() {
        let [a, b, c] = inst.world_corners(i as u32);
        if (b - a).cross(c - a).length() == 0.0 {
            continue;
        }
        if let Some((t, u, v)) = moller_trumbore(ray.origin, ray.dir, a, b, c) {
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= t_min && best.is_none_or(|bb| t < bb.0)
            {
                best = Some((t, i as u32));
            }
        }
    }
    best
}

#[test]
fn tessellated_sphere_agrees_with_analytic_sphere_within_tessellation_error() {
    let (c, r) = ([0.002, -0.001, 0.03], 0.008);
    let mesh = TriangleMesh::icosphere(1.0, 4);
    mesh.assert_well_formed();
    let w = Transform::from_euler(
        Vec3::from(c),
        Vec3::new(0.3, -0.2, 0.7), // a rotation must not matter for a sphere
        Vec3::new(r, r, r),
    );
    let inst = MeshInstance::new(Arc::new(mesh.clone()), w).unwrap();
    inst.bvh.assert_well_formed();
    // Tessellation error: the mesh lies between the spheres of radius r − ε and r.
    let eps = (0..inst.mesh.triangles.len())
        .map(|i| {
            let [a, b, cc] = inst.world_corners(i as u32).map(|v| v.value());
            r - point_triangle_distance(c, a, b, cc)
        })
        .fold(0.0_f64, f64::max);
    assert!(eps > 0.0 && eps < 1e-3 * r * 50.0, "eps {eps}");
    // Largest angle between a face normal and the radial directions of its corners.
    let max_facet_angle = (0..inst.mesh.triangles.len())
        .map(|i| {
            let [a, b, cc] = inst.world_corners(i as u32);
            let n = (b - a).cross(cc - a).normalize();
            [a, b, cc]
                .iter()
                .map(|v| n.dot((*v - Vec3::from(c)).normalize()).min(1.0).acos())
                .fold(0.0_f64, f64::max)
        })
        .fold(0.0_f64, f64::max);

    let mut geo = Geometry::<f64>::new();
    let mesh_id = geo.add(inst.clone()).unwrap();
    let mut ana = Geometry::<f64>::new();
    ana.add(Sphere::new(Vec3::from(c), r)).unwrap();
    let mut inner = Geometry::<f64>::new();
    inner.add(Sphere::new(Vec3::from(c), r - eps)).unwrap();
    let mut rng = Rng(7);
    let mut n_checked = 0;
    for _ in 0..2000 {
        let o = [rng.range(-0.01, 0.01), rng.range(-0.01, 0.01), 0.0];
        let target = [
            c[0] + rng.range(-0.9, 0.9) * (r - eps),
            c[1] + rng.range(-0.5, 0.5) * (r - eps),
            c[2],
        ];
        let ray = Ray::from_f64s(o, sub(target, o));
        let (Some(hm), Some(hs), Some(hi)) = (
            geo.intersect(&ray, 1e-9, 1.0),
            ana.intersect(&ray, 1e-9, 1.0),
            inner.intersect(&ray, 1e-9, 1.0),
        ) else {
            continue;
        };
        n_checked += 1;
        assert_eq!(hm.object, mesh_id);
        // Exact bracket: t_sphere ≤ t_mesh ≤ t_inner_sphere (up to rounding).
        assert!(
            hm.t >= hs.t - 1e-15 && hm.t <= hi.t + 1e-15,
            "{} not in [{}, {}]",
            hm.t,
            hs.t,
            hi.t
        );
        // Normals: the face normal is within the largest facet angle of the radial
        // direction at the mesh hit point.
        let radial = (hm.point - Vec3::from(c)).normalize();
        let ang = hm.normal.dot(radial).min(1.0).acos();
        assert!(
            ang <= max_facet_angle + 1e-9,
            "normal off by {ang} > {max_facet_angle}"
        );
        assert!(hm.entering(&ray.dir));
    }
    assert!(n_checked > 1500, "only {n_checked} rays checked");

    // Point-in-solid by parity agrees with the sphere away from the shell.
    let mut n_in = 0;
    for _ in 0..3000 {
        let p = [
            c[0] + rng.range(-1.3, 1.3) * r,
            c[1] + rng.range(-1.3, 1.3) * r,
            c[2] + rng.range(-1.3, 1.3) * r,
        ];
        let d = norm(sub(p, c));
        if d > r - eps - 1e-9 && d < r + 1e-9 {
            continue;
        }
        assert_eq!(geo.contains(mesh_id, p), d < r, "p {p:?} at distance {d}");
        n_in += usize::from(d < r);
    }
    assert!(n_in > 300);
}

#[test]
fn bvh_closest_hit_equals_brute_force_on_valve() {
    let mesh = valve_leaflets(0.5, &ValveParams::default());
    let w = Transform::from_euler(
        Vec3::new(0.0, 0.0, 0.03),
        Vec3::new(1.2, 0.1, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
    );
    let inst = MeshInstance::new(Arc::new(mesh), w).unwrap();
    inst.bvh.assert_well_formed();
    let mut rng = Rng(11);
    let (mut hits, mut f32_same) = (0, 0);
    for _ in 0..3000 {
        let o = [rng.range(-0.02, 0.02), rng.range(-0.003, 0.003), 0.0];
        let target = [
            rng.range(-0.02, 0.02),
            rng.range(-0.02, 0.02),
            rng.range(0.02, 0.045),
        ];
        let ray = Ray::from_f64s(o, sub(target, o));
        let bvh = inst.find(&ray, 1e-9, 1.0);
        let bf = brute_force(&inst, &ray, 1e-9);
        match (bvh, bf) {
            (None, None) => {}
            (Some(h), Some((t, tri))) => {
                hits += 1;
                assert_eq!(h.t, t, "same f64 test, same t");
                if h.triangle != tri {
                    // Only a shared edge may differ, at the same t.
                    assert!((h.t - t).abs() == 0.0);
                }
                // Bare f32 traversal finds (nearly) the same hit.
                let o32 = ray.origin.value().map(|x| x as f32);
                let d32 = ray.dir.value().map(|x| x as f32);
                let (t32, tri32) = inst.bvh.traverse_f32(o32, d32, 0.0, f32::INFINITY).unwrap();
                assert!((f64::from(t32) - t).abs() < 1e-6, "f32 {t32} vs {t}");
                f32_same += usize::from(tri32 == tri);
            }
            (a, b) => panic!("BVH {a:?} vs brute force {b:?} for {ray:?}"),
        }
    }
    assert!(hits > 200, "only {hits} hits");
    assert!(f32_same * 100 >= hits * 99, "{f32_same}/{hits}");
}

/// Brute-force `f64` closest hit with `t ∈ [t_min, t_max]` and the number of
/// crossings with `t > t_min`, over every non-degenerate triangle.
fn brute_force_full(
    inst: &MeshInstance<f64>,
    o: [f64; 3],
    d: [f64; 3],
    t_min: f64,
    t_max: f64,
) -> (Option<(f64, u32)>, usize) {
    let (o, d) = (Vec3::from(o), Vec3::from(d));
    let mut best: Option<(f64, u32)> = None;
    let mut crossings = 0;
    for i in 0..inst.mesh.triangles.len() {
        let [a, b, c] = inst.world_corners(i as u32);
        if (b - a).cross(c - a).length() == 0.0 {
            continue;
        }
        if let Some((t, u, v)) = moller_trumbore(o, d, a, b, c) {
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t.is_finite() {
                crossings += usize::from(t > t_min);
                if t >= t_min && t <= t_max && best.is_none_or(|bb| t < bb.0) {
                    best = Some((t, i as u32));
                }
            }
        }
    }
    (best, crossings)
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = norm(v);
    [v[0] / l, v[1] / l, v[2] / l]
}

/// The BVH query equals the brute-force `f64` search over all triangles on the
/// rays that stress hit finding: starting on a leaflet (the tracer's secondary
/// and connection rays), grazing a triangle's plane, aimed at vertices and
/// edges, from near (inside the 0.1 mm `obvhs` node floor) and far; crossing
/// counts (point-in-solid parity) equal brute force too.
#[test]
fn bvh_equals_brute_force_on_surface_grazing_vertex_and_near_rays() {
    let valve = valve_leaflets(0.5, &ValveParams::default());
    let w_valve = Transform::from_euler(
        Vec3::new(0.001, -0.002, 0.012),
        Vec3::new(0.4, -0.3, 0.2),
        Vec3::new(1.0, 1.0, 1.0),
    );
    let sphere = TriangleMesh::icosphere(0.008, 3);
    let w_sphere = Transform::from_translation(Vec3::new(0.0, 0.0, 0.03));
    let mut rng = Rng(2026);
    let mut stats = [0usize; 4]; // hits per family
    for (mesh, w) in [(valve, w_valve), (sphere, w_sphere)] {
        let inst = MeshInstance::new(Arc::new(mesh), w).unwrap();
        let n_tri = inst.mesh.triangles.len();
        for k in 0..6000 {
            let family = k % 4;
            let tri = (rng.next() * n_tri as f64) as u32;
            let [a, b, c] = inst.world_corners(tri).map(|v| v.value());
            let (mut u, mut v) = (rng.next(), rng.next());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            // Sometimes exactly on a vertex or an edge.
            match k % 7 {
                0 => (u, v) = (0.0, 0.0),
                1 => (u, v) = (1.0, 0.0),
                2 => v = 1.0 - u,
                3 => u = 0.0,
                _ => {}
            }
            let p: [f64; 3] = core::array::from_fn(|i| (1.0 - u - v) * a[i] + u * b[i] + v * c[i]);
            let rand_dir = |rng: &mut Rng| {
                unit([
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                ])
            };
            let n = unit({
                let (e1, e2) = (sub(b, a), sub(c, a));
                [
                    e1[1] * e2[2] - e1[2] * e2[1],
                    e1[2] * e2[0] - e1[0] * e2[2],
                    e1[0] * e2[1] - e1[1] * e2[0],
                ]
            });
            let (o, d) = match family {
                // Starting on the surface, any direction.
                0 => (p, rand_dir(&mut rng)),
                // Grazing: along the triangle's plane, from just off it.
                1 => {
                    let along = unit(sub(b, a));
                    let tilt = rng.range(-1e-6, 1e-6);
                    let d = unit(core::array::from_fn(|i| along[i] + tilt * n[i]));
                    let off = rng.range(-1e-9, 1e-9);
                    let o = core::array::from_fn(|i| p[i] - 0.002 * d[i] + off * n[i]);
                    (o, d)
                }
                // Aimed at the point (vertex, edge or interior) from the probe.
                2 => {
                    let o = [rng.range(-0.02, 0.02), rng.range(-0.003, 0.003), 0.0];
                    (o, unit(sub(p, o)))
                }
                // Aimed at it from very close (inside the 0.1 mm obvhs floor).
                _ => {
                    let d = rand_dir(&mut rng);
                    let back = 10f64.powf(rng.range(-9.0, -3.5));
                    (core::array::from_fn(|i| p[i] - back * d[i]), d)
                }
            };
            let t_min = if family == 0 { 1e-9 } else { 0.0 };
            let t_max = if k % 3 == 0 {
                rng.range(0.0, 0.02)
            } else {
                1.0
            };
            let got = inst.bvh.closest_hit(o, d, t_min, t_max);
            let (bf, crossings) = brute_force_full(&inst, o, d, t_min, t_max);
            match (got, bf) {
                (None, None) => {}
                (Some(h), Some((t, _))) => {
                    assert_eq!(h.t, t, "BVH vs brute force: o {o:?} d {d:?}");
                    stats[family] += 1;
                }
                (g, b) => panic!("BVH {g:?} vs brute force {b:?}: o {o:?} d {d:?}"),
            }
            assert_eq!(
                inst.bvh.count_crossings(o, d, t_min),
                crossings,
                "crossings: o {o:?} d {d:?}"
            );
        }
    }
    assert!(stats.iter().all(|&n| n > 300), "hits per family {stats:?}");
}

#[test]
fn mesh_transform_derivatives() {
    // A single upward-facing square (two triangles) is not closed, but hit
    // quantities do not need closure.
    let quad = TriangleMesh::new(
        vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ],
        vec![[0, 2, 1], [0, 3, 2]], // normal −z: faces a probe above it
    )
    .unwrap();
    type D = Dual<7>;
    let (tr, eul, sc) = ([0.001, 0.0, 0.02], [0.2, -0.1, 0.3], 0.01);
    let w = Transform::from_euler(
        Vec3::new(
            D::variable(tr[0], 0),
            D::variable(tr[1], 1),
            D::variable(tr[2], 2),
        ),
        Vec3::new(
            D::variable(eul[0], 3),
            D::variable(eul[1], 4),
            D::variable(eul[2], 5),
        ),
        Vec3::new(D::variable(sc, 6), D::variable(sc, 6), D::variable(sc, 6)),
    );
    let inst = MeshInstance::new(Arc::new(quad.clone()), w).unwrap();
    let mut geo = Geometry::<D>::new();
    geo.add(inst).unwrap();
    let d = [0.1, 0.05, 1.0];
    let ray = Ray::<D>::from_f64s([0.0; 3], d);
    let h = geo.intersect(&ray, 1e-9, 1.0).unwrap();
    let n = h.normal.value();
    let dv = ray.dir.value();
    let nd = dot(n, dv);
    assert!(nd < 0.0, "the quad faces the ray");
    // Translation moves the plane by δ: dt/dT_k = n_k/(n·d) exactly (plane offset
    // along n is n·δ).
    for k in 0..3 {
        let want = n[k] / nd;
        assert!(
            (h.t.eps[k] - want).abs() < 1e-12,
            "dt/dT{k}: {} vs {want}",
            h.t.eps[k]
        );
    }
    // Translating along the ray direction moves t by exactly the same amount.
    let along = h.t.eps[0] * dv[0] + h.t.eps[1] * dv[1] + h.t.eps[2] * dv[2];
    assert!((along - 1.0).abs() < 1e-12, "{along}");
    // Rotation and scale against central differences of the f64 hit.
    let t_of = |tr: [f64; 3], eul: [f64; 3], sc: f64| {
        let w = Transform::from_euler(Vec3::from(tr), Vec3::from(eul), Vec3::new(sc, sc, sc));
        let inst = MeshInstance::new(Arc::new(quad.clone()), w).unwrap();
        let mut g = Geometry::<f64>::new();
        g.add(inst).unwrap();
        g.intersect(&Ray::from_f64s([0.0; 3], d), 1e-9, 1.0)
            .unwrap()
            .t
    };
    let hstep = 1e-6;
    for k in 0..3 {
        let (mut ep, mut em) = (eul, eul);
        ep[k] += hstep;
        em[k] -= hstep;
        let fd = (t_of(tr, ep, sc) - t_of(tr, em, sc)) / (2.0 * hstep);
        assert!(
            (h.t.eps[3 + k] - fd).abs() < 1e-8,
            "dt/deuler{k}: {} vs {fd}",
            h.t.eps[3 + k]
        );
    }
    let fd = (t_of(tr, eul, sc + 1e-7) - t_of(tr, eul, sc - 1e-7)) / 2e-7;
    assert!(
        (h.t.eps[6] - fd).abs() < 1e-6,
        "dt/dscale: {} vs {fd}",
        h.t.eps[6]
    );
    assert!(
        h.t.eps[3..6].iter().any(|x| x.abs() > 1e-4),
        "rotation must matter here"
    );
}

#[test]
fn mirrored_transform_keeps_normals_outward() {
    let mesh = Arc::new(TriangleMesh::icosphere(0.005, 2));
    let w = Transform::from_euler(
        Vec3::new(0.0, 0.0, 0.02),
        Vec3::zero(),
        Vec3::new(-1.0, 1.0, 1.0),
    );
    assert!(w.flips_orientation());
    let mut g = Geometry::<f64>::new();
    g.add(MeshInstance::new(mesh, w).unwrap()).unwrap();
    let ray = Ray::from_f64s([0.0005, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let h = g.intersect(&ray, 1e-9, 1.0).unwrap();
    assert!(h.entering(&ray.dir), "normal {:?}", h.normal);
    assert!(g.contains(0, [0.0, 0.0, 0.02]));
}

#[test]
fn degenerate_triangles_are_never_hit() {
    // A valid triangle plus zero-area ones (repeated vertex, collinear).
    let mesh = TriangleMesh::new(
        vec![
            [-1.0, -1.0, 1.0],
            [1.0, -1.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.0, 0.0, 0.5],
            [0.0, 0.0, 0.5],
            [-1.0, 0.0, 0.6],
            [1.0, 0.0, 0.6],
            [0.0, 0.0, 0.6],
        ],
        vec![[0, 1, 2], [3, 4, 1], [5, 6, 7], [3, 3, 3]],
    )
    .unwrap();
    let inst = MeshInstance::new(Arc::new(mesh), Transform::<f64>::identity()).unwrap();
    assert_eq!(inst.bvh.len(), 1);
    let ray = Ray::from_f64s([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let h = inst.find(&ray, 1e-9, 10.0).unwrap();
    assert_eq!((h.t, h.triangle), (1.0, 0));
    // A mesh with only degenerate triangles cannot be built.
    let bad = TriangleMesh::new(
        vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    assert!(MeshInstance::new(Arc::new(bad), Transform::<f64>::identity()).is_err());
}

#[test]
fn mesh_bvh_is_built_from_the_transform_value_and_shared() {
    let mesh = Arc::new(TriangleMesh::icosphere(0.004, 3));
    let w = Transform::from_translation(Vec3::new(0.0, 0.0, 0.02));
    let inst = MeshInstance::new(mesh, w).unwrap();
    let dual = inst.with_transform(Transform::from_translation(Vec3::new(
        Dual::<1>::constant(0.0),
        Dual::<1>::constant(0.0),
        Dual::<1>::variable(0.02, 0),
    )));
    assert!(Arc::ptr_eq(&inst.bvh, &dual.bvh));
    let mut g = Geometry::<Dual<1>>::new();
    g.add(dual).unwrap();
    let h = g
        .intersect(&Ray::from_f64s([0.0; 3], [0.0, 0.0, 1.0]), 1e-9, 1.0)
        .unwrap();
    // Moving the mesh along the ray moves the hit by the same amount.
    assert!((h.t.eps[0] - 1.0).abs() < 1e-12);
    let _ = MeshBvh::build(&inst.mesh, &inst.world_from_object).unwrap();
}

#[test]
fn valve_leaflets_are_closed_disjoint_shells() {
    for closure in [0.0, 0.5, 1.0] {
        let leaflets = valve_leaflet_meshes(closure, &ValveParams::default());
        assert_eq!(leaflets.len(), 3);
        let insts: Vec<_> = leaflets
            .iter()
            .map(|m| {
                m.assert_well_formed();
                MeshInstance::new(Arc::new(m.clone()), Transform::<f64>::identity()).unwrap()
            })
            .collect();
        for (a, ma) in leaflets.iter().enumerate() {
            for (b, ib) in insts.iter().enumerate() {
                if a != b {
                    let bad = ma.positions.iter().filter(|p| ib.contains(**p)).count();
                    assert_eq!(bad, 0, "closure {closure}: leaflet {a} pokes into {b}");
                }
            }
        }
    }
    // The shell has the requested thickness: a ray through a closed leaflet
    // travels th/|cos θ| inside it (θ the incidence angle on the entry face;
    // the two faces are parallel offsets of the mid-surface, so up to curvature).
    let th = ValveParams::default().thickness_m;
    let closed = valve_leaflets(1.0, &ValveParams::default());
    let mut g = Geometry::<f64>::new();
    g.add(MeshInstance::new(Arc::new(closed), Transform::<f64>::identity()).unwrap())
        .unwrap();
    let mut rng = Rng(5);
    let mut n = 0;
    for _ in 0..400 {
        // Away from the leaflet borders (side walls): within ±40° of a midline.
        let mid = (rng.next() * 3.0).floor() * 2.0 * std::f64::consts::PI / 3.0;
        let (rho, ang) = (rng.range(0.004, 0.012), mid + rng.range(-0.7, 0.7));
        let ray = Ray::from_f64s([rho * ang.cos(), rho * ang.sin(), -0.01], [0.0, 0.0, 1.0]);
        let Some(h1) = g.intersect(&ray, 1e-9, 1.0) else {
            continue; // through a gap between leaflets
        };
        assert!(h1.entering(&ray.dir));
        let h2 = g
            .intersect(&Ray::new(h1.point, ray.dir), 1e-9, 1.0)
            .unwrap();
        assert!(!h2.entering(&ray.dir));
        let want = th / h1.normal.z.abs();
        assert!((h2.t / want - 1.0).abs() < 0.05, "chord {} vs {want}", h2.t);
        n += 1;
    }
    assert!(n > 300, "{n}");
    // Closing moves the free edges towards the axis and the annulus plane.
    let open = valve_leaflets(0.0, &ValveParams::default());
    let closed = valve_leaflets(1.0, &ValveParams::default());
    let min_rho = |m: &TriangleMesh| {
        m.positions
            .iter()
            .map(|p| (p[0] * p[0] + p[1] * p[1]).sqrt())
            .fold(f64::INFINITY, f64::min)
    };
    assert!(min_rho(&open) > 0.01 && min_rho(&closed) < 0.0025);
    assert!(open.bounds().1[2] > 0.012 && closed.bounds().1[2] < 0.006);
}

#[test]
fn shipped_valve_objs_match_the_generator() {
    let dir = usray_testdata::workspace_file("scenes/meshes");
    for (name, closure) in usray_geometry::valve::SCENE_VALVES {
        let path = dir.join(format!("{name}.obj"));
        let loaded = usray_geometry::obj::load_obj(&path).unwrap();
        let fresh = valve_leaflets(closure, &ValveParams::default());
        // The OBJ reader may renumber vertices; compare triangle corners.
        let same = loaded.triangles.len() == fresh.triangles.len()
            && (0..fresh.triangles.len()).all(|i| loaded.corners(i) == fresh.corners(i));
        assert!(
            same,
            "{} is stale: rerun the write_valve_meshes example",
            path.display()
        );
    }
}

#[test]
fn hits_close_to_the_origin_are_not_culled_by_the_bvh() {
    // obvhs's CWBVH node test floors entry distances at 1e-4 (in coordinate
    // units); in metres that would hide every face within 0.1 mm of the origin.
    let quad = TriangleMesh::new(
        vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ],
        vec![[0, 2, 1], [0, 3, 2]],
    )
    .unwrap();
    let w = Transform::from_euler(
        Vec3::new(0.0, 0.0, 0.02),
        Vec3::zero(),
        Vec3::new(0.01, 0.01, 1.0),
    );
    let inst = MeshInstance::new(Arc::new(quad), w).unwrap();
    for delta in [1e-8, 1e-6, 3e-5, 9e-5, 2e-4] {
        let o = [0.001, 0.002, 0.02 - delta];
        let h = inst.bvh.closest_hit(o, [0.0, 0.0, 1.0], 1e-9, 1.0);
        let h = h.unwrap_or_else(|| panic!("missed the face {delta} m ahead"));
        assert!((h.t - delta).abs() < 1e-15, "{} vs {delta}", h.t);
        assert_eq!(inst.bvh.count_crossings(o, [0.0, 0.0, 1.0], 0.0), 1);
        if delta >= 3e-5 {
            let (t32, _) = inst
                .bvh
                .traverse_f32(o.map(|x| x as f32), [0.0, 0.0, 1.0], 0.0, 1.0)
                .unwrap_or_else(|| panic!("bare traversal missed the face {delta} m ahead"));
            assert!((f64::from(t32) - delta).abs() < 1e-8, "{t32} vs {delta}");
            // A `t_min` beyond the face skips it (like the tracer's `T_MIN`).
            let beyond = (2.0 * delta) as f32;
            assert!(inst
                .bvh
                .traverse_f32(o.map(|x| x as f32), [0.0, 0.0, 1.0], beyond, 1.0)
                .is_none());
        }
    }
    // And from just behind the face nothing is hit.
    assert!(inst
        .bvh
        .closest_hit([0.001, 0.002, 0.02 + 1e-8], [0.0, 0.0, 1.0], 1e-9, 1.0)
        .is_none());
}

#[test]
fn valve_openness_derivative_matches_finite_differences() {
    let p = ValveParams::default();
    let place = Transform::from_euler(
        Vec3::new(0.0, 0.0, 0.03),
        Vec3::new(1.4, 0.0, 0.0), // valve axis tilted towards the probe's x-z plane
        Vec3::new(1.0, 1.0, 1.0),
    );
    let step = 1e-6;
    let at =
        |openness: f64| MeshInstance::new(Arc::new(valve_leaflets(openness, &p)), place).unwrap();
    let mut rng = Rng(3);
    let mut checked = 0;
    for openness in [0.3, 0.6] {
        let mesh = Arc::new(valve_leaflets(openness, &p));
        let verts = valve_leaflet_positions(Dual::<1>::variable(openness, 0), &p);
        let place_d = Transform::from_euler(
            Vec3::from_f64s([0.0, 0.0, 0.03]),
            Vec3::from_f64s([1.4, 0.0, 0.0]),
            Vec3::from_f64s([1.0, 1.0, 1.0]),
        );
        let inst = MeshInstance::new(mesh.clone(), place_d)
            .unwrap()
            .with_vertices(verts)
            .unwrap();
        let mut g = Geometry::<Dual<1>>::new();
        g.add(inst).unwrap();
        let (plus, minus) = (at(openness + step), at(openness - step));
        let t_of = |inst: &MeshInstance<f64>, ray: &Ray<f64>| {
            inst.find(ray, 1e-9, 1.0).map(|h| (h.t, h.triangle))
        };
        for _ in 0..200 {
            let o = [rng.range(-0.015, 0.015), rng.range(-0.002, 0.002), 0.0];
            let target = [rng.range(-0.015, 0.015), rng.range(-0.01, 0.01), 0.03];
            let r64 = Ray::from_f64s(o, sub(target, o));
            let Some(h) = g.intersect(&Ray::from_f64s(o, sub(target, o)), 1e-9, 1.0) else {
                continue;
            };
            let (Some((tp, trp)), Some((tm, trm))) = (t_of(&plus, &r64), t_of(&minus, &r64)) else {
                continue;
            };
            if trp != h.primitive || trm != h.primitive {
                continue; // the FD stencil crossed a triangle edge: not comparable
            }
            let fd = (tp - tm) / (2.0 * step);
            assert!(
                (h.t.eps[0] - fd).abs() < 1e-6 * (1.0 + fd.abs()),
                "dt/dopenness {} vs FD {fd}",
                h.t.eps[0]
            );
            checked += 1;
        }
    }
    assert!(checked > 50, "only {checked} rays compared");
    // Mismatched vertices are refused.
    let mesh = Arc::new(valve_leaflets(0.3, &p));
    let wrong = valve_leaflet_positions(0.31, &p)
        .into_iter()
        .map(|v| Vec3::from_f64s(v.value()))
        .collect::<Vec<Vec3<f64>>>();
    assert!(MeshInstance::new(mesh, Transform::<f64>::identity())
        .unwrap()
        .with_vertices(wrong)
        .is_err());
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(128))]

    /// Generated OBJ text — vertices with any numbers (huge, tiny, NaN), faces
    /// with any indices (0, negative, past the end, huge) and of any arity —
    /// parses or is refused naming the file: never a panic, and a mesh that
    /// parses passes its own invariant check.
    #[test]
    fn generated_obj_text_parses_or_is_refused(
        vertices in proptest::collection::vec(proptest::array::uniform3(proptest::num::f64::ANY), 0..6),
        faces in proptest::collection::vec(proptest::collection::vec(-3i64..10, 1..5), 0..5),
        huge in proptest::bool::ANY,
    ) {
        let mut text = String::new();
        for v in &vertices {
            text += &format!("v {} {} {}\n", v[0], v[1], v[2]);
        }
        for f in &faces {
            let idx: Vec<String> = f.iter().map(|i| i.to_string()).collect();
            text += &format!("f {}\n", idx.join(" "));
        }
        if huge {
            text += "f 1 2 99999999999999999999\n";
        }
        match usray_geometry::obj::parse_obj(&text, "gen.obj") {
            Ok(mesh) => proptest::prop_assert!(mesh.check("gen.obj").is_ok()),
            Err(e) => proptest::prop_assert!(e.to_string().contains("gen.obj"), "{}", e),
        }
    }
}
