//! Grazing and degenerate inputs: no NaN, no panic; rays starting on surfaces;
//! the nested-media convention walked along rays.

use std::sync::Arc;

use usray_ad::Dual;
use usray_geometry::shapes::{
    cylinder::Cylinder, half_space::HalfSpace, hollow_cylinder::HollowCylinder, slab::Slab,
    sphere::Sphere,
};
use usray_geometry::{Geometry, MediumStack, MeshInstance, Ray, Transform, TriangleMesh, Vec3};

fn finite_hit<const N: usize>(h: &usray_geometry::Hit<Dual<N>>) -> bool {
    h.t.re.is_finite()
        && h.t.eps.iter().all(|e| e.is_finite())
        && [
            h.normal.x, h.normal.y, h.normal.z, h.point.x, h.point.y, h.point.z,
        ]
        .iter()
        .all(|c| c.re.is_finite() && c.eps.iter().all(|e| e.is_finite()))
}

#[test]
fn grazing_rays_give_no_nan_values_or_derivatives() {
    type D = Dual<2>;
    let r = 0.005;
    let mut g = Geometry::<D>::new();
    g.add(Sphere::new(
        Vec3::from_f64s([0.0, 0.0, 0.02]),
        D::variable(r, 0),
    ))
    .unwrap();
    g.add(Cylinder::new(
        Vec3::from_f64s([0.03, 0.0, 0.02]),
        D::variable(r, 1),
    ))
    .unwrap();
    // Offsets through exactly tangent and within a few ulps of tangent.
    let mut n_hits = 0;
    for k in -4..=4 {
        let x = r + k as f64 * 1e-18;
        for base in [0.0, 0.03] {
            let ray = Ray::<D>::from_f64s([base + x, 0.0, 0.0], [0.0, 0.0, 1.0]);
            if let Some(h) = g.intersect(&ray, 1e-9, 1.0) {
                n_hits += 1;
                assert!(finite_hit(&h), "offset {x}: {h:?}");
            }
        }
    }
    // Exactly tangent rays are misses by convention; the rest may hit.
    let exact = Ray::<D>::from_f64s([r, 0.0, 0.0], [0.0, 0.0, 1.0]);
    assert!(g.intersect(&exact, 1e-9, 1.0).is_none());
    assert!(
        n_hits >= 4,
        "near-tangent rays inside the radius must hit ({n_hits})"
    );
    // Near-grazing on a slab (dz tiny): t huge but finite, or beyond t_max.
    let mut s = Geometry::<D>::new();
    s.add(Slab::new(D::variable(0.01, 0), D::constant(0.02)))
        .unwrap();
    let ray = Ray::<D>::new(
        Vec3::zero(),
        Vec3::from_f64s([1.0, 0.0, 1e-300]).normalize(),
    );
    if let Some(h) = s.intersect(&ray, 1e-9, f64::MAX) {
        assert!(finite_hit(&h));
    }
    let flat = Ray::<D>::from_f64s([0.0, 0.0, 0.015], [1.0, 0.0, 0.0]);
    assert!(s.intersect(&flat, 1e-9, f64::MAX).is_none());
}

#[test]
fn non_finite_or_zero_rays_never_hit_or_panic() {
    let mut g = Geometry::<f64>::new();
    g.add(Sphere::new(Vec3::new(0.0, 0.0, 0.02), 0.005))
        .unwrap();
    g.add(
        MeshInstance::new(
            Arc::new(TriangleMesh::icosphere(0.004, 1)),
            Transform::identity(),
        )
        .unwrap(),
    )
    .unwrap();
    for (o, d) in [
        ([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 0.0, 0.0], [f64::INFINITY, 0.0, 1.0]),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
    ] {
        let ray = Ray::new(Vec3::from(o), Vec3::from(d));
        assert!(g.intersect(&ray, 1e-9, 1.0).is_none(), "{o:?} {d:?}");
    }
    // Zero vector normalisation: finite value and derivatives.
    let z = Vec3::new(
        Dual::<1>::variable(0.0, 0),
        Dual::constant(0.0),
        Dual::constant(0.0),
    );
    let n = z.normalize();
    assert!(n.x.re == 0.0 && n.x.eps[0].is_finite());
    assert_eq!(z.length().eps[0], 0.0);
    // Tiny and huge vectors normalise without under/overflow.
    for s in [1e-300, 1e300] {
        let v = Vec3::new(3.0 * s, 0.0, 4.0 * s).normalize().value();
        assert!(
            (v[0] - 0.6).abs() < 1e-15 && (v[2] - 0.8).abs() < 1e-15,
            "{v:?}"
        );
    }
}

