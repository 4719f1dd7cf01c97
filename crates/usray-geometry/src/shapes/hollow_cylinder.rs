//! [`HollowCylinder`]: a tube (wall between two coaxial cylinders along `y`).

use super::cylinder::{rho2, y_cylinder_roots};
use super::Roots;
use crate::{Ray, Vec3};
use usray_ad::Real;

/// A cylindrical tube along `y`: the solid region is the **wall**
/// `r − thickness_m < ρ < r`, `ρ` the distance to the axis (metres). The lumen
/// (`ρ < r − thickness_m`) is *outside* the object (it holds whatever medium
/// surrounds the tube).
///
/// Two surfaces: 0 = outer (`ρ = r`, outward normal pointing away from the axis),
/// 1 = inner (`ρ = r − t`, outward normal of the wall pointing **towards** the
/// axis). Crossings are the sphere-like quadratics of [`super::cylinder`] for each
/// radius. This is the `wall_thickness` effect of `CONTRACT.md` §3 and the paper's
/// hollow-cylinder phantom (R = 20 mm, t = 3 mm).
///
/// ```
/// use usray_geometry::{shapes::hollow_cylinder::HollowCylinder, Ray, Vec3};
/// let h = HollowCylinder::new(Vec3::new(0.0_f64, 0.0, 0.04), 0.02, 0.003);
/// let r = Ray::from_f64s([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
/// let ts: Vec<f64> = h.roots(&r).as_slice().iter().map(|x| x.0).collect();
/// assert_eq!(ts.len(), 4); // outer in, inner in, inner out, outer out (in list order below)
/// assert!(h.contains([0.0, 0.0, 0.0215]) && !h.contains([0.0, 0.0, 0.04]));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HollowCylinder<T> {
    /// A point on the axis, metres (`y` unused).
    pub center: Vec3<T>,
    /// Outer radius, metres (> 0).
    pub radius: T,
    /// Wall thickness, metres (`0 < thickness_m < radius`).
    pub thickness_m: T,
}

impl<T: Real> HollowCylinder<T> {
    /// A tube from a point on its axis, outer radius and wall thickness (metres).
    pub fn new(center: Vec3<T>, radius: T, thickness_m: T) -> Self {
        Self {
            center,
            radius,
            thickness_m,
        }
    }

    /// Inner radius `r − t`.
    #[inline]
    pub fn inner_radius(&self) -> T {
        self.radius - self.thickness_m
    }

    /// Crossings: the outer pair (surface 0, nearer first), then the inner pair
    /// (surface 1, nearer first).
    #[inline]
    pub fn roots(&self, ray: &Ray<T>) -> Roots<T> {
        let mut out = Roots::none();
        y_cylinder_roots(ray, self.center, self.radius, 0, &mut out);
        y_cylinder_roots(ray, self.center, self.inner_radius(), 1, &mut out);
        out
    }

    /// Curvature (1/m) of the cut through the `xz` plane at a surface point,
    /// signed against the outward normal: `1/radius` on the outer surface
    /// (convex), `−1/inner radius` on the inner one (the wall is concave
    /// there: its outward normal points at the axis).
    #[inline]
    pub fn in_plane_curvature(&self, _p: Vec3<T>, surface: u32) -> T {
        if surface == 0 {
            self.radius.recip()
        } else {
            -self.inner_radius().recip()
        }
    }

    /// Unit outward normal of the wall at a point of surface 0 (outer) or 1 (inner).
    #[inline]
    pub fn normal_at(&self, p: Vec3<T>, surface: u32) -> Vec3<T> {
        let k = self.in_plane_curvature(p, surface);
        Vec3::new(
            (p.x - self.center.x) * k,
            T::zero(),
            (p.z - self.center.z) * k,
        )
    }

    /// Point strictly inside the wall (values).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let r = self.radius.value();
        let ri = self.inner_radius().value();
        let d2 = rho2(p, self.center.value());
        d2 < r * r && d2 > ri * ri
    }

    /// Values only.
    pub fn to_f64(&self) -> HollowCylinder<f64> {
        HollowCylinder::new(
            self.center.to_f64(),
            self.radius.value(),
            self.thickness_m.value(),
        )
    }

    /// Finite, `radius > 0` and `0 < thickness_m < radius`.
    pub fn is_valid(&self) -> bool {
        let (r, t) = (self.radius.value(), self.thickness_m.value());
        self.center.is_finite()
            && self.radius.is_finite()
            && self.thickness_m.is_finite()
            && r > 0.0
            && t > 0.0
            && t < r
    }
}
