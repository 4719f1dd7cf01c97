//! Hit derivatives carried by `Dual` against central finite differences of the
//! `f64` hit and against the analytic implicit-function derivative
//! `dt = (dρ_surface + n·dc − n·do)/(n·d)` (from differentiating the surface
//! equation at the hit point).

use usray_ad::{Dual, Real};
use usray_geometry::shapes::{
    cylinder::Cylinder, hollow_cylinder::HollowCylinder, slab::Slab, sphere::Sphere,
};
use usray_geometry::{Geometry, Ray, Shape, Vec3};

type D4 = Dual<4>;

/// Central difference of `f` at `x` with step `h` (error O(h²)).
fn central(f: impl Fn(f64) -> f64, x: f64, h: f64) -> f64 {
    (f(x + h) - f(x - h)) / (2.0 * h)
}

fn hit_t<S: Into<Shape<f64>>>(shape: S, ray: Ray<f64>) -> f64 {
    let mut g = Geometry::<f64>::new();
    g.add(shape).unwrap();
    g.intersect(&ray, 1e-9, 1.0).unwrap().t
}

fn check(name: &str, ad: f64, fd: f64, analytic: Option<f64>) {
    // FD with h = 1e-7 m on t ≈ 1e-2 m: truncation ~h²·t''' and rounding
    // ~1e-16·t/h ≈ 1e-11; 1e-6 absolute on O(1) derivatives is far looser than both
    // and far tighter than any wrong formula.
    assert!((ad - fd).abs() < 1e-6, "{name}: AD {ad} vs FD {fd}");
    if let Some(a) = analytic {
        assert!((ad - a).abs() < 1e-10, "{name}: AD {ad} vs analytic {a}");
    }
}

#[test]
fn sphere_dt_dradius_and_dcentre() {
    let (c, r) = ([0.001, -0.0005, 0.02], 0.004);
    let (o, d) = ([0.0015, 0.0, 0.0], [0.05, 0.02, 1.0]);
    let ray64 = Ray::from_f64s(o, d);
    let ray = Ray::<D4>::from_f64s(o, d);
    let sph = Sphere::new(
        Vec3::new(
            D4::variable(c[0], 0),
            D4::variable(c[1], 1),
            D4::variable(c[2], 2),
        ),
        D4::variable(r, 3),
    );
    let mut g = Geometry::<D4>::new();
    g.add(sph).unwrap();
    let h = g.intersect(&ray, 1e-9, 1.0).unwrap();
    let n = h.normal.value();
    let dv = ray64.dir.value();
    let nd = n[0] * dv[0] + n[1] * dv[1] + n[2] * dv[2];
    let step = 1e-7;
    for k in 0..3 {
        let fd = central(
            |x| {
                let mut cc = c;
                cc[k] = x;
                hit_t(Sphere::new(Vec3::from(cc), r), ray64)
            },
            c[k],
            step,
        );
        check(&format!("dt/dc{k}"), h.t.eps[k], fd, Some(n[k] / nd));
    }
    let fd = central(|x| hit_t(Sphere::new(Vec3::from(c), x), ray64), r, step);
    check("dt/dr", h.t.eps[3], fd, Some(1.0 / nd));
    // The normal's derivative too (FD of the f64 normal).
    let normal_of = |x: f64| {
        let mut g = Geometry::<f64>::new();
        g.add(Sphere::new(Vec3::from(c), x)).unwrap();
        g.intersect(&ray64, 1e-9, 1.0).unwrap().normal.value()
    };
    for k in 0..3 {
        let fd = (normal_of(r + step)[k] - normal_of(r - step)[k]) / (2.0 * step);
        assert!(
            (h.normal.get(k).eps[3] - fd).abs() < 1e-5 * (1.0 + fd.abs()),
            "dn{k}/dr: {} vs {fd}",
            h.normal.get(k).eps[3]
        );
    }
}