#[test]
fn rays_starting_on_a_surface_skip_it_with_t_min() {
    let mut g = Geometry::<f64>::new();
    g.add(Sphere::new(Vec3::new(0.0, 0.0, 0.02), 0.005))
        .unwrap();
    g.add(
        MeshInstance::new(
            Arc::new(TriangleMesh::icosphere(0.004, 3)),
            Transform::from_translation(Vec3::new(0.02, 0.0, 0.02)),
        )
        .unwrap(),
    )
    .unwrap();
    for (x, k) in [(0.0, 0usize), (0.02, 1usize)] {
        let ray = Ray::from_f64s([x + 0.001, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let h = g.intersect(&ray, 1e-9, 1.0).unwrap();
        assert_eq!(h.object, k);
        // Leave from the hit point, both straight on and reflected back out.
        let on = g.intersect(&Ray::new(h.point, ray.dir), 1e-9, 1.0).unwrap();
        assert_eq!(on.object, k);
        assert!(on.t > 1e-3, "re-hit the entry surface at t = {}", on.t);
        assert!(!on.entering(&ray.dir));
        let n = h.normal;
        let refl = ray.dir - n * (2.0 * ray.dir.dot(n));
        let back = g.intersect(&Ray::new(h.point, refl), 1e-9, 1.0);
        assert!(back.is_none(), "reflected ray re-hit {back:?}");
    }
}

#[test]
fn medium_stack_follows_innermost_containing_along_rays() {
    // Background water; a big sphere (0) containing a tube (1) and a mesh ball (2)
    // inside the tube's wall region's neighbour; a half-space (3) far below.
    let mut g = Geometry::<f64>::new();
    g.add(Sphere::new(Vec3::new(0.0, 0.0, 0.03), 0.02)).unwrap();
    g.add(HollowCylinder::new(Vec3::new(0.0, 0.0, 0.03), 0.012, 0.003))
        .unwrap();
    g.add(
        MeshInstance::new(
            Arc::new(TriangleMesh::icosphere(0.004, 3)),
            Transform::from_translation(Vec3::new(0.0, 0.0, 0.03)),
        )
        .unwrap(),
    )
    .unwrap();
    g.add(HalfSpace::below_depth(0.06)).unwrap();
    let mut n_cross = 0;
    for i in 0..60 {
        let a = -0.5 + i as f64 / 60.0;
        let ray = Ray::from_f64s([0.0, 0.0, 0.0], [a.sin(), 0.05, a.cos()]);
        let mut stack = g.stack_at(ray.origin.value());
        assert!(stack.is_empty());
        let mut o = ray.origin;
        while let Some(h) = g.intersect(&Ray::new(o, ray.dir), 1e-9, 1.0) {
            let before = stack.top();
            let mid_before = (o + ray.dir * (0.5 * h.t)).value();
            assert_eq!(
                before,
                g.innermost_containing(mid_before),
                "before hit {h:?}"
            );
            let predicted = if h.entering(&ray.dir) {
                Some(h.object)
            } else {
                stack.after_exit(h.object)
            };
            stack.cross(h.object, h.entering(&ray.dir));
            assert_eq!(stack.top(), predicted);
            o = h.point;
            n_cross += 1;
        }
        // After the last hit the ray is inside the half-space.
        assert_eq!(stack.top(), Some(3));
    }
    assert!(n_cross > 300, "{n_cross}");
    let mut s = MediumStack::new();
    assert!(
        !s.exit(5),
        "exiting an object never entered is reported, not a panic"
    );
    for k in 0..usray_geometry::MEDIUM_STACK_DEPTH {
        assert!(s.push(k));
    }
    assert!(!s.push(99));
}

#[test]
fn rays_far_outside_f32_range_do_not_panic() {
    let inst = MeshInstance::new(
        Arc::new(TriangleMesh::icosphere(0.004, 1)),
        Transform::<f64>::identity(),
    )
    .unwrap();
    assert!(inst
        .bvh
        .closest_hit([1e300, 0.0, 0.0], [-1.0, 0.0, 0.0], 0.0, f64::INFINITY)
        .is_none());
    assert!(inst
        .bvh
        .traverse_f32([f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], 0.0, 1.0)
        .is_none());
    assert!(!inst.contains([1e300, 0.0, 0.0]));
    assert!(inst
        .bvh
        .closest_hit([0.0; 3], [0.0, 0.0, 1.0], 0.0, f64::NAN)
        .is_none());
}
