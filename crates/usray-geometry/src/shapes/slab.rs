//! [`Slab`]: the layer between two planes of constant depth `z`.

use super::Roots;
use crate::{Ray, Vec3};
use usray_ad::Real;

/// The solid layer `z_top_m < z < z_bottom_m` (metres, `z` = depth), infinite in
/// `x` and `y`: a refracting layer (e.g. a fat or muscle layer, a plastic
/// standoff).
///
/// Two surfaces: 0 = the top plane `z = z_top_m` (outward normal `(0, 0, −1)`,
/// towards the probe), 1 = the bottom plane `z = z_bottom_m` (outward normal
/// `(0, 0, +1)`). Ray–plane crossing `t = (z_plane − o_z)/d_z`; a ray with
/// `d_z = 0` exactly never crosses (no division by zero).
///
/// ```
/// use usray_geometry::{shapes::slab::Slab, Ray};
/// let s = Slab::new(0.01_f64, 0.02);
/// let r = Ray::from_f64s([0.0, 0.0, 0.0], [0.6, 0.0, 0.8]);
/// let ts = s.roots(&r);
/// assert!((ts.items[0].0 - 0.0125).abs() < 1e-15 && (ts.items[1].0 - 0.025).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slab<T> {
    /// Depth of the top plane, metres.
    pub z_top_m: T,
    /// Depth of the bottom plane, metres (`> z_top_m`).
    pub z_bottom_m: T,
}

impl<T: Real> Slab<T> {
    /// A slab between depths `z_top_m < z_bottom_m` (metres).
    pub fn new(z_top_m: T, z_bottom_m: T) -> Self {
        Self {
            z_top_m,
            z_bottom_m,
        }
    }

    /// A slab from its top depth and thickness (metres).
    pub fn from_depth_thickness(z_top_m: T, thickness_m: T) -> Self {
        Self::new(z_top_m, z_top_m + thickness_m)
    }

    /// Crossings: top plane (surface 0), then bottom plane (surface 1).
    #[inline]
    pub fn roots(&self, ray: &Ray<T>) -> Roots<T> {
        let mut out = Roots::none();
        if ray.dir.z.value() != 0.0 {
            let inv = ray.dir.z.recip();
            out.push((self.z_top_m - ray.origin.z) * inv, 0);
            out.push((self.z_bottom_m - ray.origin.z) * inv, 1);
        }
        out
    }

    /// Unit outward normal of surface 0 (`−z`) or 1 (`+z`).
    #[inline]
    pub fn normal_at(&self, _p: Vec3<T>, surface: u32) -> Vec3<T> {
        let s = if surface == 0 { -1.0 } else { 1.0 };
        Vec3::from_f64s([0.0, 0.0, s])
    }

    /// Point strictly inside (values).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        p[2] > self.z_top_m.value() && p[2] < self.z_bottom_m.value()
    }

    /// Values only.
    pub fn to_f64(&self) -> Slab<f64> {
        Slab::new(self.z_top_m.value(), self.z_bottom_m.value())
    }

    /// Finite and `z_top_m < z_bottom_m`.
    pub fn is_valid(&self) -> bool {
        self.z_top_m.is_finite()
            && self.z_bottom_m.is_finite()
            && self.z_top_m.value() < self.z_bottom_m.value()
    }
}
