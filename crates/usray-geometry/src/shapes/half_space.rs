//! [`HalfSpace`]: everything on one side of a plane ("a flat interface at depth d").

use super::Roots;
use crate::{Ray, Vec3};
use usray_ad::Real;

/// The solid half-space `(p − point)·normal < 0`: `normal` is the unit **outward**
/// normal of the solid (it points out of the region, into the other medium).
///
/// One surface (index 0). Ray–plane crossing
/// `t = ((point − o)·n)/(d·n)`; a ray with `d·n = 0` exactly never crosses.
/// [`HalfSpace::below_depth`] builds the common case "a different medium below the
/// flat interface at depth `d`" (`z > d`, normal `(0, 0, −1)` towards the probe).
///
/// ```
/// use usray_geometry::{shapes::half_space::HalfSpace, Ray};
/// let h = HalfSpace::below_depth(0.03_f64);
/// let r = Ray::from_f64s([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
/// assert!((h.roots(&r).items[0].0 - 0.03).abs() < 1e-15);
/// assert!(h.contains([0.0, 0.0, 0.031]) && !h.contains([0.0, 0.0, 0.029]));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSpace<T> {
    /// A point on the bounding plane, metres.
    pub point: Vec3<T>,
    /// Unit outward normal of the solid region.
    pub normal: Vec3<T>,
}

impl<T: Real> HalfSpace<T> {
    /// A half-space from a point on its plane and its outward normal (normalised
    /// here).
    pub fn new(point: Vec3<T>, outward_normal: Vec3<T>) -> Self {
        Self {
            point,
            normal: outward_normal.normalize(),
        }
    }

    /// The region `z > depth_m` (below a flat interface at depth `depth_m`).
    pub fn below_depth(depth_m: T) -> Self {
        Self {
            point: Vec3::new(T::zero(), T::zero(), depth_m),
            normal: Vec3::from_f64s([0.0, 0.0, -1.0]),
        }
    }

    /// The single crossing (surface 0).
    #[inline]
    pub fn roots(&self, ray: &Ray<T>) -> Roots<T> {
        let mut out = Roots::none();
        let den = ray.dir.dot(self.normal);
        if den.value() != 0.0 {
            out.push((self.point - ray.origin).dot(self.normal) / den, 0);
        }
        out
    }

    /// The outward normal.
    #[inline]
    pub fn normal_at(&self, _p: Vec3<T>, _surface: u32) -> Vec3<T> {
        self.normal
    }

    /// Point strictly inside (values).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let q = self.point.value();
        let n = self.normal.value();
        (p[0] - q[0]) * n[0] + (p[1] - q[1]) * n[1] + (p[2] - q[2]) * n[2] < 0.0
    }

    /// Values only.
    pub fn to_f64(&self) -> HalfSpace<f64> {
        HalfSpace {
            point: self.point.to_f64(),
            normal: self.normal.to_f64(),
        }
    }

    /// Finite point and a non-zero normal.
    pub fn is_valid(&self) -> bool {
        self.point.is_finite()
            && self.normal.is_finite()
            && self.normal.length_squared().value() > 0.5
    }
}
