//! The enter/exit convention for every shape: just before a hit the point is
//! inside the object iff the ray is exiting, just after iff it is entering; the
//! normal is unit and the point lies on the ray.

use std::sync::Arc;

use proptest::prelude::*;
use usray_geometry::shapes::{
    cylinder::Cylinder, half_space::HalfSpace, hollow_cylinder::HollowCylinder, slab::Slab,
    sphere::Sphere,
};
use usray_geometry::valve::{valve_leaflets, ValveParams};
use usray_geometry::{Geometry, MeshInstance, Ray, Shape, Transform, TriangleMesh, Vec3};

fn shapes() -> Vec<(&'static str, Shape<f64>)> {
    let valve = MeshInstance::new(
        Arc::new(valve_leaflets(0.7, &ValveParams::default())),
        Transform::from_euler(
            Vec3::new(0.0, 0.0, 0.03),
            Vec3::new(1.3, 0.2, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
        ),
    )
    .unwrap();
    let ball = MeshInstance::new(
        Arc::new(TriangleMesh::icosphere(1.0, 3)),
        Transform::from_euler(
            Vec3::new(0.002, 0.0, 0.03),
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(0.012, 0.006, 0.009),
        ),
    )
    .unwrap();
    vec![
        (
            "sphere",
            Sphere::new(Vec3::new(0.001, 0.002, 0.03), 0.01).into(),
        ),
        (
            "cylinder",
            Cylinder::new(Vec3::new(-0.002, 0.0, 0.03), 0.008).into(),
        ),
        (
            "tube",
            HollowCylinder::new(Vec3::new(0.0, 0.0, 0.03), 0.012, 0.002).into(),
        ),
        ("slab", Slab::new(0.02, 0.026).into()),
        (
            "half-space",
            HalfSpace::new(Vec3::new(0.0, 0.0, 0.03), Vec3::new(0.3, 0.1, -1.0)).into(),
        ),
        ("valve mesh", valve.into()),
        ("ellipsoid mesh", ball.into()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn inside_flips_exactly_at_hits(
        ox in -0.02..0.02f64, oy in -0.005..0.005f64, oz in -0.01..0.05f64,
        dx in -1.0..1.0f64, dy in -0.5..0.5f64, dz in -1.0..1.0f64,
    ) {
        prop_assume!(dx * dx + dy * dy + dz * dz > 0.01);
        for (name, shape) in shapes() {
            let mut g = Geometry::<f64>::new();
            g.add(shape).unwrap();
            let ray = Ray::from_f64s([ox, oy, oz], [dx, dy, dz]);
            let mut o = ray.origin;
            let mut n_hits = 0;
            while let Some(h) = g.intersect(&Ray::new(o, ray.dir), 1e-9, 1.0) {
                n_hits += 1;
                prop_assert!(n_hits < 200, "{}: runaway", name);
                prop_assert!((h.normal.length() - 1.0).abs() < 1e-12, "{}: |n| = {}", name, h.normal.length());
                let enter = h.entering(&ray.dir);
                // Skip near-grazing hits, where ±δ along the ray stays within δ·cos of the surface.
                let cos = h.normal.dot(ray.dir).abs();
                if cos > 1e-3 {
                    let d = 1e-8 / cos;
                    let before = (h.point - ray.dir * d).value();
                    let after = (h.point + ray.dir * d).value();
                    prop_assert_eq!(g.contains(0, before), !enter, "{}: before {:?}", name, h);
                    prop_assert_eq!(g.contains(0, after), enter, "{}: after {:?}", name, h);
                }
                let p = (o + ray.dir * h.t).value();
                let q = h.point.value();
                prop_assert!((0..3).all(|k| (p[k] - q[k]).abs() < 1e-15), "{}", name);
                o = h.point;
            }
        }
    }
}
