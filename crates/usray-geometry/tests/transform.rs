//! Transforms: Euler and axis-angle agree, rotations are orthonormal, inverse
//! round-trips, normals stay perpendicular under non-uniform scale; the geometry
//! types are thread-safe.

use usray_ad::Dual;
use usray_geometry::{Geometry, Mat3, Transform, Vec3};

fn close3(a: [f64; 3], b: [f64; 3], tol: f64) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() <= tol, "{a:?} vs {b:?}");
    }
}

#[test]
fn euler_single_axis_equals_axis_angle() {
    for (k, axis) in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        .iter()
        .enumerate()
    {
        let mut e = [0.0; 3];
        e[k] = 0.7;
        let a = Transform::from_euler(Vec3::zero(), Vec3::from(e), Vec3::new(1.0, 1.0, 1.0));
        let b = Transform::from_axis_angle(
            Vec3::zero(),
            Vec3::from(*axis).scale(0.7),
            Vec3::new(1.0, 1.0, 1.0),
        );
        let p = Vec3::new(0.3, -0.2, 0.9);
        close3(
            a.transform_point(p).value(),
            b.transform_point(p).value(),
            1e-15,
        );
    }
    // Right-handed: +90° about z takes x to y.
    let r = Mat3::rotation_z(std::f64::consts::FRAC_PI_2);
    close3(
        r.mul_vec(Vec3::new(1.0, 0.0, 0.0)).value(),
        [0.0, 1.0, 0.0],
        1e-15,
    );
}

#[test]
fn rotations_are_orthonormal_and_inverse_round_trips() {
    let w = Transform::<f64>::from_axis_angle(
        Vec3::new(0.01, -0.02, 0.03),
        Vec3::new(0.3, -1.1, 0.4),
        Vec3::new(2.0, 0.5, 3.0),
    );
    let r = w.rotation;
    for i in 0..3 {
        for j in 0..3 {
            let d = r.rows[i].dot(r.rows[j]);
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((d - want).abs() < 1e-15, "R Rᵀ[{i}{j}] = {d}");
        }
    }
    assert!((r.determinant() - 1.0).abs() < 1e-14);
    let p = Vec3::new(0.004, 0.005, -0.006);
    close3(
        w.inverse_transform_point(w.transform_point(p)).value(),
        p.value(),
        1e-17,
    );
    assert!(!w.flips_orientation());
    let m = Transform::from_euler(Vec3::zero(), Vec3::zero(), Vec3::new(1.0, -1.0, 1.0));
    assert!(m.flips_orientation());
}

#[test]
fn normals_stay_perpendicular_under_nonuniform_scale() {
    let w = Transform::<f64>::from_euler(
        Vec3::new(0.0, 0.0, 0.02),
        Vec3::new(0.2, 0.4, -0.3),
        Vec3::new(3.0, 0.5, 1.5),
    );
    // A plane with normal n contains tangents t1, t2.
    let n = Vec3::<f64>::new(1.0, 2.0, -0.5).normalize();
    let t1 = n.cross(Vec3::new(0.0, 0.0, 1.0)).normalize();
    let t2 = n.cross(t1);
    let nw = w.transform_normal(n);
    assert!((nw.length() - 1.0).abs() < 1e-15);
    assert!(nw.dot(w.transform_vector(t1)).abs() < 1e-15);
    assert!(nw.dot(w.transform_vector(t2)).abs() < 1e-15);
}

#[test]
fn translation_derivative_is_identity() {
    type D = Dual<3>;
    let w = Transform::from_translation(Vec3::new(
        D::variable(0.1, 0),
        D::variable(0.2, 1),
        D::variable(0.3, 2),
    ));
    let p = w.transform_point(Vec3::from_f64s([1.0, 2.0, 3.0]));
    assert_eq!(
        [p.x.eps, p.y.eps, p.z.eps],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    );
}

#[test]
fn geometry_is_send_and_sync() {
    fn check<T: Send + Sync + Clone>() {}
    check::<Geometry<f64>>();
    check::<Geometry<Dual<4>>>();
    check::<usray_geometry::MediumStack>();
}