#[test]
fn cylinder_dt_dradius_dcentre_and_exit_root() {
    let (c, r) = ([0.0008, 0.0, 0.015], 0.005);
    let (o, d) = ([0.0, 0.0, 0.0], [0.1, 0.3, 1.0]);
    let ray64 = Ray::from_f64s(o, d);
    let ray = Ray::<D4>::from_f64s(o, d);
    let cyl = Cylinder::new(
        Vec3::new(
            D4::variable(c[0], 0),
            D4::constant(c[1]),
            D4::variable(c[2], 2),
        ),
        D4::variable(r, 3),
    );
    let mut g = Geometry::<D4>::new();
    g.add(cyl).unwrap();
    for (which, t_min) in [("entry", 1e-9), ("exit", 0.0125)] {
        let h = g.intersect(&ray, t_min, 1.0).unwrap();
        let n = h.normal.value();
        let dv = ray64.dir.value();
        let nd = n[0] * dv[0] + n[2] * dv[2];
        let t_of = |cc: [f64; 3], rr: f64| {
            let mut g = Geometry::<f64>::new();
            g.add(Cylinder::new(Vec3::from(cc), rr)).unwrap();
            g.intersect(&ray64, t_min, 1.0).unwrap().t
        };
        let step = 1e-7;
        for k in [0, 2] {
            let fd = central(
                |x| {
                    let mut cc = c;
                    cc[k] = x;
                    t_of(cc, r)
                },
                c[k],
                step,
            );
            check(
                &format!("{which} dt/dc{k}"),
                h.t.eps[k],
                fd,
                Some(n[k] / nd),
            );
        }
        assert_eq!(h.t.eps[1], 0.0, "the axis position along y cannot matter");
        let fd = central(|x| t_of(c, x), r, step);
        check(&format!("{which} dt/dr"), h.t.eps[3], fd, Some(1.0 / nd));
    }
}

