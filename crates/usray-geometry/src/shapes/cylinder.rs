//! [`Cylinder`]: an infinite solid circular cylinder whose axis is parallel to `y`
//! (the elevation direction of the probe frame).

use super::{solve_quadratic_half_b, Roots};
use crate::{Ray, Vec3};
use usray_ad::Real;

/// A solid circular cylinder `(x − cx)² + (z − cz)² < r²`, infinite along `y`
/// (metres). `center.y` is unused (kept so scenes can give a full 3-point).
///
/// One surface (index 0). Ray intersection: the sphere quadratic restricted to the
/// `xz` components, `(dx² + dz²) t² + 2 (dx ox' + dz oz') t + ox'² + oz'² − r² = 0`
/// with `o' = o − c`; a ray parallel to the axis never crosses the surface. Outward
/// normal `((x − cx)/r, 0, (z − cz)/r)`.
///
/// ```
/// use usray_geometry::{shapes::cylinder::Cylinder, Ray, Vec3};
/// let c = Cylinder::new(Vec3::new(0.0_f64, 0.0, 0.015), 0.005);
/// let r = Ray::from_f64s([0.0, 0.3, 0.0], [0.0, 0.0, 1.0]);
/// assert!((c.roots(&r).items[0].0 - 0.010).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder<T> {
    /// A point on the axis, metres (`y` unused).
    pub center: Vec3<T>,
    /// Radius, metres (> 0).
    pub radius: T,
}

/// Crossings of a ray's line with the infinite y-axis cylinder of radius `r`
/// through `c`, nearer first, tagged `surface`.
#[inline]
pub(crate) fn y_cylinder_roots<T: Real>(
    ray: &Ray<T>,
    c: Vec3<T>,
    r: T,
    surface: u32,
    out: &mut Roots<T>,
) {
    let (ox, oz) = (ray.origin.x - c.x, ray.origin.z - c.z);
    let (dx, dz) = (ray.dir.x, ray.dir.z);
    let a = dx * dx + dz * dz;
    let b = dx * ox + dz * oz;
    let cc = ox * ox + oz * oz - r * r;
    if let Some((t1, t2)) = solve_quadratic_half_b(a, b, cc) {
        out.push(t1, surface);
        out.push(t2, surface);
    }
}

/// Radial distance² from the y axis through `c` (values).
#[inline]
pub(crate) fn rho2(p: [f64; 3], c: [f64; 3]) -> f64 {
    (p[0] - c[0]).powi(2) + (p[2] - c[2]).powi(2)
}

impl<T: Real> Cylinder<T> {
    /// A cylinder from a point on its axis and its radius (metres).
    pub fn new(center: Vec3<T>, radius: T) -> Self {
        Self { center, radius }
    }

    /// Crossings of the ray's line with the surface, nearer first (surface 0).
    #[inline]
    pub fn roots(&self, ray: &Ray<T>) -> Roots<T> {
        let mut out = Roots::none();
        y_cylinder_roots(ray, self.center, self.radius, 0, &mut out);
        out
    }

    /// Unit outward normal at a surface point.
    #[inline]
    pub fn normal_at(&self, p: Vec3<T>, _surface: u32) -> Vec3<T> {
        let k = self.radius.recip();
        Vec3::new(
            (p.x - self.center.x) * k,
            T::zero(),
            (p.z - self.center.z) * k,
        )
    }

    /// Curvature (1/m) of the cut through the `xz` plane at a surface point,
    /// signed against the outward normal: `1/radius` (convex).
    #[inline]
    pub fn in_plane_curvature(&self, _p: Vec3<T>, _surface: u32) -> T {
        self.radius.recip()
    }

    /// Point strictly inside (values).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let r = self.radius.value();
        rho2(p, self.center.value()) < r * r
    }

    /// Values only.
    pub fn to_f64(&self) -> Cylinder<f64> {
        Cylinder::new(self.center.to_f64(), self.radius.value())
    }

    /// Finite centre and positive finite radius.
    pub fn is_valid(&self) -> bool {
        self.center.is_finite() && self.radius.is_finite() && self.radius.value() > 0.0
    }
}
