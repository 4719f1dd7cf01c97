//! Analytic shapes against closed forms: distances, normals, inside starts,
//! nearest-object selection.

use usray_geometry::shapes::{
    cylinder::Cylinder, half_space::HalfSpace, hollow_cylinder::HollowCylinder, slab::Slab,
    sphere::Sphere,
};
use usray_geometry::{Geometry, Ray, Vec3};

const EPS: f64 = 1e-9; // t_min, metres

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn assert_vec(a: [f64; 3], b: [f64; 3], tol: f64) {
    for k in 0..3 {
        assert!(close(a[k], b[k], tol), "{a:?} vs {b:?}");
    }
}

#[test]
fn sphere_axis_parallel_rays_match_closed_form() {
    let (zc, r) = (0.02, 0.004);
    let mut g = Geometry::<f64>::new();
    g.add(Sphere::new(Vec3::new(0.0, 0.0, zc), r)).unwrap();
    for &x0 in &[0.0, 0.001, -0.002, 0.0035, 0.00399] {
        let ray = Ray::from_f64s([x0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let h = g.intersect(&ray, EPS, 1.0).unwrap();
        let s = (r * r - x0 * x0).sqrt();
        assert!(close(h.t, zc - s, 1e-15), "x0 {x0}: {} vs {}", h.t, zc - s);
        assert_vec(h.normal.value(), [x0 / r, 0.0, -s / r], 1e-12);
        assert!(h.entering(&ray.dir));
        // Continue from the entry: exit at zc + s with outward normal.
        let r2 = Ray::new(h.point, ray.dir);
        let h2 = g.intersect(&r2, EPS, 1.0).unwrap();
        assert!(close(h.t + h2.t, zc + s, 1e-15));
        assert_vec(h2.normal.value(), [x0 / r, 0.0, s / r], 1e-12);
        assert!(!h2.entering(&ray.dir));
    }
    // Misses just outside the radius.
    let ray = Ray::from_f64s([0.00401, 0.0, 0.0], [0.0, 0.0, 1.0]);
    assert!(g.intersect(&ray, EPS, 1.0).is_none());
}

#[test]
fn sphere_oblique_rays_land_on_surface() {
    let c = [0.003, -0.001, 0.025];
    let r = 0.006;
    let mut g = Geometry::<f64>::new();
    g.add(Sphere::new(Vec3::from(c), r)).unwrap();
    let mut hits = 0;
    for i in 0..200 {
        let a = i as f64 * 0.0123;
        let dir = [0.3 * a.sin(), 0.2 * (1.7 * a).cos(), 1.0];
        let ray = Ray::from_f64s([0.001 * a.cos(), 0.0, 0.0], dir);
        if let Some(h) = g.intersect(&ray, EPS, 1.0) {
            hits += 1;
            let p = h.point.value();
            let d = ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
            assert!(close(d, r, 1e-15), "point off the sphere by {}", d - r);
            assert!(close(h.normal.length(), 1.0, 1e-14));
            assert!(h.entering(&ray.dir));
        }
    }
    assert!(hits > 20, "only {hits} hits");
}

#[test]
fn ray_starting_inside_sphere_exits() {
    let mut g = Geometry::<f64>::new();
    g.add(Sphere::new(Vec3::new(0.0, 0.0, 0.02), 0.005))
        .unwrap();
    let ray = Ray::from_f64s([0.0, 0.0, 0.02], [0.6, 0.0, 0.8]);
    let h = g.intersect(&ray, EPS, 1.0).unwrap();
    assert!(close(h.t, 0.005, 1e-15));
    assert_vec(h.normal.value(), [0.6, 0.0, 0.8], 1e-12);
    assert!(!h.entering(&ray.dir));
}

#[test]
fn cylinder_is_infinite_along_y_and_matches_closed_form() {
    let (zc, r) = (0.015, 0.005);
    let mut g = Geometry::<f64>::new();
    g.add(Cylinder::new(Vec3::new(0.001, 0.7, zc), r)).unwrap();
    for &(x0, beta) in &[(0.001, 0.0), (0.003, 0.3), (-0.0025, -0.6), (0.0059, 0.1)] {
        // Direction tilted in elevation by beta: the xz-footprint is along z.
        let ray = Ray::from_f64s([x0, 0.0, 0.0], [0.0, f64::sin(beta), f64::cos(beta)]);
        let h = g.intersect(&ray, EPS, 1.0).unwrap();
        let dx = x0 - 0.001;
        let s = (r * r - dx * dx).sqrt();
        let t = (zc - s) / beta.cos();
        assert!(close(h.t, t, 1e-15), "{} vs {t}", h.t);
        assert_vec(h.normal.value(), [dx / r, 0.0, -s / r], 1e-12);
    }
    // A ray parallel to the axis never crosses the surface, inside or outside.
    let inside = Ray::from_f64s([0.001, 0.0, zc], [0.0, 1.0, 0.0]);
    assert!(g.intersect(&inside, EPS, 1e3).is_none());
    assert!(g.contains(0, [0.001, 123.0, zc]));
    assert!(!g.contains(0, [0.001, 0.0, zc + 0.0051]));
}

#[test]
fn hollow_cylinder_wall_sequence_and_normals() {
    let (zc, rr, th) = (0.04, 0.02, 0.003);
    let mut g = Geometry::<f64>::new();
    g.add(HollowCylinder::new(Vec3::new(0.0, 0.0, zc), rr, th))
        .unwrap();
    let dir = Vec3::new(0.0, 0.0, 1.0);
    let expect = [
        (zc - rr, 0, [0.0, 0.0, -1.0], true),
        (zc - rr + th, 1, [0.0, 0.0, 1.0], false),
        (zc + rr - th, 1, [0.0, 0.0, -1.0], true),
        (zc + rr, 0, [0.0, 0.0, 1.0], false),
    ];
    let mut origin = Vec3::new(0.0, 0.0, 0.0);
    let mut travelled = 0.0;
    for (t_exp, surf, n_exp, entering) in expect {
        let ray = Ray::new(origin, dir);
        let h = g.intersect(&ray, EPS, 1.0).unwrap();
        travelled += h.t;
        assert!(close(travelled, t_exp, 1e-15), "{travelled} vs {t_exp}");
        assert_eq!(h.surface, surf);
        assert_vec(h.normal.value(), n_exp, 1e-12);
        assert_eq!(h.entering(&dir), entering);
        origin = h.point;
    }
    assert!(g.intersect(&Ray::new(origin, dir), EPS, 1.0).is_none());
    // contains: wall only.
    assert!(g.contains(0, [0.0, 0.0, zc - rr + 0.5 * th]));
    assert!(!g.contains(0, [0.0, 0.0, zc]));
    assert!(!g.contains(0, [0.0, 0.0, zc - rr - 1e-4]));
}

#[test]
fn oblique_hollow_cylinder_hits_lie_on_their_circles() {
    let (c, rr, th) = ([0.002, 0.0, 0.03], 0.01, 0.002);
    let mut g = Geometry::<f64>::new();
    g.add(HollowCylinder::new(Vec3::from(c), rr, th)).unwrap();
    for i in 0..100 {
        let a = -0.4 + 0.008 * i as f64;
        let ray = Ray::from_f64s([0.0, 0.0, 0.0], [a.sin(), 0.1, a.cos()]);
        let mut o = ray.origin;
        while let Some(h) = g.intersect(&Ray::new(o, ray.dir), EPS, 1.0) {
            let p = h.point.value();
            let rho = ((p[0] - c[0]).powi(2) + (p[2] - c[2]).powi(2)).sqrt();
            let want = if h.surface == 0 { rr } else { rr - th };
            assert!(close(rho, want, 1e-15), "surface {} rho {rho}", h.surface);
            // Outward normal of the wall: away from the axis outside, towards it inside.
            let radial = [(p[0] - c[0]) / rho, 0.0, (p[2] - c[2]) / rho];
            let sign = if h.surface == 0 { 1.0 } else { -1.0 };
            assert_vec(h.normal.value(), radial.map(|x| sign * x), 1e-12);
            o = h.point;
        }
    }
}

#[test]
fn slab_and_half_space_closed_forms() {
    let mut g = Geometry::<f64>::new();
    let slab = g.add(Slab::new(0.01, 0.013)).unwrap();
    let half = g.add(HalfSpace::below_depth(0.03)).unwrap();
    let dir = [0.28, 0.0, 0.96];
    let ray = Ray::from_f64s([0.0, 0.0, 0.0], dir);
    let h = g.intersect(&ray, EPS, 1.0).unwrap();
    assert_eq!((h.object, h.surface), (slab, 0));
    assert!(close(h.t, 0.01 / 0.96, 1e-15));
    assert_vec(h.normal.value(), [0.0, 0.0, -1.0], 0.0);
    let h2 = g.intersect(&Ray::new(h.point, ray.dir), EPS, 1.0).unwrap();
    assert_eq!((h2.object, h2.surface), (slab, 1));
    assert!(close(h2.t, 0.003 / 0.96, 1e-15));
    assert_vec(h2.normal.value(), [0.0, 0.0, 1.0], 0.0);
    let h3 = g.intersect(&Ray::new(h2.point, ray.dir), EPS, 1.0).unwrap();
    assert_eq!(h3.object, half);
    assert!(close(h2.point.z + h3.t * 0.96, 0.03, 1e-15));
    assert!(h3.entering(&ray.dir));
    // t_max culls.
    assert!(g.intersect(&ray, EPS, 0.01).is_none());
    // A ray parallel to the planes never hits them.
    let flat = Ray::from_f64s([0.0, 0.0, 0.011], [1.0, 0.0, 0.0]);
    assert!(g.intersect(&flat, EPS, 1e3).is_none());
    // Tilted half-space: plane through (0,0,0.02) with outward normal towards -x-z.
    let mut g2 = Geometry::<f64>::new();
    g2.add(HalfSpace::new(
        Vec3::new(0.0, 0.0, 0.02),
        Vec3::new(-1.0, 0.0, -1.0),
    ))
    .unwrap();
    let h = g2
        .intersect(&Ray::from_f64s([0.0; 3], [0.0, 0.0, 1.0]), EPS, 1.0)
        .unwrap();
    assert!(close(h.t, 0.02, 1e-15));
    let s = 0.5_f64.sqrt();
    assert_vec(h.normal.value(), [-s, 0.0, -s], 1e-15);
}

#[test]
fn nearest_object_wins_and_ids_are_indices() {
    let mut g = Geometry::<f64>::new();
    let far = g
        .add(Sphere::new(Vec3::new(0.0, 0.0, 0.05), 0.005))
        .unwrap();
    let near = g
        .add(Cylinder::new(Vec3::new(0.0, 0.0, 0.02), 0.004))
        .unwrap();
    assert_eq!((far, near), (0, 1));
    let ray = Ray::from_f64s([0.0; 3], [0.0, 0.0, 1.0]);
    let h = g.intersect(&ray, EPS, 1.0).unwrap();
    assert_eq!(h.object, near);
    assert!(close(h.t, 0.016, 1e-15));
    let h = g.intersect(&ray, 0.025, 1.0).unwrap();
    assert_eq!(h.object, far);
    assert!(close(h.t, 0.045, 1e-15));
}

#[test]
fn invalid_parameters_are_rejected() {
    let mut g = Geometry::<f64>::new();
    assert!(g.add(Sphere::new(Vec3::zero(), 0.0)).is_err());
    assert!(g.add(Sphere::new(Vec3::zero(), f64::NAN)).is_err());
    assert!(g
        .add(Cylinder::new(Vec3::new(f64::INFINITY, 0.0, 0.0), 1.0))
        .is_err());
    assert!(g
        .add(HollowCylinder::new(Vec3::zero(), 0.01, 0.01))
        .is_err());
    assert!(g.add(HollowCylinder::new(Vec3::zero(), 0.01, 0.0)).is_err());
    assert!(g.add(Slab::new(0.02, 0.01)).is_err());
    assert!(g.add(HalfSpace::new(Vec3::zero(), Vec3::zero())).is_err());
    assert!(g.is_empty());
    let e = g
        .add(HollowCylinder::new(Vec3::zero(), 0.01, 0.02))
        .unwrap_err();
    assert!(e.to_string().contains("thickness_m"), "{e}");
}

#[test]
fn in_plane_curvature_is_signed_against_the_outward_normal() {
    // Along the axis line x = 0 through a tube, a cylinder and a sphere whose
    // centre is off the plane y = 0 (its cut at y = 0 a circle of radius
    // √(r² − y_c²)); then a slab.
    let mut g = Geometry::<f64>::new();
    let (rr, th) = (0.004, 0.001);
    g.add(HollowCylinder::new(Vec3::new(0.0, 0.0, 0.01), rr, th))
        .unwrap();
    g.add(Cylinder::new(Vec3::new(0.0, 0.0, 0.03), 0.002))
        .unwrap();
    g.add(Sphere::new(Vec3::new(0.0, 0.003, 0.05), 0.005))
        .unwrap();
    g.add(Slab::new(0.07, 0.08)).unwrap();
    let dir = Vec3::new(0.0, 0.0, 1.0);
    // Tube outer, inner, inner, outer; cylinder in, out; sphere in, out; slab top, bottom.
    let want = [
        1.0 / rr,
        -1.0 / (rr - th),
        -1.0 / (rr - th),
        1.0 / rr,
        500.0,
        500.0,
        250.0,
        250.0,
        0.0,
        0.0,
    ];
    let mut origin = Vec3::new(0.0, 0.0, 0.0);
    for (k, w) in want.into_iter().enumerate() {
        let h = g.intersect(&Ray::new(origin, dir), EPS, 1.0).unwrap();
        let kappa = g.in_plane_curvature(&h);
        assert!(
            close(kappa, w, 1e-9 * w.abs().max(1.0)),
            "hit {k}: {kappa} vs {w}"
        );
        origin = h.point;
    }
}