#[test]
fn hollow_cylinder_dt_dthickness_on_inner_surface() {
    let (zc, rr, th) = (0.04, 0.02, 0.003);
    let ray = Ray::<Dual<2>>::from_f64s([0.002, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let tube = HollowCylinder::new(
        Vec3::from_f64s([0.0, 0.0, zc]),
        Dual::<2>::variable(rr, 0),
        Dual::<2>::variable(th, 1),
    );
    let mut g = Geometry::<Dual<2>>::new();
    g.add(tube).unwrap();
    let outer = g.intersect(&ray, 1e-9, 1.0).unwrap();
    assert_eq!(outer.surface, 0);
    let inner = g.intersect(&ray, outer.t.value() + 1e-9, 1.0).unwrap();
    assert_eq!(inner.surface, 1);
    // Inner entry point z = zc − √((R−t)² − x0²): dz/dR = −(R−t)/√(…), dz/dt = +(R−t)/√(…).
    let ri = rr - th;
    let s = (ri * ri - 0.002f64 * 0.002).sqrt();
    check("inner dt/dR", inner.t.eps[0], -ri / s, Some(-ri / s));
    check("inner dt/dthickness", inner.t.eps[1], ri / s, Some(ri / s));
    // Outer surface does not depend on the thickness.
    assert_eq!(outer.t.eps[1], 0.0);
    let fd = central(
        |x| {
            let mut g = Geometry::<f64>::new();
            g.add(HollowCylinder::new(Vec3::new(0.0, 0.0, zc), rr, x))
                .unwrap();
            let r64 = ray.to_f64();
            let o = g.intersect(&r64, 1e-9, 1.0).unwrap();
            g.intersect(&r64, o.t + 1e-9, 1.0).unwrap().t
        },
        th,
        1e-7,
    );
    check("inner dt/dthickness FD", inner.t.eps[1], fd, None);
}

#[test]
fn slab_and_ray_origin_derivatives() {
    type D2 = Dual<2>;
    let d = [0.6, 0.0, 0.8];
    // Derivative w.r.t. the slab depth and w.r.t. the ray origin's x (which must be 0
    // for a horizontal plane) and z.
    let slab = Slab::new(D2::variable(0.01, 0), D2::constant(0.02));
    let mut g = Geometry::<D2>::new();
    g.add(slab).unwrap();
    let ray = Ray::new(
        Vec3::new(D2::constant(0.0), D2::constant(0.0), D2::variable(0.001, 1)),
        Vec3::from_f64s(d),
    );
    let h = g.intersect(&ray, 1e-9, 1.0).unwrap();
    check("dt/dz_top", h.t.eps[0], 1.0 / 0.8, Some(1.0 / 0.8));
    check("dt/do_z", h.t.eps[1], -1.0 / 0.8, Some(-1.0 / 0.8));
    // The hit point's depth follows the plane exactly.
    assert!((h.point.z.eps[0] - 1.0).abs() < 1e-15 && h.point.z.eps[1].abs() < 1e-15);
}

#[test]
fn derivatives_flow_through_the_ray_direction() {
    // A refracted ray's direction depends on parameters; t must carry that.
    type D1 = Dual<1>;
    let a = D1::variable(0.1, 0); // steering angle, rad
    let ray = Ray::new(Vec3::zero(), Vec3::new(a.sin(), D1::zero(), a.cos()));
    let mut g = Geometry::<D1>::new();
    g.add(Sphere::new(
        Vec3::from_f64s([0.0, 0.0, 0.02]),
        D1::constant(0.005),
    ))
    .unwrap();
    let h = g.intersect(&ray, 1e-9, 1.0).unwrap();
    let fd = central(
        |x| {
            hit_t(
                Sphere::new(Vec3::new(0.0, 0.0, 0.02), 0.005),
                Ray::from_f64s([0.0; 3], [x.sin(), 0.0, x.cos()]),
            )
        },
        0.1,
        1e-7,
    );
    check("dt/dangle", h.t.eps[0], fd, None);
    assert!(h.t.eps[0].abs() > 1e-4, "test must be sensitive");
}

#[test]
fn values_match_f64_exactly() {
    // The dual's value path is the f64 computation.
    let sph64 = Sphere::new(Vec3::new(0.001, 0.0, 0.02), 0.004);
    let r64 = Ray::from_f64s([0.0; 3], [0.01, 0.0, 1.0]);
    let t64 = hit_t(sph64, r64);
    let mut g = Geometry::<D4>::new();
    g.add(Sphere::new(
        Vec3::from_f64s([0.001, 0.0, 0.02]),
        D4::variable(0.004, 3),
    ))
    .unwrap();
    let h = g
        .intersect(&Ray::from_f64s([0.0; 3], [0.01, 0.0, 1.0]), 1e-9, 1.0)
        .unwrap();
    assert_eq!(h.t.value(), t64);
}

#[test]
fn reverse_mode_gradient_matches_forward_mode() {
    use usray_ad::reverse::Recording;
    let (c, r) = ([0.001, 0.0, 0.03], 0.012);
    let th = 0.003;
    let (o, d) = ([0.002, 0.001, 0.0], [0.05, 0.0, 1.0]);
    // Forward: second hit (inner wall) of a tube, w.r.t. (cx, cz, r, thickness).
    let fwd = {
        let tube = HollowCylinder::new(
            Vec3::new(
                D4::variable(c[0], 0),
                D4::constant(0.0),
                D4::variable(c[2], 1),
            ),
            D4::variable(r, 2),
            D4::variable(th, 3),
        );
        let mut g = Geometry::<D4>::new();
        g.add(tube).unwrap();
        let ray = Ray::<D4>::from_f64s(o, d);
        let h1 = g.intersect(&ray, 1e-9, 1.0).unwrap();
        let h2 = g
            .intersect(&Ray::new(h1.point, ray.dir), 1e-9, 1.0)
            .unwrap();
        (h1.t + h2.t).eps
    };
    let mut grad = [0.0; 4];
    {
        let rec = Recording::start();
        let [cx, cz, rr, tt] = rec.inputs_array::<4>(&[c[0], c[2], r, th]);
        let tube = HollowCylinder::new(Vec3::new(cx, Real::zero(), cz), rr, tt);
        let mut g = Geometry::new();
        g.add(tube).unwrap();
        let ray = Ray::from_f64s(o, d);
        let h1 = g.intersect(&ray, 1e-9, 1.0).unwrap();
        let h2 = g
            .intersect(&Ray::new(h1.point, ray.dir), 1e-9, 1.0)
            .unwrap();
        rec.gradient(h1.t + h2.t, &mut grad);
    }
    for k in 0..4 {
        assert!(
            (grad[k] - fwd[k]).abs() < 1e-12,
            "{k}: {} vs {}",
            grad[k],
            fwd[k]
        );
    }
    assert!(
        grad[3].abs() > 0.5,
        "thickness must matter for the inner wall"
    );
}
