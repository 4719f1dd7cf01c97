//! [`Sphere`]: a solid ball with differentiable centre and radius.

use super::{solve_quadratic_half_b, Roots};
use crate::{Ray, Vec3};
use usray_ad::Real;

/// A solid sphere `|p − center| < radius` (metres).
///
/// One surface (index 0). Ray intersection: substituting `x = o + t d` into
/// `|x − c|² = r²` gives `(d·d) t² + 2 (d·(o − c)) t + |o − c|² − r² = 0`, solved
/// in cancellation-free form ([`solve_quadratic_half_b`]); the outward normal is
/// `(x − c)/r`.
///
/// ```
/// use usray_geometry::{shapes::sphere::Sphere, Ray, Vec3};
/// let s = Sphere::new(Vec3::new(0.0_f64, 0.0, 0.02), 0.005);
/// let r = Ray::from_f64s([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
/// let roots = s.roots(&r);
/// assert!((roots.items[0].0 - 0.015).abs() < 1e-15);
/// assert!((roots.items[1].0 - 0.025).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere<T> {
    /// Centre, metres.
    pub center: Vec3<T>,
    /// Radius, metres (> 0).
    pub radius: T,
}

impl<T: Real> Sphere<T> {
    /// A sphere from its centre and radius (metres).
    pub fn new(center: Vec3<T>, radius: T) -> Self {
        Self { center, radius }
    }

    /// The crossings of the ray's line with the sphere, nearer first (surface 0).
    #[inline]
    pub fn roots(&self, ray: &Ray<T>) -> Roots<T> {
        let oc = ray.origin - self.center;
        let a = ray.dir.length_squared();
        let b = ray.dir.dot(oc);
        let c = oc.length_squared() - self.radius * self.radius;
        let mut out = Roots::none();
        if let Some((t1, t2)) = solve_quadratic_half_b(a, b, c) {
            out.push(t1, 0);
            out.push(t2, 0);
        }
        out
    }

    /// Unit outward normal `(p − c)/r` at a surface point `p`.
    #[inline]
    pub fn normal_at(&self, p: Vec3<T>, _surface: u32) -> Vec3<T> {
        (p - self.center) * self.radius.recip()
    }

    /// Curvature (1/m) of the cut through the `xz` plane at a surface point
    /// `p` of that plane, signed against the outward normal: the cut is a
    /// circle about the centre's projection, of radius `|p − c|` in `xz`
    /// (`√(r² − c_y²)`), convex.
    #[inline]
    pub fn in_plane_curvature(&self, p: Vec3<T>, _surface: u32) -> T {
        let (dx, dz) = (p.x - self.center.x, p.z - self.center.z);
        (dx * dx + dz * dz).sqrt().recip()
    }

    /// Point strictly inside (values).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let c = self.center.value();
        let r = self.radius.value();
        let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
        d2 < r * r
    }

    /// Values only.
    pub fn to_f64(&self) -> Sphere<f64> {
        Sphere::new(self.center.to_f64(), self.radius.value())
    }

    /// Finite centre and positive finite radius.
    pub fn is_valid(&self) -> bool {
        self.center.is_finite() && self.radius.is_finite() && self.radius.value() > 0.0
    }
}
